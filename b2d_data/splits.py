"""Split manifests: the official Bench2Drive file lists, the baselines' train/val split, and generated splits.

A manifest names the clips of a split with their archive sha256 and size, divided into ``train`` and ``val``.
Saved as JSON::

    {"b2d_split_manifest": 1, "name": "base", "seed": 0, "source": "...",
     "train": {"<clip>.tar.gz": {"sha256": "...", "size": 123}, ...},
     "val":   {"<clip>.tar.gz": {"sha256": null, "size": null}, ...}}

Both parts use the official lists' layout (archive name → sha256/size), so ``b2d-verify`` reads a manifest and
an official list alike.

Generation (deterministic for a seed; clips are first sorted by name, all randomness comes from the seed):

- **mini** (10 clips): one clip per *scenario family* (table :data:`SCENARIO_FAMILIES`: ten behaviour families
  grouping the 44 scenarios, plus ``NoScenario``), then round-robin over families again if fewer than 10 are
  present. Within a family, a clip whose scenario, town and weather are not yet used is preferred. All train.
- **base** (1000 clips, 950 train + 50 val): scenarios are drawn round-robin so that each scenario gets as many
  clips as possible; the val part is chosen by :func:`choose_val`. A corpus of fewer than 1000 clips is taken
  whole, with val scaled to 5 % but at least one clip per scenario and at most half the clips.
- **full**: every clip; val = 5 % of the clips (at least one per scenario), chosen by :func:`choose_val`.

:func:`choose_val` first takes one clip of every scenario present (the clip whose weather is least used so far
in val), then fills the remaining places with the clips whose weather is least represented in val, so the val
weathers stay balanced (counts differ by at most one where the corpus allows).
"""

from __future__ import annotations

import json
import logging
import random
from collections import Counter, defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Literal

from b2d_data.format.names import ClipName, ClipNameError

logger = logging.getLogger(__name__)

MANIFEST_VERSION = 1
ARCHIVE_SUFFIX = ".tar.gz"
Part = Literal["train", "val", "all"]
PARTS: tuple[str, ...] = ("train", "val", "all")
#: A corpus's own split manifest lives in ``<root>/splits/`` (``b2d-collect --preset`` writes it there).
CORPUS_SPLITS_DIR = "splits"

#: Behaviour families of the scenarios (clip prefixes) used to spread the mini split; each scenario is in one.
SCENARIO_FAMILIES: dict[str, tuple[str, ...]] = {
    "obstacle_in_lane": ("Accident", "ConstructionObstacle", "ParkedObstacle", "HazardAtSideLane"),
    "obstacle_two_ways": (
        "AccidentTwoWays", "ConstructionObstacleTwoWays", "ParkedObstacleTwoWays", "HazardAtSideLaneTwoWays",
        "VehicleOpensDoorTwoWays",
    ),
    "crossing_road_users": (
        "DynamicObjectCrossing", "ParkingCrossingPedestrian", "PedestrianCrossing", "VehicleTurningRoutePedestrian",
        "CrossingBicycleFlow",
    ),
    "cut_in": ("HighwayCutIn", "ParkingCutIn", "StaticCutIn"),
    "merging_flows": (
        "EnterActorFlow", "InterurbanActorFlow", "InterurbanAdvancedActorFlow", "MergerIntoSlowTraffic",
        "MergerIntoSlowTrafficV2", "HighwayExit",
    ),
    "junction_turns": (
        "NonSignalizedJunctionLeftTurn", "NonSignalizedJunctionLeftTurnEnterFlow", "NonSignalizedJunctionRightTurn",
        "SignalizedJunctionLeftTurn", "SignalizedJunctionLeftTurnEnterFlow", "SignalizedJunctionRightTurn",
    ),
    "right_of_way_violations": (
        "OppositeVehicleRunningRedLight", "OppositeVehicleTakingPriority", "BlockedIntersection", "VehicleTurningRoute",
    ),
    "signs_and_lights": (
        "TJunction", "VanillaNonSignalizedTurn", "VanillaNonSignalizedTurnEncounterStopsign",
        "VanillaSignalizedTurnEncounterGreenLight", "VanillaSignalizedTurnEncounterRedLight",
    ),
    "lane_change_and_parking_exit": ("LaneChange", "ParkingExit"),
    "emergency": ("HardBreakRoute", "ControlLoss", "YieldToEmergencyVehicle", "InvadingTurn"),
    "no_scenario": ("NoScenario",),
}  # fmt: skip
_FAMILY_OF: dict[str, str] = {s: fam for fam, members in SCENARIO_FAMILIES.items() for s in members}

