"""The collection plan of a ``b2d-collect --preset``: a town for every slot, each slot's routes, the plan kept for a
resume, and the split manifest written from what was made.

Every slot of the composition (:mod:`~b2d_data.collection.presets`) is one target of one clip: its routes are
``--attempts-per-clip`` routes of its type in its town (``placement.make_routes`` over all the slots of that type and
town, so that first attempts take distinct places), set to the slot's weather and numbered
``(slot index + 1) × 100 + attempt`` so that a route id names its slot. The runner runs these targets as any
collection's (resume, Ray, the per-type table). The plan is saved under ``<out>/routes/`` so that a resume never
re-runs the placement; the manifest goes to ``<out>/splits/<preset>.json``, where ``ClipDataset(out, split="train")``
finds it.
"""

from __future__ import annotations

import functools
import json
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any


from b2d_data.collection.job import CollectConfig, with_weather
from b2d_data.collection.layout import usable_cores, worker_context
from b2d_data.collection.plan import (
    PLANNED_ROUTES_DIR,
    CollectError,
    CollectionPlan,
    RouteTask,
    ScenarioPlan,
    implemented_scenarios,
    route_seed,
    settings_of,
)
from b2d_data.collection.presets import (
    TRAIN,
    VAL,
    Composition,
    PresetError,
    Slot,
    assign_towns,
    compose,
    interleaved,
    move_sides,
)
from b2d_data.collection.towns import TownError, TownSource, load_map, route_town
from b2d_data.format.weather import PRESETS
from b2d_data.maps import Map
from b2d_data.scenarios.route_xml import Route
from b2d_data.splits import SplitEntry, SplitManifest

log = logging.getLogger(__name__)

#: Route ids of a preset are (slot index + 1) × ROUTE_ID_STRIDE + attempt: at most this many attempts per clip.
ROUTE_ID_STRIDE = 100
#: Corpus sub-folder of the split manifest (``ClipDataset(root, split="train")`` reads the one manifest there).
SPLITS_DIR = "splits"


@dataclass
class PresetPlan:
    """A preset's slots, the town each got, why a slot has no routes, and each slot's route ids."""

    composition: Composition
    towns: dict[int, str | None]
    errors: dict[int, str] = field(default_factory=dict)
    route_ids: dict[int, list[str]] = field(default_factory=dict)

    def left_out(self) -> dict[str, int]:
        """Entries of the official list that have no slot, by reason."""
        out = {f"unknown scenario type {k}": v for k, v in sorted(self.composition.unknown.items())}
        if self.composition.malformed:
            out["not a clip name"] = len(self.composition.malformed)
        return out


def slot_route_id(index: int, attempt: int) -> str:
    """The id of attempt ``attempt`` (0-based) of slot ``index``."""
    return str((index + 1) * ROUTE_ID_STRIDE + attempt)


def slot_of_route(route_id: str) -> int:
    """The slot index a preset route id belongs to."""
    return int(route_id) // ROUTE_ID_STRIDE - 1


class _Towns:
    """The towns a preset may use (generated presets and shipped CARLA towns), materialised and loaded once."""

    def __init__(self, out: Path) -> None:
        from b2d_data.data import shipped_towns
        from b2d_data.maps import towngen

        self.out = out
        #: towns any type's clips may move to; ``sided`` also those kept for a drawn side the others lack
        self.generated = [p.town for p in towngen.TOWN_PRESETS.values() if p.substitute]
        self.sided = [p.town for p in towngen.TOWN_PRESETS.values()]
        self.shipped = shipped_towns()
        self._sources: dict[str, TownSource] = {}

    def source(self, town: str) -> TownSource:
        """The file-backed source of a town name."""
        if town not in self._sources:
            try:
                source = route_town(town)
            except TownError as exc:
                raise CollectError(str(exc)) from None
            if source is None:
                raise CollectError(f"no map for town {town}: neither a generated preset nor a shipped CARLA town")
            try:
                self._sources[town] = source.materialise(self.out)
            except TownError as exc:
                raise CollectError(str(exc)) from None
        return self._sources[town]

    def map(self, town: str) -> Map:
        """The loaded map of a town name."""
        return load_map(self.source(town))


