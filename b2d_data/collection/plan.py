"""The collection plan: each scenario's routes in attempt order, their towns and seeds, and option checks.

:func:`plan_collection` resolves the town (a generated preset, an OpenDRIVE file, or a folder of them for a route
file), builds each scenario's route list (``placement.make_routes`` with an attempt budget, or the routes of a
route XML file) and derives every route's seed from ``--seed`` and the route id, so that the same seed gives the
same routes, the same runs and the same annotations. A ``--preset`` (a Bench2Drive-sized corpus) is planned by
:mod:`~b2d_data.collection.preset_plan`: one target per clip it copies, over several types and towns.
"""

from __future__ import annotations

import contextlib
import difflib
import logging
import os
import tempfile
import zlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from b2d_data.collection.job import (
    CollectConfig,
    with_weather,
)
from b2d_data.collection.towns import (
    TOWN_SEED,
    TownError,
    TownSource,
    default_preset,
    load_map,
    preset_town_name,
    route_town,
    shipped_town,
    xodr_source,
)
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.scenario_types import BY_CLIP_PREFIX, BY_XML_TYPE, NO_SCENARIO
from b2d_data.format.weather import UnknownWeatherError, preset
from b2d_data.scenarios.route_xml import Route

if TYPE_CHECKING:
    from b2d_data.collection.preset_plan import PresetPlan
    from b2d_data.maps import Map

log = logging.getLogger(__name__)

#: Where a generated collection saves its planned routes (one route file per scenario).
PLANNED_ROUTES_DIR = "routes"
#: The settings a resumed collection must share with the one it continues.
#: Settings that change what a route produces; a resume with other values would mix incompatible clips.
FIXED_SETTINGS = ("seed", "town", "xodr", "routes_file", "weathers", "width", "height", "lidar_azimuth_steps",
                   "format_version", "sensors", "params", "preset", "n_scale")  # fmt: skip


class CollectError(Exception):
    """A problem the user can act on (bad option, unknown scenario or town, unreadable routes, busy folder)."""


@dataclass(frozen=True)
class RouteTask:
    """One route to attempt: the route, its (file-backed) town, its scenario, its seed and the group whose target
    it counts towards (empty: its scenario's)."""

    route: Route
    town: TownSource
    scenario: str
    seed: int
    group: str = ""

    @property
    def key(self) -> str:
        """The group this attempt counts towards: ``group``, else the scenario."""
        return self.group or self.scenario


@dataclass
class ScenarioPlan:
    """One target: a scenario's routes in attempt order and its clip target. A preset has one per clip it copies
    (``group`` names it); the summary adds up the plans of one scenario."""

    scenario: str
    target: int
    tasks: list[RouteTask] = field(default_factory=list)
    #: Why the scenario has no routes (placement failed), if it has none.
    error: str | None = None
    group: str = ""

    @property
    def key(self) -> str:
        """The name the runner keeps this target under: ``group``, else the scenario."""
        return self.group or self.scenario


@dataclass
class CollectionPlan:
    """Every scenario's routes, the towns they use, and the settings that must not change on resume."""

    scenarios: list[ScenarioPlan]
    towns: list[TownSource]
    settings: dict[str, Any]
    skipped: list[str] = field(default_factory=list)
    #: A preset's slots and their routes (None for other collections).
    preset: PresetPlan | None = None


def route_seed(seed: int, route_id: str) -> int:
    """The seed of one route: a function of the collection seed and the route id only."""
    state = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, zlib.crc32(str(route_id).encode("utf-8"))])
    return int(state.generate_state(1)[0] & 0x7FFFFFFF)


def resolve_scenario(name: str) -> str:
    """The XML type of a scenario name (XML type or clip prefix); unknown names list close matches."""
    if name in BY_XML_TYPE:
        return name
    if name in BY_CLIP_PREFIX:
        return BY_CLIP_PREFIX[name].xml_type
    if name == NO_SCENARIO:
        return name
    close = difflib.get_close_matches(name, sorted(set(BY_XML_TYPE) | set(BY_CLIP_PREFIX)), n=3, cutoff=0.5)
    hint = f" Did you mean {' or '.join(close)}?" if close else ""
    raise CollectError(f"unknown scenario {name!r}.{hint} Known scenarios: {', '.join(sorted(BY_XML_TYPE))}")


