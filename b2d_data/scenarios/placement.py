"""Scenario placement: where a town holds a scenario's layout, and Bench2Drive-like routes through those places.

:func:`find_candidates` searches the town's lane graph for trigger points where a scenario type's layout exists
(e.g. Accident: a second same-direction lane and a long junction-free stretch; junction turns: a connection making
the right turn with the right signals and the flow's entry). :func:`make_routes` turns candidates into route XML
:class:`~b2d_data.scenarios.route_xml.Route` objects (keypoints 2 m apart, the trigger point, parameters drawn
from a :mod:`~b2d_data.scenarios.param_ranges` set, two weather entries at 0 and 100 %), checking each one by
densifying it exactly as the leaderboard does and setting up the scenario on it. Layouts are sized for
bench2drive220's distances; the training set's further actors lengthen each route's junction-free stretch and the
route itself. Each type's :class:`~b2d_data.scenarios.catalog.layout.Layout` and the checks that find its places
live with its scenarios in the catalog (registered in :data:`~b2d_data.scenarios.catalog.layout.LAYOUTS`, which
this module re-exports). Everything is deterministic for (town, scenario type, n, seed, parameter set); route ids are
``(seed × 100 + type index) × 10000 + k``.
"""

from __future__ import annotations

import logging
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from b2d_data.format.scenario_types import LB2_ONLY_TYPES, NO_SCENARIO, SCENARIO_TYPES
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import WEATHER_IDS, preset
from b2d_data.maps import Map, Waypoint
from b2d_data.scenarios.catalog.junctions import JUNCTION_SEARCH, junction_entry
from b2d_data.scenarios.catalog.layout import (
    CHECK_STEP,
    KEYPOINT_SPACING,
    LAYOUTS,
    Layout,
    layout_of,
    signal_lanes,
    through_junction,
)
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    junction_lanes,
    lane_walk,
    move_along,
    yaw_diff,
)
from b2d_data.scenarios.framework import ScenarioContext, ScenarioError, scenario_class
from b2d_data.scenarios.param_ranges import BENCH2DRIVE220, DEFAULT_PARAMS, Choice, ParamSet, param_set
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import Route, ScenarioConfig
from b2d_data.scenarios.triggers import trigger_route_index

log = logging.getLogger(__name__)

#: Spacing of candidate trigger points along lanes (m).
CANDIDATE_SPACING = 20.0
#: Lane runs are measured up to this length (m); larger than any stretch a layout asks for.
RUN_CAP = 1000.0
#: A dense route may stray this far from the planned lane path before the candidate is rejected (m).
MAX_ROUTE_DEVIATION = 1.5
#: When no place gives a route with its first draw, each is drawn again up to this many times.
REDRAWS = 5


class PlacementError(ValueError):
    """A town without the layout a scenario type needs (the message names the layout)."""


# ------------------------------------------------------------------------------------------------ candidates