class _Placer:
    """Placement over the towns, remembering which (town, type) pairs hold at least one route."""

    def __init__(self, towns: _Towns, seed: int, params: str) -> None:
        self.towns, self.seed, self.params = towns, seed, params
        self._hosts: dict[tuple[str, str], bool] = {}
        self._lacking: dict[tuple[str, str], tuple[str, ...]] = {}

    def probe(self, pairs: Sequence[tuple[str, str]]) -> None:
        """Answer :meth:`can_host` for every (town, type) pair at once (``place_all``: side by side)."""
        asked = [pair for pair in dict.fromkeys(pairs) if pair not in self._hosts]
        found = place_all(self.towns, self.seed, self.params, [(town, scenario, 1, None) for town, scenario in asked])
        for pair, routes in zip(asked, found):
            self._hosts[pair] = not isinstance(routes, str)

    def can_host(self, town: str, scenario: str) -> bool:
        """Whether placement builds a route of ``scenario`` in ``town``."""
        key = (town, scenario)
        if key not in self._hosts:
            try:
                self.routes(town, scenario, 1)
                self._hosts[key] = True
            except CollectError:
                self._hosts[key] = False
        return self._hosts[key]

    def has_side(self, town: str, scenario: str, side: str) -> bool:
        """Whether ``town`` holds a place for ``scenario`` with its ``direction`` drawn as ``side``."""
        from b2d_data.scenarios import placement

        if not self.can_host(town, scenario):
            return False
        key = (town, scenario)
        if key not in self._lacking:
            self._lacking[key] = placement.missing_sides(self.towns.map(town), scenario, self.params)
        return side not in self._lacking[key]

    def routes(self, town: str, scenario: str, n: int, side: str | None = None) -> list[Route]:
        """``n`` routes of ``scenario`` in ``town``, with ``side`` only that ``direction`` (:class:`CollectError`
        naming the missing layout)."""
        from b2d_data.scenarios import placement

        pinned = {"direction": side} if side is not None else {}
        try:
            return placement.make_routes(self.towns.map(town), scenario, n, self.seed, None, self.params, **pinned)
        except placement.PlacementError as exc:
            raise CollectError(str(exc)) from None


#: Placement calls fan out over processes from this many on (a process's start and its map loads cost ~1 s).
PARALLEL_FROM = 8


def _place(out: Path, seed: int, params: str, town: str, scenario: str, n: int, side: str | None) -> list[Route] | str:
    """One placement call in a pool process: the routes, or why there are none (the CollectError's message)."""
    try:
        return _Placer(_Towns(out), seed, params).routes(town, scenario, n, side)
    except CollectError as exc:
        return str(exc)


def place_all(towns: _Towns, seed: int, params: str, requests: Sequence[tuple[str, str, int, str | None]],
              processes: int | None = None) -> list[list[Route] | str]:  # fmt: skip
    """``_Placer.routes`` for every (town, type, count, side) request, in order: the routes or the error's message.

    Each call depends on its arguments alone, so the calls run side by side on ``processes`` processes (default: one
    per core) and give what one process would; placing base's 3000 routes took 4 min on one core of an H100 host.
    """
    processes = min(processes or usable_cores(), len(requests))
    if processes <= 1 or len(requests) < PARALLEL_FROM:
        return [_place(towns.out, seed, params, *request) for request in requests]
    from concurrent.futures import ProcessPoolExecutor

    for town in dict.fromkeys(town for town, *_ in requests):
        towns.source(town)  # materialised here, once, before the processes load it
    with ProcessPoolExecutor(processes, mp_context=worker_context()) as pool:
        return list(pool.map(functools.partial(_place, towns.out, seed, params), *zip(*requests)))


def drawn_sides(slots: Sequence[Slot], params: str, seed: int) -> dict[int, str]:
    """The ``direction`` each slot of a type that draws one of several sides gets, drawn per slot from the set's
    weights (seeded by the slot's index and type, so that a slot keeps its side whatever the other slots are)."""
    from b2d_data.scenarios import placement

    out: dict[int, str] = {}
    for slot in slots:
        side = placement.drawn_side(slot.scenario, params, seed, slot.index)
        if side is not None:
            out[slot.index] = side
    return out