def implemented_scenarios() -> list[str]:
    """XML types that have both a behaviour and a placement rule (what a generated collection can hold)."""
    from b2d_data.scenarios import placement
    from b2d_data.scenarios.framework import SCENARIO_CLASSES, scenario_class

    with contextlib.suppress(Exception):
        scenario_class(next(iter(placement.LAYOUTS)))  # imports the catalog, filling the registry
    return sorted(t for t in placement.LAYOUTS if t in SCENARIO_CLASSES or t == NO_SCENARIO)


def _check_generated_scenario(name: str) -> str:
    xml_type = resolve_scenario(name)
    known = implemented_scenarios()
    if xml_type not in known:
        raise CollectError(
            f"scenario {xml_type!r} cannot be generated yet (no behaviour or placement rule); "
            f"implemented: {', '.join(known)}"
        )
    return xml_type


def _check_weathers(weathers: Sequence[int]) -> tuple[int, ...]:
    try:
        for w in weathers:
            preset(w)
    except UnknownWeatherError as exc:
        raise CollectError(str(exc.args[0] if exc.args else exc)) from None
    return tuple(int(w) for w in weathers)


def settings_of(config: CollectConfig) -> dict[str, Any]:
    """The settings recorded in ``collect.json`` (JSON-friendly)."""
    values = asdict(config)
    out: dict[str, Any] = {}
    for key in FIXED_SETTINGS:
        value = values[key]
        if isinstance(value, Path):
            value = str(value.resolve())
        elif isinstance(value, tuple):
            value = list(value)
        elif hasattr(value, "value"):
            value = value.value
        out[key] = value
    return out


def _generated_plan(config: CollectConfig) -> CollectionPlan:
    from b2d_data.scenarios import placement

    scenarios = list(dict.fromkeys(_check_generated_scenario(s) for s in config.scenarios))
    if config.xodr is not None:
        town = xodr_source(config.xodr)
    elif config.town is not None and (shipped := shipped_town(config.town)) is not None:
        town = shipped
    else:
        town = TownSource(preset=config.town or default_preset())
    town = _materialise(town, config.out)
    world_map = load_map(town)
    weathers = list(config.weathers) or None
    budget = max(1, config.attempts_per_clip) * config.n
    # only a town the user did not choose sends a drawn side it has no place for to another generated town
    sides = _SideTowns(config, world_map) if config.town is None and config.xodr is None else None
    sources = {world_map.name: town}
    plans = []
    for scenario in scenarios:
        plan = ScenarioPlan(scenario, config.n)
        saved = config.out / PLANNED_ROUTES_DIR / f"{scenario}.xml"
        allowed = {world_map.name, *(sides.towns if sides is not None else ())}
        routes = _saved_routes(saved, budget, allowed) if config.resume else []
        # The list for the full budget; a town with fewer places still gets the routes the target needs.
        for count in dict.fromkeys((budget, config.n)) if not routes else ():
            try:
                if sides is not None:
                    routes = sides.routes(scenario, count, weathers)
                else:
                    routes = placement.make_routes(world_map, scenario, count, config.seed, weathers, config.params)
                _save_routes(routes, saved)
                break
            except placement.PlacementError as exc:
                plan.error = str(exc)
        if routes:
            plan.error = None
        for r in routes:
            if r.town not in sources:
                sources[r.town] = _materialise(TownSource(preset=_preset_of(r.town)), config.out)
        plan.tasks = [RouteTask(r, sources[r.town], scenario, route_seed(config.seed, r.id)) for r in routes]
        if plan.error:
            log.warning("%s: %s", scenario, plan.error)
        plans.append(plan)
    return CollectionPlan(plans, list(sources.values()), settings_of(config))


def _preset_of(town: str) -> str:
    from b2d_data.maps import towngen

    return next(p.name for p in towngen.TOWN_PRESETS.values() if p.town == town)


