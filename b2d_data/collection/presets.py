"""Bench2Drive-sized corpora: what the ``mini``, ``base``, ``full`` and ``uniform`` presets of ``b2d-collect`` hold.

A preset is a list of :class:`Slot` records, one per clip to make: its scenario type, weather, the town of the clip
it copies and its part of the split (train or val).

- ``mini``, ``base``, ``full`` copy Bench2Drive's official file lists clip by clip (``bench2drive_mini_10.json``,
  ``bench2drive_base_1000.json``, ``bench2drive_full+sup_13638.json``; names ``<Scenario>_<Town>_Route<id>_Weather<w>``
  read by :class:`~b2d_data.format.names.ClipName`). Val: base's is the baselines' split
  (``bench2drive_base_train_val_split.json``, 50 clips); mini has none (as the official mini); full, which has no
  official one, takes :func:`b2d_data.splits.choose_val`'s pick of 5 % of its clips (at least one per scenario), the
  rule of ``b2d-split generate --split full``. A clip of a type b2d-data does not know, or whose name does not parse,
  is reported in :attr:`Composition.unknown` / :attr:`Composition.malformed` and left out.
- ``uniform`` is Bench2Drive v0.0.4's design: each of the 44 types × 25 routes; route ``k`` of the ``t``-th type
  (in ``SCENARIO_TYPES`` order) has weather ``WEATHER_IDS[(25 t + k) % 23]`` (every preset about equally often);
  val is each type's first route (44 val clips, whose weathers cover all 23 presets).

Scaling (:func:`scale`, ``--n-scale s``): each part (train, val) with ``N`` slots keeps ``M = max(1, ⌊N s + ½⌋)``
slots; ``M`` is shared among the scenario types in proportion to their slots by the largest-remainder rule (quota
``M n_t / N``: each type first gets its quota rounded down, the seats left go to the largest remainders, ties to the
type whose name sorts first). A type keeping ``m`` of its ``n`` slots (in list order) keeps those at positions
``⌊(2 j + 1) n / (2 m)⌋`` for ``j < m``: evenly spread, and repeated when ``m > n`` (``s > 1``).

Towns (:func:`assign_towns`): a slot keeps its clip's town when b2d-data ships that town's OpenDRIVE and placement
finds a place for the type there; otherwise the slots of a type go round robin over the generated towns that hold
the type (``towngen`` presets in their order: Town100 …), so each town's form of the type's layout occurs; the
``k``-th type needing a substitute starts at its ``k``-th host town.
"""

from __future__ import annotations

import json
import logging
import math
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path

from b2d_data.format.names import ClipName, ClipNameError
from b2d_data.format.scenario_types import SCENARIO_TYPES
from b2d_data.format.weather import WEATHER_IDS

log = logging.getLogger(__name__)

PRESET_NAMES: tuple[str, ...] = ("mini", "base", "full", "uniform")
#: The official list each copying preset follows (files of ``b2d_data/data/bench2drive``).
OFFICIAL_LISTS: dict[str, str] = {
    "mini": "bench2drive_mini_10.json",
    "base": "bench2drive_base_1000.json",
    "full": "bench2drive_full+sup_13638.json",
}
#: The baselines' val list of base (Bench2DriveZoo).
BASE_VAL_LIST = "bench2drive_base_train_val_split.json"
#: Routes per scenario type of ``uniform`` (v0.0.4: 44 × 25 = 1100).
UNIFORM_ROUTES = 25
TRAIN, VAL = "train", "val"


class PresetError(ValueError):
    """An unknown preset or scale, or an official list that cannot be read (the message names the file)."""


@dataclass(frozen=True)
class Slot:
    """One clip of a preset: its scenario's XML type, weather (None: the copied name lost it), the copied clip's town
    ("" for uniform), its part (``train``/``val``) and what it copies (an official clip name, or ``<Type>#<k>``)."""

    index: int
    scenario: str
    weather: int | None
    town: str
    part: str
    source: str


@dataclass
class Composition:
    """A preset's slots (in order: their index), and the list entries it left out."""

    name: str
    slots: list[Slot]
    #: Clips of the list whose scenario type b2d-data does not know: name → count.
    unknown: dict[str, int] = field(default_factory=dict)
    #: Names of the list that are not clip names.
    malformed: list[str] = field(default_factory=list)
    #: The file(s) the composition follows, for the manifest.
    source: str = ""


def _read_names(path: Path) -> list[str]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise PresetError(f"cannot read the official list {path}: {exc}") from None
    if not isinstance(data, dict):
        raise PresetError(f"{path}: expected an object mapping archive names to {{sha256, size}}")
    return list(data)