def _slot_routes(slots: Sequence[Slot], routes: Sequence[Route], attempts: int) -> dict[int, list[Route]]:
    """Routes of one (town, type) group dealt to its slots: attempt ``a`` of the ``j``-th slot is route
    ``a × len(slots) + j`` (first attempts on distinct places), renumbered and set to the slot's weather."""
    out: dict[int, list[Route]] = {}
    for j, slot in enumerate(slots):
        mine = []
        for a in range(attempts):
            route = replace(routes[a * len(slots) + j], id=slot_route_id(slot.index, a))
            if slot.weather is not None and slot.weather in PRESETS:
                route = with_weather(route, slot.weather)
            mine.append(route)
        out[slot.index] = mine
    return out


def _plan_routes(
    comp: Composition, towns: _Towns, config: CollectConfig
) -> tuple[dict[int, str | None], dict[int, list[Route]], dict[int, str]]:
    """Each slot's town, routes and (when it has none) the reason."""
    placer = _Placer(towns, config.seed, config.params)
    implemented = set(implemented_scenarios())
    errors: dict[int, str] = {}
    usable = []
    for slot in comp.slots:
        if slot.scenario in implemented:
            usable.append(slot)
        else:
            errors[slot.index] = f"{slot.scenario} cannot be generated yet (no behaviour or placement rule)"
    # Every pair assign_towns may ask about, probed side by side: a slot's own shipped town, and the generated towns
    # any slot may move to.
    shipped = set(towns.shipped)
    placer.probe([(s.town, s.scenario) for s in usable if s.town in shipped]
                 + [(town, scenario) for scenario in dict.fromkeys(s.scenario for s in usable)
                    for town in towns.generated])  # fmt: skip
    assigned = assign_towns(usable, placer.can_host, towns.shipped, towns.generated)
    # each slot keeps to its drawn side; one its town lacks (direction=left: a one-way road's left kerb) moves it
    assigned, pinned = move_sides(
        usable, assigned, drawn_sides(usable, config.params, config.seed), placer.has_side, towns.sided
    )
    groups: dict[tuple[str, str, str | None], list[Slot]] = {}
    for slot in usable:
        town = assigned[slot.index]
        if town is None:
            errors[slot.index] = f"no town holds a place for {slot.scenario}"
        else:
            groups.setdefault((town, slot.scenario, pinned.get(slot.index)), []).append(slot)
    routes: dict[int, list[Route]] = {}
    attempts = config.attempts_per_clip
    log.info("placing %d route(s) of %d (town, type) group(s)", sum(len(m) for m in groups.values()) * attempts,
             len(groups))  # fmt: skip
    requests = [(town, scenario, len(members) * attempts, side) for (town, scenario, side), members in groups.items()]
    for members, made in zip(groups.values(), place_all(towns, config.seed, config.params, requests)):
        if isinstance(made, str):
            errors.update({s.index: made for s in members})
        else:
            routes.update(_slot_routes(members, made, attempts))
    return assigned, routes, errors


def _plan_files(out: Path, name: str) -> tuple[Path, Path]:
    folder = out / PLANNED_ROUTES_DIR
    return folder / f"preset_{name}.xml", folder / f"preset_{name}.json"


def _save_plan(out: Path, comp: Composition, towns: dict[int, str | None], routes: dict[int, list[Route]],
               errors: dict[int, str], attempts: int) -> None:  # fmt: skip
    from b2d_data.scenarios.route_xml import write_routes

    xml, notes = _plan_files(out, comp.name)
    xml.parent.mkdir(parents=True, exist_ok=True)
    every = [r for index in sorted(routes) for r in routes[index]]
    body = {"slots": len(comp.slots), "attempts": attempts, "towns": {str(k): v for k, v in towns.items()},
            "errors": {str(k): v for k, v in errors.items()}}  # fmt: skip
    for path, write in ((xml, lambda p: write_routes(every, p)),
                        (notes, lambda p: p.write_text(json.dumps(body, indent=1), encoding="utf-8"))):  # fmt: skip
        temp = path.with_name(f".{path.name}.tmp-{os.getpid()}-000000")
        write(temp)
        os.replace(temp, path)