@dataclass(frozen=True, eq=False)
class Candidate:
    """A place for one scenario: its trigger waypoint and how the route reaches it and leaves it.

    Straight candidates walk ``pre`` m back and the rest of the route length forward along the lane; junction
    candidates run ``approach`` m before the junction, through ``connection`` and ``departure`` m beyond it.
    ``fixed`` holds parameters the layout decides (e.g. OppositeVehicleRunningRedLight's ``direction``).
    """

    scenario_type: str
    layout: str
    trigger: Waypoint
    connection: JunctionLane | None = None
    fixed: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    #: The layout the candidate was found with (None: the type's default in ``LAYOUTS``).
    layout_spec: Layout | None = None

    @property
    def spec(self) -> Layout:
        """The layout this candidate was found with."""
        return self.layout_spec if self.layout_spec is not None else LAYOUTS[self.scenario_type]

    @property
    def location(self) -> Location:
        """The trigger waypoint's location."""
        return self.trigger.transform.location

    def path(self, rng: np.random.Generator) -> tuple[list[Waypoint], Waypoint] | None:
        """The planned route as lane waypoints 2 m apart and its trigger waypoint (None when the lanes end)."""
        spec = self.spec
        step = KEYPOINT_SPACING
        if self.connection is None and spec.path_builder is not None:
            built = spec.path_builder(self.trigger, rng, spec.length)
            return (built, self.trigger) if built else None
        if self.connection is None:
            return self.straight_path(self.draw_pre(rng))
        conn = self.connection
        if spec.route_path is not None:
            return spec.route_path(conn, rng)
        approach = float(rng.uniform(*spec.approach))
        departure = float(rng.uniform(*spec.departure))
        back = lane_walk(conn.entry, approach, forward=False, step=step)
        if any(wp.is_junction for wp in back) or len(back) * step < spec.approach[0]:
            return None
        through = through_junction(conn, departure, spec.departure[0], spec.merge_left_after, rng)
        if through is None:
            return None
        path = list(reversed(back)) + through
        offset = float(rng.uniform(*spec.trigger_offset))
        trigger = path[min(round(offset / step), len(back) - 1)]
        return path, trigger

    @property
    def is_straight(self) -> bool:
        """Its route follows the trigger's lane (no junction, no path builder)."""
        return self.connection is None and self.spec.path_builder is None

    def draw_pre(self, rng: np.random.Generator) -> float:
        """Straight candidates: metres of route before the trigger."""
        spec = self.spec
        return float(rng.uniform(*spec.pre)) if spec.pre[1] > 0 else 0.0

    def straight_path(self, pre: float, extra: float = 0.0) -> tuple[list[Waypoint], Waypoint] | None:
        """Straight candidates: ``pre`` m before the trigger and the layout's length (plus ``extra`` m) after it."""
        spec = self.spec
        step = KEYPOINT_SPACING
        clear = spec.clear_after + extra
        back = lane_walk(self.trigger, pre, forward=False, step=step) if pre > 0 else [self.trigger]
        ahead = lane_walk(self.trigger, spec.length + extra - pre, step=step)
        # end before the next junction when the scenario's stretch is covered: junction traffic is no part of
        # these scenarios and only makes their routes longer to finish
        first_junction = next((k for k, wp in enumerate(ahead) if wp.is_junction), None)
        if first_junction is not None and (first_junction - 3) * step >= clear:
            ahead = ahead[: first_junction - 2]
        if (len(ahead) - 1) * step < clear:
            return None
        return list(reversed(back)) + ahead[1:], self.trigger


def _check_type(scenario_type: str, params: str = DEFAULT_PARAMS) -> Layout:
    if scenario_type != NO_SCENARIO:
        scenario_class(scenario_type)  # unknown types: error listing the known ones
    try:
        return layout_of(scenario_type, params)
    except KeyError:
        raise PlacementError(f"no placement rule for scenario type {scenario_type!r}") from None


class _RunLength:
    """Metres of good lane (junction-free, ``lane_ok``) from a waypoint on, in 5 m steps, memoised along lanes.

    ``run(p) = 0`` for a bad point, else ``5 + run(next(p))`` (a dead end counts as bad), saturating at ``cap``
    (which must exceed every distance asked for). Walks from neighbouring candidates share their points, so every
    lane point is examined about once.
    """

    def __init__(self, lane_ok: Callable[[Waypoint], bool] | None, forward: bool, cap: float) -> None:
        self.lane_ok = lane_ok
        self.forward = forward
        self.cap = cap
        self.memo: dict[tuple[int, int, int, float], float] = {}

    def _key(self, wp: Waypoint) -> tuple[int, int, int, float]:
        return (wp.road_id, wp.section_id, wp.lane_id, round(wp.s, 1))

    def __call__(self, wp: Waypoint | None) -> float:
        chain: list[tuple[int, int, int, float]] = []
        tail = 0.0
        current = wp
        while current is not None:
            key = self._key(current)
            if key in self.memo:
                tail = self.memo[key]
                break
            if current.is_junction or (self.lane_ok is not None and not self.lane_ok(current)):
                self.memo[key] = 0.0
                break
            chain.append(key)
            if len(chain) * CHECK_STEP >= self.cap:
                break
            current = move_along(current, CHECK_STEP, forward=self.forward, step=CHECK_STEP)
        for key in reversed(chain):
            tail = min(self.cap, tail + CHECK_STEP)
            self.memo[key] = tail
        return self.memo[self._key(wp)] if wp is not None else 0.0

    def ok(self, wp: Waypoint, distance: float) -> bool:
        """The sample points 5, 10, … ``distance`` m from ``wp`` are all good."""
        if distance <= 0:
            return True
        nxt = move_along(wp, CHECK_STEP, forward=self.forward, step=CHECK_STEP)
        return nxt is not None and self(nxt) >= distance - 1e-6