#: Default sizes of the generated splits.
MINI_SIZE = 10
BASE_SIZE = 1000
BASE_VAL = 50
FULL_VAL_FRACTION = 0.05


def scenario_family(scenario: str) -> str:
    """The behaviour family of a clip prefix (unknown scenarios form their own family)."""
    return _FAMILY_OF.get(scenario, scenario)


def clip_name_of(text: str) -> str:
    """A clip name from an archive name or a path (``v1/<clip>``, ``<clip>.tar.gz``)."""
    name = text.rstrip("/").split("/")[-1]
    return name[: -len(ARCHIVE_SUFFIX)] if name.endswith(ARCHIVE_SUFFIX) else name


@dataclass(frozen=True, order=True)
class SplitEntry:
    """One clip of a split with its archive checksum and size (``None`` when unknown)."""

    clip: str
    sha256: str | None = None
    size: int | None = None

    @property
    def archive_name(self) -> str:
        """``<clip>.tar.gz``, as keyed in the official lists."""
        return self.clip + ARCHIVE_SUFFIX

    def parsed(self) -> ClipName | None:
        """The parsed clip name, or ``None`` when it is malformed."""
        try:
            return ClipName.parse(self.clip)
        except ClipNameError:
            return None


@dataclass
class SplitManifest:
    """The clips of a split, divided into train and val."""

    name: str
    train: tuple[SplitEntry, ...]
    val: tuple[SplitEntry, ...] = ()
    seed: int | None = None
    source: str = ""
    extra: dict = field(default_factory=dict)

    def entries(self, part: Part = "all") -> tuple[SplitEntry, ...]:
        """Entries of one part (``train``, ``val``) or of both (``all``), train first."""
        if part == "train":
            return self.train
        if part == "val":
            return self.val
        if part == "all":
            return self.train + self.val
        raise ValueError(f"unknown split part {part!r}; use 'train', 'val' or 'all'")

    def clips(self, part: Part = "all") -> list[str]:
        """Clip names of one part."""
        return [e.clip for e in self.entries(part)]

    def file_list(self, part: Part = "all") -> dict[str, dict]:
        """The official-list layout: archive name → {sha256, size}, sorted by name."""
        return {e.archive_name: {"sha256": e.sha256, "size": e.size} for e in sorted(self.entries(part))}

    def to_json(self) -> dict:
        """The manifest as a JSON-ready dict."""
        return {
            "b2d_split_manifest": MANIFEST_VERSION,
            "name": self.name,
            "seed": self.seed,
            "source": self.source,
            **({"extra": self.extra} if self.extra else {}),
            "train": self.file_list("train"),
            "val": self.file_list("val"),
        }

    def save(self, path: str | Path) -> Path:
        """Write the manifest as indented JSON (atomically)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(self.to_json(), indent=4) + "\n", encoding="utf-8")
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> SplitManifest:
        """Read a manifest written by :meth:`save`, or an official file list (then everything is train)."""
        path = Path(path)
        data = _read_json(path)
        if isinstance(data, dict) and "b2d_split_manifest" in data:
            return cls(
                name=str(data.get("name", path.stem)),
                train=_entries_from_list(data.get("train", {}), path),
                val=_entries_from_list(data.get("val", {}), path),
                seed=data.get("seed"),
                source=str(data.get("source", "")),
                extra=dict(data.get("extra", {})),
            )
        return cls(name=path.stem, train=_entries_from_list(data, path), source=str(path))


def _read_json(path: Path) -> object:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: split file does not exist") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON: {exc}") from exc


def _entries_from_list(data: object, path: Path) -> tuple[SplitEntry, ...]:
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected an object mapping archive names to {{sha256, size}}")
    out = []
    for key, value in data.items():
        value = value or {}
        if not isinstance(value, dict):
            raise ValueError(f"{path}: entry {key!r} must be an object with sha256 and size")
        size = value.get("size")
        out.append(SplitEntry(clip_name_of(key), value.get("sha256"), int(size) if size is not None else None))
    return tuple(sorted(out))


def corpus_manifest(root: str | Path) -> Path:
    """The one split manifest in ``<root>/splits/`` (FileNotFoundError / ValueError say what is there instead)."""
    folder = Path(root) / CORPUS_SPLITS_DIR
    found = sorted(folder.glob("*.json")) if folder.is_dir() else []
    if not found:
        raise FileNotFoundError(
            f"{folder}: no split manifest (b2d-collect --preset writes one; or b2d-split generate {root} --split base "
            f"--out {folder / 'base.json'})"
        )
    if len(found) > 1:
        raise ValueError(
            f"{folder} holds {len(found)} split manifests ({', '.join(p.name for p in found)}); pass split=<file> "
            "and part='train' or 'val' to choose one"
        )
    return found[0]


def load_file_list(path: str | Path) -> tuple[SplitEntry, ...]:
    """Read an official list (``bench2drive_base_1000.json`` …): archive name → {sha256, size}."""
    path = Path(path)
    return _entries_from_list(_read_json(path), path)


def load_val_list(path: str | Path) -> list[str]:
    """Clip names of a baseline val list: Zoo's ``{"val": ["v1/<clip>", ...]}`` or a plain JSON list."""
    path = Path(path)
    data = _read_json(path)
    names = data.get("val") if isinstance(data, dict) else data
    if not isinstance(names, list):
        raise ValueError(f"{path}: expected {{'val': [...]}} or a list of clip names")
    return [clip_name_of(str(n)) for n in names]