def slots_of_names(names: Iterable[str], val: Iterable[str] = ()) -> Composition:
    """Slots copying clip names (archive names or paths are fine), sorted by name; ``val`` names the val clips."""
    from b2d_data.splits import clip_name_of

    val_set = {clip_name_of(v) for v in val}
    slots: list[Slot] = []
    unknown: Counter[str] = Counter()
    malformed: list[str] = []
    for name in sorted({clip_name_of(n) for n in names}):
        try:
            parsed = ClipName.parse(name)
        except (ClipNameError, ValueError):  # ValueError: a scenario or town unfit for a file name
            malformed.append(name)
            continue
        if not parsed.is_known_scenario:
            unknown[parsed.scenario] += 1
            continue
        part = VAL if name in val_set else TRAIN
        slots.append(Slot(len(slots), parsed.xml_type, parsed.weather_id, parsed.town, part, name))
    if unknown:
        log.warning("leaving out %d clip(s) of unknown scenario types: %s", sum(unknown.values()),
                    ", ".join(f"{k} ×{v}" for k, v in sorted(unknown.items())))  # fmt: skip
    if malformed:
        log.warning("leaving out %d name(s) that are not clip names, e.g. %s", len(malformed), malformed[0])
    return Composition("", slots, dict(unknown), malformed)


def uniform_slots() -> Composition:
    """v0.0.4's design: 25 routes of each of the 44 types; weathers cycle over the presets, val = route 1 of each."""
    slots = []
    for t, kind in enumerate(SCENARIO_TYPES):
        for k in range(UNIFORM_ROUTES):
            weather = WEATHER_IDS[(t * UNIFORM_ROUTES + k) % len(WEATHER_IDS)]
            part = VAL if k == 0 else TRAIN
            slots.append(Slot(len(slots), kind.xml_type, weather, "", part, f"{kind.clip_prefix}#{k + 1}"))
    return Composition("uniform", slots, source=f"Bench2Drive v0.0.4: {len(SCENARIO_TYPES)} types × {UNIFORM_ROUTES}")


def _full_val(slots: Sequence[Slot], seed: int) -> set[str]:
    """The val clips ``b2d-split generate --split full`` would choose among these clips."""
    from b2d_data.splits import FULL_VAL_FRACTION, SplitEntry, choose_val

    n_types = len({s.scenario for s in slots})
    n_val = min(len(slots), max(n_types, round(FULL_VAL_FRACTION * len(slots))))
    return {e.clip for e in choose_val([SplitEntry(s.source) for s in slots], n_val, seed)}


def compose(name: str, n_scale: float = 1.0, seed: int = 0, lists_dir: Path | None = None) -> Composition:
    """The slots of preset ``name`` scaled by ``n_scale`` (lists read from ``lists_dir``, default: the shipped ones)."""
    from b2d_data.data import bench2drive_dir

    if name not in PRESET_NAMES:
        raise PresetError(f"unknown preset {name!r}; presets: {', '.join(PRESET_NAMES)}")
    if name == "uniform":
        return scale(uniform_slots(), n_scale)
    folder = lists_dir if lists_dir is not None else bench2drive_dir()
    list_path = folder / OFFICIAL_LISTS[name]
    names = _read_names(list_path)
    source = list_path.name
    val: list[str] = []
    if name == "base":
        from b2d_data.splits import load_val_list

        try:
            val = load_val_list(folder / BASE_VAL_LIST)
        except (OSError, ValueError) as exc:
            raise PresetError(str(exc)) from None
        source += f" + {BASE_VAL_LIST}"
    comp = slots_of_names(names, val)
    if name == "full":
        chosen = _full_val(comp.slots, seed)
        comp.slots = [replace(s, part=VAL if s.source in chosen else TRAIN) for s in comp.slots]
    comp.name, comp.source = name, source
    return scale(comp, n_scale)


def half_up(x: Fraction) -> int:
    """``x`` rounded to the nearest integer, halves up (2.5 → 3, unlike Python's ``round``)."""
    return math.floor(x + Fraction(1, 2))


def apportion(counts: dict[str, int], seats: int) -> dict[str, int]:
    """``seats`` shared in proportion to ``counts`` by the largest-remainder rule; ties go to the name sorting first."""
    total = sum(counts.values())
    if total == 0:
        return {k: 0 for k in counts}
    quotas = {k: Fraction(seats * n, total) for k, n in counts.items()}
    out = {k: math.floor(q) for k, q in quotas.items()}
    left = seats - sum(out.values())
    for k in sorted(counts, key=lambda k: (-(quotas[k] - out[k]), k))[:left]:
        out[k] += 1
    return out