class _SideTowns:
    """The default town's routes, with the draws of a ``direction`` it has no place for (``left`` of the kerb-side
    types: a one-way road's left kerb) placed in the first other generated town that has one."""

    def __init__(self, config: CollectConfig, world_map: Map) -> None:
        from b2d_data.maps import towngen

        self.config, self.map = config, world_map
        self.towns = [p.town for p in towngen.TOWN_PRESETS.values() if p.town != world_map.name]
        self._maps: dict[str, Map] = {}

    def _map(self, town: str) -> Map:
        from b2d_data.maps import load_opendrive, towngen

        if town not in self._maps:
            # probed in memory: only a town that gets routes is written into the corpus (by the plan's sources)
            with tempfile.TemporaryDirectory(prefix="b2d_side_town_") as folder:
                self._maps[town] = load_opendrive(towngen.write_town(_preset_of(town), TOWN_SEED, folder))
        return self._maps[town]

    def _host(self, scenario: str, side: str) -> Map | None:
        from b2d_data.scenarios import placement

        for town in self.towns:
            other = self._map(town)
            # a town without any place for the type lacks every side too
            if side not in placement.missing_sides(other, scenario, self.config.params):
                return other
        return None

    def routes(self, scenario: str, count: int, weathers: list[int] | None) -> list[Route]:
        """``count`` routes in attempt order: route ``k`` keeps the side drawn for it (seeded by the type and ``k``);
        the default town's routes are its first ones for that many (as without the move), renumbered after them."""
        from b2d_data.scenarios import placement

        seed, params = self.config.seed, self.config.params
        # missing_sides is empty for a type that draws no side, or only one
        hosts = {}
        for side in placement.missing_sides(self.map, scenario, params):
            host = self._host(scenario, side)
            if host is not None:
                hosts[side] = host
        if not hosts:
            return placement.make_routes(self.map, scenario, count, seed, weathers, params)
        drawn = [placement.drawn_side(scenario, params, seed, k) for k in range(count)]
        moved = {side: drawn.count(side) for side in hosts}
        stay = count - sum(moved.values())
        here = iter(placement.make_routes(self.map, scenario, stay, seed, weathers, params) if stay else [])
        there = {
            side: iter(placement.make_routes(hosts[side], scenario, n, seed, weathers, params, direction=side))
            for side, n in moved.items()
            if n
        }
        log.info("%s: %s of %d route(s) in %s (%s has no place for them)", scenario,
                 ", ".join(f"{n} {side}" for side, n in moved.items()), count,
                 "/".join(hosts[side].name for side in moved), self.map.name)  # fmt: skip
        out, extra = [], stay
        for side in drawn:
            if side in there:
                out.append(replace(next(there[side]), id=placement.route_id(seed, scenario, extra)))
                extra += 1
            else:
                out.append(next(here))
        return out


def _saved_routes(path: Path, budget: int, towns: set[str]) -> list[Route]:
    """The routes planned by an earlier session (so that a resume never depends on a re-run of the placement)."""
    if not path.is_file():
        return []
    try:
        routes = _read_route_file(path)
    except CollectError as exc:
        log.warning("ignoring the saved route list: %s", exc)
        return []
    if len(routes) < budget or any(r.town not in towns for r in routes):
        return []
    log.info("using the %d routes planned earlier in %s", len(routes), path)
    return routes


def _save_routes(routes: Sequence[Route], path: Path) -> None:
    from b2d_data.scenarios.route_xml import write_routes

    path.parent.mkdir(parents=True, exist_ok=True)
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}-000000")
    write_routes(routes, temp)
    os.replace(temp, path)


def _materialise(town: TownSource, out: Path) -> TownSource:
    try:
        return town.materialise(out)
    except TownError as exc:
        raise CollectError(str(exc)) from None


def _read_route_file(path: Path) -> list[Route]:
    from b2d_data.scenarios.route_xml import read_route_argument

    try:
        return read_route_argument(path)
    except B2DFormatError as exc:
        raise CollectError(f"cannot read route file: {exc}") from None