def import_official(
    list_path: str | Path, val_path: str | Path | None = None, name: str | None = None
) -> SplitManifest:
    """A manifest from an official file list, optionally divided by a baseline val list (the rest is train)."""
    list_path = Path(list_path)
    entries = load_file_list(list_path)
    source = str(list_path.name)
    if val_path is None:
        return SplitManifest(name=name or list_path.stem, train=entries, source=source)
    val_names = set(load_val_list(val_path))
    known = {e.clip for e in entries}
    missing = sorted(val_names - known)
    if missing:
        logger.warning("%s: %d val clips are not in %s: %s", val_path, len(missing), list_path.name, missing[:5])
    train = tuple(e for e in entries if e.clip not in val_names)
    val = tuple(e for e in entries if e.clip in val_names)
    return SplitManifest(name=name or list_path.stem, train=train, val=val, source=f"{source} + {Path(val_path).name}")


# ------------------------------------------------------------------------------------------- generation


@cache
def _meta(clip: str) -> tuple[str, str, int | None]:
    # Cached: parsing is the hot path of the greedy choices, and a truncated name should warn only once.
    try:
        parsed = ClipName.parse(clip)
    except ClipNameError:
        return clip.split("_")[0], "", None
    return parsed.scenario, parsed.town, parsed.weather_id


def _scenario(entry: SplitEntry) -> str:
    return _meta(entry.clip)[0]


def _town(entry: SplitEntry) -> str:
    return _meta(entry.clip)[1]


def _weather(entry: SplitEntry) -> int | None:
    return _meta(entry.clip)[2]


def _shuffled(items: Iterable, rng: random.Random) -> list:
    out = list(items)
    rng.shuffle(out)
    return out


def generate_mini(entries: Sequence[SplitEntry], seed: int = 0, size: int = MINI_SIZE) -> SplitManifest:
    """Mini split: one clip per scenario family where possible, preferring unused scenarios, towns, weathers."""
    rng = random.Random(seed)
    pool = sorted(set(entries))
    by_family: dict[str, list[SplitEntry]] = defaultdict(list)
    for e in _shuffled(pool, rng):
        by_family[scenario_family(_scenario(e))].append(e)
    families = _shuffled(sorted(by_family), rng)
    chosen: list[SplitEntry] = []
    used_scen: set[str] = set()
    used_town: set[str] = set()
    used_weather: set[int | None] = set()
    while len(chosen) < min(size, len(pool)):
        progressed = False
        for fam in families:
            if len(chosen) >= size or not by_family[fam]:
                continue
            # Lexicographic preference: new scenario, then new town, then new weather; ties keep seeded order.
            best = min(
                by_family[fam],
                key=lambda e: (_scenario(e) in used_scen, _town(e) in used_town, _weather(e) in used_weather),
            )
            by_family[fam].remove(best)
            chosen.append(best)
            used_scen.add(_scenario(best))
            used_town.add(_town(best))
            used_weather.add(_weather(best))
            progressed = True
        if not progressed:
            break
    if len(chosen) < size:
        logger.warning("mini split: the corpus holds only %d clips, fewer than %d", len(chosen), size)
    return SplitManifest(name="mini", train=tuple(sorted(chosen)), seed=seed, source="generated")