def _saved_plan(
    out: Path, comp: Composition, attempts: int
) -> tuple[dict[int, str | None], dict[int, list[Route]], dict[int, str]] | None:
    """The plan an earlier session saved for this composition and attempt count, or None."""
    from b2d_data.scenarios.route_xml import read_routes

    xml, notes = _plan_files(out, comp.name)
    if not (xml.is_file() and notes.is_file()):
        return None
    try:
        body = json.loads(notes.read_text(encoding="utf-8"))
        if body.get("slots") != len(comp.slots) or body.get("attempts") != attempts:
            log.info("the saved plan %s is for other settings; planning again", notes)
            return None
        saved = read_routes(xml)
        towns = {int(k): v for k, v in body["towns"].items()}
        errors = {int(k): str(v) for k, v in body["errors"].items()}
    except Exception as exc:  # noqa: BLE001 - any damage to the saved plan means: plan again
        log.warning("ignoring the saved plan %s: %s", notes, exc)
        return None
    routes: dict[int, list[Route]] = {}
    for route in saved:
        routes.setdefault(slot_of_route(route.id), []).append(route)
    log.info("using the %d routes planned earlier in %s", len(saved), xml)
    return towns, routes, errors


def preset_plan(config: CollectConfig) -> CollectionPlan:
    """The plan of ``config.preset``: one target of one clip per slot, in an order mixing the types."""
    assert config.preset is not None
    if config.attempts_per_clip >= ROUTE_ID_STRIDE:
        raise CollectError(f"--attempts-per-clip must be below {ROUTE_ID_STRIDE} with --preset")
    try:
        comp = compose(config.preset, config.n_scale, config.seed)
    except PresetError as exc:
        raise CollectError(str(exc)) from None
    out = Path(config.out)
    towns = _Towns(out)
    planned = _saved_plan(out, comp, config.attempts_per_clip) if config.resume else None
    if planned is None:
        planned = _plan_routes(comp, towns, config)
        _save_plan(out, comp, *planned, config.attempts_per_clip)
    assigned, routes, errors = planned
    plans = []
    used: dict[str, TownSource] = {}
    for slot in interleaved(comp.slots):
        tasks = []
        for route in routes.get(slot.index, []):
            source = used.setdefault(route.town, towns.source(route.town))
            tasks.append(RouteTask(route, source, slot.scenario, route_seed(config.seed, route.id), f"#{slot.index}"))
        plans.append(ScenarioPlan(slot.scenario, 1, tasks, errors.get(slot.index), group=f"#{slot.index}"))
    ids = {index: [str(r.id) for r in rs] for index, rs in routes.items()}
    preset = PresetPlan(comp, assigned, errors, ids)
    moved = sum(1 for s in comp.slots if assigned.get(s.index) not in (None, s.town))
    log.info("preset %s: %d clips, %d of them in a substitute town", comp.name, len(comp.slots), moved)
    return CollectionPlan(plans, list(used.values()), settings_of(config), preset=preset)


def write_manifest(out: Path, preset: PresetPlan, made: dict[str, str], config: CollectConfig) -> SplitManifest:
    """Write ``<out>/splits/<preset>.json``: the clips made (``made``: route id → clip) in their slots' parts, what
    each copies, and the slots still without a clip."""
    comp = preset.composition
    parts: dict[str, list[SplitEntry]] = {TRAIN: [], VAL: []}
    copies: dict[str, str] = {}
    missing: list[str] = []
    for slot in comp.slots:
        clip = next((made[r] for r in preset.route_ids.get(slot.index, []) if r in made), None)
        if clip is None:
            missing.append(slot.source)
            continue
        parts[slot.part].append(SplitEntry(clip))
        copies[clip] = slot.source
    extra: dict[str, Any] = {"preset": comp.name, "n_scale": config.n_scale, "params": config.params,
                             "copies": copies, "missing": missing, "left_out": preset.left_out()}  # fmt: skip
    manifest = SplitManifest(comp.name, tuple(sorted(parts[TRAIN])), tuple(sorted(parts[VAL])), config.seed,
                             f"b2d-collect --preset {comp.name}: {comp.source}", extra)  # fmt: skip
    manifest.save(out / SPLITS_DIR / f"{comp.name}.json")
    return manifest