def _stretch_ok(wp: Waypoint, distance: float, forward: bool, lane_ok: Callable[[Waypoint], bool] | None) -> bool:
    """The lane is junction-free (and ``lane_ok``) at 5 m steps over ``distance`` m from ``wp``."""
    return _RunLength(lane_ok, forward, RUN_CAP).ok(wp, distance)


def _turn_ahead(wp: Waypoint, distance: float, step: float = 10.0) -> float:
    """Largest heading difference (deg) from ``wp`` over the next ``distance`` m of lane (10 m samples)."""
    yaw0 = wp.transform.rotation.yaw
    worst, current, walked = 0.0, wp, 0.0
    while walked < distance and current is not None:
        current = move_along(current, step, step=step)
        walked += step
        if current is not None:
            worst = max(worst, abs(yaw_diff(yaw0, current.transform.rotation.yaw)))
    return worst


def _lane_test(scenario_type: str, spec: Layout, params: ParamSet) -> Callable[[Waypoint], bool] | None:
    """The candidates' lane test: ``lane_ok``, or any side's test where the set draws ``direction``."""
    sides = params.choices(scenario_type, "direction")
    if spec.directions is None or not sides:
        return spec.lane_ok
    tests = [spec.directions[side] for side in sides]
    if len(tests) == 1:
        return tests[0]
    return lambda wp: any(test(wp) for test in tests)


def _straight_candidates(town: Map, scenario_type: str, spec: Layout, params: ParamSet) -> list[Candidate]:
    out = []
    lane_ok = _lane_test(scenario_type, spec, params)
    sides = params.choices(scenario_type, "direction")
    ahead = _RunLength(lane_ok, True, RUN_CAP)
    behind = _RunLength(None, False, RUN_CAP)
    for wp in town.generate_waypoints(CANDIDATE_SPACING):
        if wp.is_junction or lane_ok is None or not lane_ok(wp):
            continue
        if not ahead.ok(wp, spec.clear_after):
            continue
        if spec.clear_before > 0 and not behind.ok(wp, spec.clear_before):
            continue
        if spec.max_turn is not None and _turn_ahead(wp, spec.clear_after) > spec.max_turn:
            continue
        if spec.extra is not None and not _extra_holds(town, spec, wp, sides):
            continue
        out.append(Candidate(scenario_type, spec.name, wp, layout_spec=spec))
    return out


def _extra_holds(town: Map, spec: Layout, wp: Waypoint, sides: Sequence[str]) -> bool:
    """``extra`` accepts the trigger, or (``extra_sides``) some drawn side holds: its lane test, and ``extra`` where
    it checks that side."""
    assert spec.extra is not None
    if spec.extra_sides is None or spec.directions is None or not sides:
        return spec.extra(town, wp)
    return any(
        spec.directions[side](wp) and (side not in spec.extra_sides or spec.extra(town, wp)) for side in sides
    )