def _file_plan(config: CollectConfig) -> CollectionPlan:
    assert config.routes_file is not None
    routes = _read_route_file(config.routes_file)
    if not routes:
        raise CollectError(f"{config.routes_file} holds no route")
    bad = [r.id for r in routes if not str(r.id).isdigit()]
    if bad:
        raise CollectError(f"{config.routes_file}: route ids must be integers for clip names; got {bad[:5]}")
    if config.scenarios:
        wanted = {resolve_scenario(s) for s in config.scenarios}
        routes = [r for r in routes if (r.scenario_type or NO_SCENARIO) in wanted]
        if not routes:
            raise CollectError(f"{config.routes_file} has no route of scenario {', '.join(sorted(wanted))}")
    weathers = _check_weathers(config.weathers)
    towns: dict[str, TownSource | None] = {}
    skipped: list[str] = []
    for name in dict.fromkeys(r.town for r in routes):
        towns[name] = _town_for(config, name)
    missing = sorted(name for name, source in towns.items() if source is None)
    if missing:
        held = [r for r in routes if towns[r.town] is None]
        if config.xodr is None:
            where = "no --xodr was given"
        elif config.xodr.is_dir():
            where = f"{config.xodr} has no <Town>.xodr for them"
        else:
            where = f"--xodr gives the map {config.xodr.stem}"
        if len(held) == len(routes):
            raise CollectError(
                f"none of the {len(routes)} selected routes of {config.routes_file} can run: they are on "
                f"{', '.join(missing)} but {where}; pass --xodr with that town's file or a folder of <Town>.xodr"
            )
        log.warning("skipping %d route(s) on %s: no map for them (%s)", len(held), ", ".join(missing), where)
        skipped = [r.id for r in held]
        routes = [r for r in routes if towns[r.town] is not None]
    materialised = {name: _materialise(s, config.out) for name, s in towns.items() if s is not None}
    groups: dict[str, list[Route]] = {}
    for r in routes:
        if weathers:
            r = with_weather(r, weathers[route_seed(config.seed, r.id) % len(weathers)])
        groups.setdefault(r.scenario_type or NO_SCENARIO, []).append(r)
    plans = []
    for scenario, group in groups.items():
        target = len(group) if config.n is None else min(config.n, len(group))
        tasks = [RouteTask(r, materialised[r.town], scenario, route_seed(config.seed, r.id)) for r in group]
        plans.append(ScenarioPlan(scenario, target, tasks))
    return CollectionPlan(plans, list(materialised.values()), settings_of(config), skipped)


def _town_for(config: CollectConfig, town: str) -> TownSource | None:
    """A route file's town: the --xodr file or folder, else a generated preset or a shipped CARLA town of that name."""
    try:
        return route_town(town, config.xodr, config.town)
    except TownError as exc:
        raise CollectError(str(exc)) from None


def _check_preset(config: CollectConfig) -> None:
    from b2d_data.collection.presets import PRESET_NAMES, Composition, PresetError, scale

    if config.preset not in PRESET_NAMES:
        raise CollectError(f"unknown preset {config.preset!r}; presets: {', '.join(PRESET_NAMES)}")
    given = [flag for flag, value in (("--scenario", config.scenarios), ("--routes", config.routes_file),
                                      ("--town", config.town), ("--xodr", config.xodr), ("--weather", config.weathers))
             if value]  # fmt: skip
    if given:
        raise CollectError(f"--preset decides scenarios, towns and weathers itself; drop {', '.join(given)}")
    try:
        scale(Composition(config.preset, []), config.n_scale)  # the scaling rule's own check of the factor
    except PresetError as exc:
        raise CollectError(str(exc)) from None


def validate_config(config: CollectConfig) -> None:
    """Check the options before anything touches the disk (raises :class:`CollectError` naming the problem)."""
    if config.preset is not None:
        _check_preset(config)
    if config.n is not None and config.n < 1:
        raise CollectError(f"--n must be at least 1, got {config.n}")
    if config.workers < 1:
        raise CollectError(f"--workers must be at least 1, got {config.workers}")
    if config.town is not None and config.xodr is not None:
        raise CollectError("give either --town PRESET or --xodr FILE, not both")
    _check_weathers(config.weathers)
    try:
        if config.town is not None and shipped_town(config.town) is None:
            preset_town_name(config.town)
        if config.xodr is not None and not config.xodr.is_dir():
            xodr_source(config.xodr)
    except TownError as exc:
        raise CollectError(str(exc)) from None
    if config.ray_address is not None:
        from b2d_data.collection.ray_backend import RayUnavailableError, require_ray

        try:
            require_ray()
        except RayUnavailableError as exc:
            raise CollectError(str(exc)) from None
    if config.xodr is not None and config.xodr.is_dir() and config.routes_file is None:
        raise CollectError(f"--xodr {config.xodr} is a folder; without --routes give one OpenDRIVE file")
    if config.preset is not None:
        return  # _check_preset refused scenarios and route files
    if config.routes_file is not None:
        for name in config.scenarios:
            resolve_scenario(name)
        _read_route_file(config.routes_file)
    else:
        if not config.scenarios:
            raise CollectError("give at least one --scenario NAME (or a route file with --routes)")
        for name in config.scenarios:
            _check_generated_scenario(name)


def plan_collection(config: CollectConfig) -> CollectionPlan:
    """Resolve towns and scenarios and list every route to attempt, in order (raises :class:`CollectError`)."""
    validate_config(config)
    if config.preset is not None:
        from b2d_data.collection.preset_plan import preset_plan

        return preset_plan(config)
    if config.routes_file is not None:
        return _file_plan(config)
    if config.n is None:
        config = replace(config, n=1)
    return _generated_plan(config)