def _round_robin_by_scenario(pool: Sequence[SplitEntry], size: int, rng: random.Random) -> list[SplitEntry]:
    by_scen: dict[str, list[SplitEntry]] = defaultdict(list)
    for e in _shuffled(pool, rng):
        by_scen[_scenario(e)].append(e)
    order = _shuffled(sorted(by_scen), rng)
    chosen: list[SplitEntry] = []
    while len(chosen) < size:
        progressed = False
        for scen in order:
            if by_scen[scen] and len(chosen) < size:
                chosen.append(by_scen[scen].pop())
                progressed = True
        if not progressed:
            break
    return chosen


def choose_val(entries: Sequence[SplitEntry], n_val: int, seed: int = 0) -> list[SplitEntry]:
    """Pick ``n_val`` val clips: one of every scenario first, then fill while balancing weathers."""
    rng = random.Random(seed)
    pool = _shuffled(sorted(set(entries)), rng)
    n_val = min(n_val, len(pool))
    weather_count: Counter = Counter()
    scen_count: Counter = Counter()
    chosen: list[SplitEntry] = []
    scenarios = _shuffled(sorted({_scenario(e) for e in pool}), rng)
    if len(scenarios) > n_val:
        logger.warning(
            "val holds %d clips but the corpus has %d scenarios: not all can be in val", n_val, len(scenarios)
        )
    for scen in scenarios[:n_val]:
        candidates = [e for e in pool if _scenario(e) == scen]
        best = min(candidates, key=lambda e: weather_count[_weather(e)])
        pool.remove(best)
        chosen.append(best)
        weather_count[_weather(best)] += 1
        scen_count[scen] += 1
    by_weather: dict[int | None, list[SplitEntry]] = defaultdict(list)
    for e in pool:
        by_weather[_weather(e)].append(e)
    weather_order = {w: i for i, w in enumerate(by_weather)}  # first-seen order of the seeded pool
    while len(chosen) < n_val:
        open_weathers = [w for w, items in by_weather.items() if items]
        if not open_weathers:
            break
        # The least represented weather in val, then its clip of the least represented scenario.
        w = min(open_weathers, key=lambda k: (weather_count[k], weather_order[k]))
        best = min(by_weather[w], key=lambda e: scen_count[_scenario(e)])
        by_weather[w].remove(best)
        chosen.append(best)
        weather_count[w] += 1
        scen_count[_scenario(best)] += 1
    return chosen


def generate_base(
    entries: Sequence[SplitEntry], seed: int = 0, size: int = BASE_SIZE, n_val: int = BASE_VAL
) -> SplitManifest:
    """Base split: ``size`` clips drawn round-robin over scenarios; ``n_val`` of them form val."""
    rng = random.Random(seed)
    pool = sorted(set(entries))
    if len(pool) < size:
        # A smaller corpus keeps val in proportion, but still one clip per scenario, and never over half the clips.
        n_scen = len({_scenario(e) for e in pool})
        n_val = min(max(round(n_val * len(pool) / size), n_scen), len(pool) // 2)
        logger.warning(
            "base split: the corpus holds only %d clips, fewer than %d: taking all, %d of them as val",
            len(pool), size, n_val,
        )  # fmt: skip
    chosen = pool if len(pool) <= size else _round_robin_by_scenario(pool, size, rng)
    val = set(choose_val(chosen, n_val, seed))
    return SplitManifest(
        name="base",
        train=tuple(sorted(e for e in chosen if e not in val)),
        val=tuple(sorted(val)),
        seed=seed,
        source="generated",
    )


def generate_full(
    entries: Sequence[SplitEntry], seed: int = 0, val_fraction: float = FULL_VAL_FRACTION
) -> SplitManifest:
    """Full split: every clip; a val part of ``val_fraction`` (at least one clip per scenario)."""
    pool = sorted(set(entries))
    n_scen = len({_scenario(e) for e in pool})
    n_val = min(len(pool), max(n_scen, round(val_fraction * len(pool))))
    val = set(choose_val(pool, n_val, seed))
    return SplitManifest(
        name="full",
        train=tuple(e for e in pool if e not in val),
        val=tuple(sorted(val)),
        seed=seed,
        source="generated",
    )


def generate(kind: str, entries: Sequence[SplitEntry], seed: int = 0) -> SplitManifest:
    """Generate the ``mini``, ``base`` or ``full`` manifest of a corpus."""
    if kind == "mini":
        return generate_mini(entries, seed)
    if kind == "base":
        return generate_base(entries, seed)
    if kind == "full":
        return generate_full(entries, seed)
    raise ValueError(f"unknown split {kind!r}; use mini, base or full")