def _junction_candidates(town: Map, scenario_type: str, spec: Layout) -> list[Candidate]:
    lights = town.traffic_lights()
    lit_junctions = {s.junction_id for s in lights}
    lit_lanes = signal_lanes(lights)
    stop_lanes = signal_lanes(town.stop_signs())
    out = []
    for junction_id in sorted(town.junctions):
        junction = town.junctions[junction_id]
        lanes = junction_lanes(junction)
        lanes.sort(key=lambda c: (c.entry.road_id, c.entry.lane_id, c.exit.road_id, c.exit.lane_id))
        for conn in lanes:
            if conn.turn not in spec.turns:
                continue
            # signals reference either the incoming lane or (CARLA's towns) the junction's connecting lane
            keys = {(conn.entry.road_id, conn.entry.lane_id), (conn.start.road_id, conn.start.lane_id)}
            if spec.signalized is True and not keys & lit_lanes:
                continue
            if spec.signalized is False and (junction_id in lit_junctions or keys & lit_lanes):
                continue
            if spec.stop_sign and not keys & stop_lanes:
                continue
            if spec.junction_ok is not None and not spec.junction_ok(town, conn, lanes):
                continue
            if not _stretch_ok(conn.entry, spec.approach[1], False, None):
                continue
            if not _stretch_ok(conn.exit, spec.departure[1], True, None):
                continue
            variants = spec.junction_extra(conn, lanes) if spec.junction_extra is not None else [{}]
            for fixed in variants:
                out.append(Candidate(scenario_type, spec.name, conn.entry, conn, fixed, spec))
    return out


def find_candidates(town: Map, scenario_type: str, params: str | ParamSet = DEFAULT_PARAMS) -> list[Candidate]:
    """Every place in ``town`` where ``scenario_type``'s layout exists for the parameter set, in a fixed order."""
    ranges = param_set(params)
    spec = _check_type(scenario_type, ranges.name)
    if spec.is_junction:
        found = _junction_candidates(town, scenario_type, spec)
    else:
        found = _straight_candidates(town, scenario_type, spec, ranges)
    log.info("%s: %d candidate places for %s", town.name, len(found), scenario_type)
    return found


def missing_sides(
    town: Map,
    scenario_type: str,
    params: str | ParamSet = DEFAULT_PARAMS,
    candidates: Sequence[Candidate] | None = None,
) -> tuple[str, ...]:
    """The ``direction`` values the set draws for ``scenario_type`` that no place in ``town`` holds (e.g. ``left`` of
    the kerb-side types in a town of two-way roads); empty for types without a drawn side."""
    ranges = param_set(params)
    spec = _check_type(scenario_type, ranges.name)
    sides = ranges.choices(scenario_type, "direction")
    if spec.directions is None or len(sides) < 2:
        return ()
    found = find_candidates(town, scenario_type, ranges) if candidates is None else candidates
    return tuple(side for side in sides if not any(spec.directions[side](c.trigger) for c in found))


def drawn_side(scenario_type: str, params: str | ParamSet, seed: int, k: int) -> str | None:
    """The ``direction`` drawn for the ``k``-th route (or preset slot) of a type that draws one of several sides,
    seeded by (seed, type, ``k``) so that it keeps its side whatever the others draw; None for other types."""
    spec = param_set(params).ranges(scenario_type).get("direction")
    if not isinstance(spec, Choice) or len(spec.values) < 2:
        return None
    return spec.draw(np.random.default_rng([int(seed), zlib.crc32(scenario_type.encode("utf-8")), k]))


# ------------------------------------------------------------------------------------------------ parameters


def _reach_extra(scenario_type: str, spec: Layout, params: Mapping[str, Mapping[str, str]]) -> tuple[float, bool]:
    """Metres the drawn ``reach_param`` lies beyond bench2drive220's largest value (>= 0), and whether it lies
    outside bench2drive220's range (the layout's ``extra`` checked other distances)."""
    base = BENCH2DRIVE220.int_range(scenario_type, spec.reach_param) if spec.reach_param else None
    if base is None or spec.reach_param not in params:
        return 0.0, False
    value = float(params[spec.reach_param]["value"])
    return max(0.0, value - base.hi), not base.lo <= value <= base.hi


def _stretch_holds(wp: Waypoint, distance: float, lane_ok: Callable[[Waypoint], bool], max_turn: float | None) -> bool:
    """The lane is junction-free, ``lane_ok`` and (with ``max_turn``) straight-ish at 5 m steps over ``distance`` m."""
    if not _RunLength(lane_ok, True, distance + CHECK_STEP).ok(wp, distance):
        return False
    return max_turn is None or _turn_ahead(wp, distance) <= max_turn