def spread(n: int, m: int) -> list[int]:
    """``m`` positions among ``n`` items, evenly spread (the centres of ``m`` equal bins; repeats when ``m > n``)."""
    return [(2 * j + 1) * n // (2 * m) for j in range(m)] if n else []


def scale(comp: Composition, n_scale: float) -> Composition:
    """The composition with each part scaled by ``n_scale`` (module docstring: the rule); 1 keeps every slot."""
    if not (isinstance(n_scale, (int, float)) and math.isfinite(n_scale) and n_scale > 0):
        raise PresetError(f"--n-scale must be a positive number, got {n_scale!r}")
    if n_scale == 1:
        return comp
    s = Fraction(n_scale).limit_denominator(10**6)  # 0.1 means a tenth, not its binary neighbour
    kept: list[tuple[Slot, int]] = []  # (slot, repeat number)
    for part in (TRAIN, VAL):
        by_type: dict[str, list[Slot]] = {}
        for slot in comp.slots:
            if slot.part == part:
                by_type.setdefault(slot.scenario, []).append(slot)
        total = sum(len(v) for v in by_type.values())
        if not total:
            continue
        seats = apportion({k: len(v) for k, v in by_type.items()}, max(1, half_up(total * s)))
        for scenario, members in by_type.items():
            positions = spread(len(members), seats[scenario])
            kept += [(members[p], positions[:j].count(p)) for j, p in enumerate(positions)]
    kept.sort(key=lambda item: (item[0].index, item[1]))
    slots = [replace(slot, index=i) for i, (slot, _) in enumerate(kept)]
    return Composition(comp.name, slots, comp.unknown, comp.malformed, comp.source)


def assign_towns(
    slots: Sequence[Slot], can_host: Callable[[str, str], bool], shipped: Iterable[str], generated: Sequence[str]
) -> dict[int, str | None]:
    """Each slot's town (None: no town can hold its type): its own when ``shipped`` and ``can_host(town, type)``,
    else round robin over the ``generated`` towns that can host the type (in that order, in slot order). The
    ``k``-th type to need a substitute starts its round at its ``k``-th host, so that types with a slot or two
    (mini) spread over the towns too."""
    shipped = set(shipped)
    out: dict[int, str | None] = {}
    turn: Counter[str] = Counter()
    hosts: dict[str, list[str]] = {}
    for slot in sorted(slots, key=lambda s: s.index):
        if slot.town in shipped and can_host(slot.town, slot.scenario):
            out[slot.index] = slot.town
            continue
        if slot.scenario not in hosts:
            hosts[slot.scenario] = [g for g in generated if can_host(g, slot.scenario)]
            turn[slot.scenario] = len(hosts) - 1
        options = hosts[slot.scenario]
        out[slot.index] = options[turn[slot.scenario] % len(options)] if options else None
        turn[slot.scenario] += 1
    return out


def move_sides(
    slots: Sequence[Slot],
    towns: Mapping[int, str | None],
    sides: Mapping[int, str],
    has_side: Callable[[str, str, str], bool],
    generated: Sequence[str],
) -> tuple[dict[int, str | None], dict[int, str]]:
    """Slots whose drawn ``direction`` (``sides``: slot index → side) their town has no place for
    (``has_side(town, type, side)`` false) move to the first of the ``generated`` towns that has one, in turn per
    (type, side); returns every slot's town and the side each slot keeps to in it (its drawn one). A slot no town
    has a place for stays where it was, unpinned (its draw falls back to another side there, logged by the
    placement)."""
    out: dict[int, str | None] = dict(towns)
    pinned: dict[int, str] = {}
    turn: Counter[tuple[str, str]] = Counter()
    for slot in sorted(slots, key=lambda s: s.index):
        side, town = sides.get(slot.index), towns.get(slot.index)
        if side is None or town is None:
            continue
        if has_side(town, slot.scenario, side):
            pinned[slot.index] = side
            continue
        options = [g for g in generated if has_side(g, slot.scenario, side)]
        if not options:
            log.warning("slot %d: no town has a place for %s with direction=%s", slot.index, slot.scenario, side)
            continue
        key = (slot.scenario, side)
        out[slot.index] = options[turn[key] % len(options)]
        pinned[slot.index] = side
        turn[key] += 1
    return out, pinned


def interleaved(slots: Sequence[Slot]) -> list[Slot]:
    """The slots in an order that mixes the types evenly (each type's ``k``-th of ``n`` at ``(k + ½) / n``), so that
    a collection stopped early holds every type in proportion."""
    rank: Counter[str] = Counter()
    n = Counter(s.scenario for s in slots)
    keyed = []
    for s in slots:
        keyed.append((Fraction(2 * rank[s.scenario] + 1, 2 * n[s.scenario]), s.index, s))
        rank[s.scenario] += 1
    return [s for _, _, s in sorted(keyed, key=lambda t: (t[0], t[1]))]