def _open_stretch_holds(
    wp: Waypoint, ahead: float, behind: float, lane_ok: Callable[[Waypoint], bool], max_turn: float | None
) -> bool:
    """:attr:`Layout.reach_through_junctions`: ``ahead`` m of lane (straightest branches) ``lane_ok`` outside
    junctions and turning at most ``max_turn``; ``behind`` m of lane back whose walk forward returns to ``wp``."""
    walk = lane_walk(wp, ahead, step=CHECK_STEP)
    if (len(walk) - 1) * CHECK_STEP < ahead - 1e-6 or not all(p.is_junction or lane_ok(p) for p in walk):
        return False
    if max_turn is not None and _turn_ahead(wp, ahead) > max_turn:
        return False
    back = lane_walk(wp, behind, forward=False, step=CHECK_STEP)
    if (len(back) - 1) * CHECK_STEP < behind - 1e-6:
        return False
    again = lane_walk(back[-1], behind, step=CHECK_STEP)[-1]
    return again.transform.location.distance_2d(wp.transform.location) < 2.0 * CHECK_STEP


def _fits(
    town: Map,
    candidate: Candidate,
    params: Mapping[str, Mapping[str, str]],
    extra: float,
    outside: bool,
    set_sides: int,
) -> bool:
    """A straight candidate holds the drawn parameters: its stretch reaches the actors and the drawn side."""
    spec = candidate.spec
    trigger = candidate.trigger
    side = params.get("direction", {}).get("value")
    lane_ok = spec.directions[side] if spec.directions is not None and side in spec.directions else spec.lane_ok
    ahead = spec.clear_after + spec.reach_ahead * extra
    behind = spec.clear_before + spec.reach_behind * extra
    if spec.reach_through_junctions and lane_ok is not None:
        return extra <= 0 or _open_stretch_holds(trigger, ahead, behind, lane_ok, spec.max_turn)
    if (
        (extra > 0 or set_sides > 1)
        and lane_ok is not None
        and not _stretch_holds(trigger, ahead, lane_ok, spec.max_turn)
    ):
        return False
    if extra > 0 and spec.reach_behind > 0 and not _stretch_ok(trigger, behind, False, None):
        return False
    if spec.extra_sides is not None and side is not None:
        # the candidate may hold another side only: check this side's own tests at the trigger
        if lane_ok is not None and not lane_ok(trigger):
            return False
        if side not in spec.extra_sides:
            return True
        if spec.extra is not None and not spec.extra(town, trigger):
            return False
    if outside and spec.reach_ok is not None and spec.reach_param is not None:
        return spec.reach_ok(town, trigger, float(params[spec.reach_param]["value"]))
    return True


# ------------------------------------------------------------------------------------------------ routes


def route_id(seed: int, scenario_type: str, k: int) -> str:
    """Route id: unique over seeds, types and the first 10 000 routes of a call."""
    # NoScenario routes take the index after the 44 types, the LB2.0-only types the ones after it
    order = [t.xml_type for t in SCENARIO_TYPES] + [NO_SCENARIO] + [t.xml_type for t in LB2_ONLY_TYPES]
    index = order.index(scenario_type) if scenario_type in order else len(SCENARIO_TYPES)
    return str((int(seed) * 100 + index) * 10000 + k + 1)


#: No keypoint this close after a lane change of the path (m): the planner makes the change itself, jumping a few
#: metres ahead on the new lane, and a keypoint inside that jump would make the route trace back.
LANE_CHANGE_KEYPOINT_GAP = 10.0


def _keypoints(path: Sequence[Waypoint]) -> tuple[Location, ...]:
    """Keypoints of a lane path: its points outside junctions (the planner finds the connection between them),
    except those within ``LANE_CHANGE_KEYPOINT_GAP`` m after a change to a neighbouring lane."""
    out: list[Location] = []
    change: Location | None = None
    for k, wp in enumerate(path):
        if wp.is_junction:
            continue
        prev = path[k - 1] if k > 0 else None
        loc = wp.transform.location
        if prev is not None and not prev.is_junction and prev.road_id == wp.road_id and prev.lane_id != wp.lane_id:
            change = prev.transform.location
        if change is not None and loc.distance_2d(change) < LANE_CHANGE_KEYPOINT_GAP:
            continue
        out.append(loc)
    return tuple(out)


def _deviation(dense: DenseRoute, path: Sequence[Waypoint]) -> float:
    planned = np.array([[wp.transform.location.x, wp.transform.location.y] for wp in path])
    d = np.hypot(dense.locations[:, None, 0] - planned[None, :, 0], dense.locations[:, None, 1] - planned[None, :, 1])
    return float(d.min(axis=1).max())


def _junction_near(scenario_type: str, dense: DenseRoute, config: ScenarioConfig) -> bool:
    """Whether a junction type's route enters a junction within :data:`JUNCTION_SEARCH` m of the trigger."""
    # Placement's own rule: the build (LB2.0's) takes the first junction however far, but a generated route keeps
    # its junction close to the trigger. A trigger off the route is left to the build, which reports it.
    if not scenario_class(scenario_type).junction_layout:
        return True
    index = trigger_route_index(dense, config.trigger_point)
    return index is None or junction_entry(dense, index, JUNCTION_SEARCH) is not None


def _route_for(
    town: Map,
    candidate: Candidate,
    rng: np.random.Generator,
    rid: str,
    index: int,
    weather_id: int,
    params_set: ParamSet = BENCH2DRIVE220,
) -> Route | None:
    """Build and check one route on a candidate; None when it does not hold up."""
    pre = candidate.draw_pre(rng) if candidate.is_straight else 0.0
    planned = candidate.straight_path(pre) if candidate.is_straight else candidate.path(rng)
    if planned is None:
        return None
    keypoints = _keypoints(planned[0])
    if len(keypoints) < 2:
        return None
    params = params_set.draw(candidate.scenario_type, rng)
    params.update({k: dict(v) for k, v in candidate.fixed.items()})
    spec = candidate.spec
    if candidate.is_straight:
        # far-out actors (training ranges) need a longer junction-free stretch and route than the layout's
        extra, outside = _reach_extra(candidate.scenario_type, spec, params)
        sides = len(params_set.choices(candidate.scenario_type, "direction"))
        if not _fits(town, candidate, params, extra, outside, sides):
            log.debug("%s: the place has no room for %s", rid, params)
            return None
        if extra > 0:
            planned = candidate.straight_path(pre, spec.reach_ahead * extra)
            if planned is None:
                return None
            keypoints = _keypoints(planned[0])
    path, trigger = planned
    if spec.path_parameters is not None:
        derived = spec.path_parameters(candidate.connection, path)
        if derived is None:
            return None
        params.update(derived)
    t = trigger.transform
    config = ScenarioConfig(
        name=f"{candidate.scenario_type}_{index}", type=candidate.scenario_type,
        trigger_point=Transform(Location(t.location.x, t.location.y, t.location.z), Rotation(yaw=t.rotation.yaw)),
        other_parameters=params,
    )  # fmt: skip
    try:
        dense = DenseRoute.from_keypoints(town, keypoints)
    except (ValueError, RuntimeError) as exc:
        log.debug("%s: no dense route (%s)", rid, exc)
        return None
    if _deviation(dense, path) > MAX_ROUTE_DEVIATION:
        log.debug("%s: the planner's route leaves the planned lanes", rid)
        return None
    weather = preset(weather_id)
    if candidate.scenario_type == NO_SCENARIO:
        return Route(id=rid, town=town.name, waypoints=keypoints, weathers=((0.0, weather), (100.0, weather)))
    if not _junction_near(candidate.scenario_type, dense, config):
        log.debug("%s: the route enters no junction within %.0f m of the trigger", rid, JUNCTION_SEARCH)
        return None
    try:
        scenario_class(candidate.scenario_type)(
            ScenarioContext(
                sim=None,
                map=town,
                route=dense,
                config=config,  # type: ignore[arg-type]
                rng=np.random.default_rng(0),
                ego_id=-1,
            )
        )
    except ScenarioError as exc:
        log.debug("%s: scenario set-up rejected the place: %s", rid, exc)
        return None
    return Route(
        id=rid, town=town.name, waypoints=keypoints, scenarios=(config,), weathers=((0.0, weather), (100.0, weather))
    )


def make_routes(
    town: Map,
    scenario_type: str,
    n: int,
    seed: int = 0,
    weathers: Sequence[int] | None = None,
    params: str | ParamSet = DEFAULT_PARAMS,
    direction: str | None = None,
) -> list[Route]:
    """``n`` routes holding one ``scenario_type`` scenario each, on distinct places while there are enough.

    ``weathers`` lists the preset ids to draw from (default: all 23); ``params`` names the parameter ranges
    (:mod:`~b2d_data.scenarios.param_ranges`: ``training``, the default, or ``bench2drive220``). A place too short
    for the drawn distances is skipped, so long distances come from the towns' longer roads. ``direction`` keeps
    the drawn ``direction`` to one of the set's sides (None: drawn as the set has it; a side the town has no place
    for is then logged, as its draws end up on the other side). Raises :class:`PlacementError` when the town lacks
    the layout (message names it) or no candidate survives the checks.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    ranges = param_set(params)
    spec = _check_type(scenario_type, ranges.name)
    if direction is not None:
        ranges = ranges.pinned(scenario_type, "direction", direction)
    pool = tuple(int(w) for w in weathers) if weathers is not None else WEATHER_IDS
    for w in pool:
        preset(w)  # unknown ids raise here, naming the valid ones
    if not pool:
        raise ValueError("weathers must list at least one preset id")
    candidates = find_candidates(town, scenario_type, ranges)
    if not candidates:
        raise PlacementError(
            f"{town.name} has no place for {scenario_type}: layout '{spec.name}' missing ({spec.description})"
        )
    if direction is None and n > 0:
        lacking = missing_sides(town, scenario_type, ranges, candidates)
        if lacking:
            # the drawn side is redrawn at the next place until one fits: the routes keep to the other side
            log.warning(
                "%s has no place for %s with direction=%s (layout: %s); those draws are placed on the other side",
                town.name, scenario_type, "/".join(lacking), spec.description,
            )  # fmt: skip
    rng = np.random.default_rng([int(seed), zlib.crc32(scenario_type.encode("utf-8"))])
    order = [int(i) for i in rng.permutation(len(candidates))]
    routes: list[Route] = []
    usable: list[Candidate] = []

    def draw(candidate: Candidate) -> Route | None:
        """A route at ``candidate`` with fresh draws, numbered after the routes made so far."""
        k = len(routes)
        return _route_for(town, candidate, rng, route_id(seed, scenario_type, k), k + 1,
                          pool[int(rng.integers(len(pool)))], ranges)  # fmt: skip

    for i in order:
        if len(routes) >= n:
            break
        route = draw(candidates[i])
        if route is not None:
            routes.append(route)
            usable.append(candidates[i])
    # no place worked with its first draw (a town with a single place, e.g. one highway exit): redraw each a few
    # times, as the draws (approach, departure, parameters) decide whether the planner's route stays on the lanes
    for _ in range(REDRAWS if not usable and n > 0 else 0):
        for i in order:
            route = draw(candidates[i])
            if route is not None:
                routes.append(route)
                usable.append(candidates[i])
                break
        if usable:
            break
    if not usable and n > 0:
        raise PlacementError(
            f"{town.name}: none of the {len(candidates)} places with layout '{spec.name}' gives a valid "
            f"{scenario_type} route"
        )
    # more routes than places: reuse the good places with fresh parameters and route extents
    attempts = 0
    while len(routes) < n and attempts < 20 * n:
        attempts += 1
        route = draw(usable[len(routes) % len(usable)])
        if route is not None:
            routes.append(route)
    if len(routes) < n:
        raise PlacementError(f"{town.name}: only {len(routes)} of {n} {scenario_type} routes could be built")
    return routes
