"""Scenario placement: where a town holds a scenario's layout, and Bench2Drive-like routes through those places.

:func:`find_candidates` searches the town's lane graph for trigger points where a scenario type's layout exists
(e.g. Accident: a second same-direction lane and a long junction-free stretch; junction turns: a connection making
the right turn with the right signals and the flow's entry). :func:`make_routes` turns candidates into route XML
:class:`~b2d_data.scenarios.route_xml.Route` objects (keypoints 2 m apart, the trigger point, parameters drawn
from a :mod:`~b2d_data.scenarios.param_ranges` set, two weather entries at 0 and 100 %), checking each one by
densifying it exactly as the leaderboard does and setting up the scenario on it. Layouts are sized for
bench2drive220's distances; the training set's further actors lengthen each route's junction-free stretch and the
route itself. Everything is deterministic for (town, scenario type, n, seed, parameter set); route ids are
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
from b2d_data.maps import LaneChange, LaneType, Map, Waypoint
from b2d_data.scenarios.catalog import enter_flow_v2, priority_at_junction
from b2d_data.scenarios.catalog.crossing_bicycles import bicycle_path
from b2d_data.scenarios.catalog.junctions import walk_back_to_source
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    connection,
    entries_from,
    find_side_lane,
    flow_into_exit,
    is_driving,
    is_outermost_driving,
    junction_lanes,
    lane_walk,
    move_along,
    opposite_driving_neighbour,
    same_direction_driving_neighbour,
    same_lane,
    yaw_diff,
)
from b2d_data.scenarios.framework import ScenarioContext, ScenarioError, scenario_class
from b2d_data.scenarios.param_ranges import BENCH2DRIVE220, DEFAULT_PARAMS, ParamSet, param_set
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import Route, ScenarioConfig

log = logging.getLogger(__name__)

#: Spacing of route keypoints, as in Bench2Drive's route files (m).
KEYPOINT_SPACING = 2.0
#: Spacing of candidate trigger points along lanes (m).
CANDIDATE_SPACING = 20.0
#: Step of the lane walks that check a stretch (m).
CHECK_STEP = 5.0
#: Lane runs are measured up to this length (m); larger than any stretch a layout asks for.
RUN_CAP = 1000.0
#: Obstacle/highway routes are about this long (m).
ROUTE_LENGTH = 150.0
#: Largest heading change (deg) over the stretch of an obstacle scenario ("straight-ish").
STRAIGHTISH = 30.0
#: A dense route may stray this far from the planned lane path before the candidate is rejected (m).
MAX_ROUTE_DEVIATION = 1.5


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

    @property
    def location(self) -> Location:
        """The trigger waypoint's location."""
        return self.trigger.transform.location

    def path(self, rng: np.random.Generator) -> tuple[list[Waypoint], Waypoint] | None:
        """The planned route as lane waypoints 2 m apart and its trigger waypoint (None when the lanes end)."""
        spec = LAYOUTS[self.scenario_type]
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
        through = _through_junction(conn, departure, spec.departure[0], spec.merge_left_after, rng)
        if through is None:
            return None
        path = list(reversed(back)) + through
        offset = float(rng.uniform(*spec.trigger_offset))
        trigger = path[min(round(offset / step), len(back) - 1)]
        return path, trigger

    @property
    def is_straight(self) -> bool:
        """Its route follows the trigger's lane (no junction, no path builder)."""
        return self.connection is None and LAYOUTS[self.scenario_type].path_builder is None

    def draw_pre(self, rng: np.random.Generator) -> float:
        """Straight candidates: metres of route before the trigger."""
        spec = LAYOUTS[self.scenario_type]
        return float(rng.uniform(*spec.pre)) if spec.pre[1] > 0 else 0.0

    def straight_path(self, pre: float, extra: float = 0.0) -> tuple[list[Waypoint], Waypoint] | None:
        """Straight candidates: ``pre`` m before the trigger and the layout's length (plus ``extra`` m) after it."""
        spec = LAYOUTS[self.scenario_type]
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


def _departure(
    exit_wp: Waypoint, length: float, merge_left_after: tuple[float, float] | None, rng: np.random.Generator
) -> list[Waypoint] | None:
    """Lane points 2 m apart over ``length`` m from a junction exit, changing into the left lane on the way when
    ``merge_left_after`` asks for it (None when that lane is missing)."""
    step = KEYPOINT_SPACING
    if merge_left_after is None:
        return lane_walk(exit_wp, length, step=step)
    keep = float(rng.uniform(*merge_left_after))
    own = lane_walk(exit_wp, keep, step=step)
    left = same_direction_driving_neighbour(own[-1], "left")
    if left is None:
        return None
    # the next keypoint is one step ahead on the left lane: the planner makes the change between the two
    return own + lane_walk(left, length - keep, step=step)[1:]


def _through_junction(
    conn: JunctionLane,
    departure: float,
    min_departure: float,
    merge_left_after: tuple[float, float] | None = None,
    rng: np.random.Generator | None = None,
) -> list[Waypoint] | None:
    """Lane waypoints 2 m apart through ``conn`` and ``departure`` m beyond it, changing left on the way as
    :func:`_departure` does when ``merge_left_after`` is given (None when the lane ends within ``min_departure``
    m or meets another junction)."""
    step = KEYPOINT_SPACING
    inside = [conn.start]
    while inside[-1].is_junction and len(inside) < 200:
        options = [o for o in inside[-1].next(step) if o.road_id == conn.start.road_id or not o.is_junction]
        if not options:
            break
        inside.append(options[0])
    after = _departure(conn.exit, departure, merge_left_after, rng)
    if after is None or any(wp.is_junction for wp in after) or len(after) * step < min_departure:
        return None
    return [wp for wp in inside if wp.is_junction] + after


@dataclass(frozen=True)
class Layout:
    """What a scenario type needs from the town.

    Straight layouts: ``lane_ok`` must hold at the trigger and every 5 m over ``clear_after`` m (junction-free, turning
    by at most ``max_turn`` degrees), the lane must be junction-free ``clear_before`` m back, and ``extra`` (if any)
    must accept the trigger.
    Junction layouts: connections with a turn in ``turns``, signalised or not (``signalized``), with a stop sign
    on the approach (``stop_sign``), accepted by ``junction_extra`` (which may return fixed parameters).
    """

    name: str
    description: str
    lane_ok: Callable[[Waypoint], bool] | None = None
    clear_before: float = 20.0
    clear_after: float = 100.0
    pre: tuple[float, float] = (10.0, 14.0)
    length: float = ROUTE_LENGTH
    extra: Callable[[Map, Waypoint], bool] | None = None
    #: Largest heading change (deg) allowed over the ``clear_after`` stretch (None: any).
    max_turn: float | None = None
    turns: tuple[str, ...] = ()
    signalized: bool | None = None
    stop_sign: bool = False
    approach: tuple[float, float] = (30.0, 38.0)
    departure: tuple[float, float] = (22.0, 30.0)
    trigger_offset: tuple[float, float] = (2.0, 8.0)
    junction_extra: Callable[[JunctionLane, list[JunctionLane]], list[dict[str, dict[str, str]]]] | None = None
    #: Straight layouts: builds the planned lane path from the trigger instead of following its lane (None: no path).
    path_builder: Callable[[Waypoint, np.random.Generator, float], list[Waypoint] | None] | None = None
    #: Junction layouts: a further check of the connection in its town (e.g. an interurban road's speed limit).
    junction_ok: Callable[[Map, JunctionLane, list[JunctionLane]], bool] | None = None
    #: Junction layouts: after the junction the route keeps its exit lane this far (m), then changes into the lane
    #: on its left (an on-ramp's acceleration lane into the highway); None: it stays on the exit lane.
    merge_left_after: tuple[float, float] | None = None
    #: Junction layouts: builds the planned lane path and trigger itself (e.g. with lane changes; None: the lane).
    route_path: Callable[[JunctionLane, np.random.Generator], tuple[list[Waypoint], Waypoint] | None] | None = None
    #: Parameters that depend on the planned path (e.g. a flow starting behind the route's start).
    path_parameters: Callable[[JunctionLane | None, list[Waypoint]], dict[str, dict[str, str]] | None] | None = None
    #: Straight layouts with a ``direction``: the lane test each drawn side needs instead of ``lane_ok`` (the
    #: candidate search takes any side the parameter set draws, each route checks its own side).
    directions: Mapping[str, Callable[[Waypoint], bool]] | None = None
    #: Straight layouts: the parameter (m) placing the scenario's actors along the route. ``clear_before``,
    #: ``clear_after``, ``length`` and ``extra`` are sized for bench2drive220's values; a larger value lengthens
    #: the junction-free stretch ahead by ``reach_ahead`` m and behind by ``reach_behind`` m per metre beyond.
    reach_param: str | None = None
    reach_ahead: float = 1.0
    reach_behind: float = 0.0
    #: Straight layouts: ``extra`` for a ``reach_param`` value outside bench2drive220's range (None: no check).
    reach_ok: Callable[[Map, Waypoint, float], bool] | None = None
    #: Straight layouts: beyond ``clear_before``/``clear_after`` the lengthened stretch may cross junctions
    #: straight on (no turn beyond ``max_turn``, ``lane_ok`` outside them), and the walk back must lead forward to
    #: the trigger again (a vehicle spawned there on its lane reaches the ego's lane).
    reach_through_junctions: bool = False

    @property
    def is_junction(self) -> bool:
        """Junction layouts have turns."""
        return bool(self.turns)


def _multi_lane_left(wp: Waypoint) -> bool:
    return is_driving(wp) and same_direction_driving_neighbour(wp, "left") is not None


def _multi_lane_right(wp: Waypoint) -> bool:
    return is_driving(wp) and same_direction_driving_neighbour(wp, "right") is not None


def _multi_lane_rightmost(wp: Waypoint) -> bool:
    return _multi_lane_left(wp) and is_outermost_driving(wp, "right")


def _multi_lane_any(wp: Waypoint) -> bool:
    return is_driving(wp) and (
        same_direction_driving_neighbour(wp, "left") is not None
        or same_direction_driving_neighbour(wp, "right") is not None
    )


def _two_way_single(wp: Waypoint) -> bool:
    return (
        is_driving(wp)
        and opposite_driving_neighbour(wp) is not None
        and same_direction_driving_neighbour(wp, "left") is None
        and same_direction_driving_neighbour(wp, "right") is None
    )


def _rightmost(wp: Waypoint) -> bool:
    return is_driving(wp) and is_outermost_driving(wp, "right")


def _any_lane(wp: Waypoint) -> bool:
    return is_driving(wp)


def _opposite_flow_room(town: Map, wp: Waypoint) -> bool:
    """The opposite lane continues 1.5 × limit + 30 m both ways around the furthest obstacle position (44 m)."""
    return _opposite_flow_room_at(town, wp, 44.0)


def _opposite_flow_room_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """The opposite lane continues 1.5 × limit + 30 m both ways around an obstacle ``distance`` m ahead."""
    obstacle = move_along(wp, distance, step=11.0)
    if obstacle is None:
        return False
    opposite = opposite_driving_neighbour(obstacle)
    if opposite is None:
        return False
    reach = 1.5 * town.speed_limit(obstacle) + 30.0
    return bool(opposite.previous(reach)) and bool(opposite.next(reach))


def _door_side_lane(town: Map, wp: Waypoint) -> bool:
    """A parking lane (or wide shoulder) on the right where the car may stand (37–59 m after the trigger), and room
    for the opposite flow around it."""
    from b2d_data.scenarios.catalog.vehicle_opens_door import side_lane

    ahead: Waypoint | None = move_along(wp, 37.0, step=37.0)
    for _ in range(4):
        if ahead is None or side_lane(ahead, "right") is None:
            return False
        ahead = move_along(ahead, 7.0, step=7.0)
    return _opposite_flow_room(town, wp)


def _door_side_lane_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """:func:`_door_side_lane` for a car ``distance`` m after the trigger."""
    from b2d_data.scenarios.catalog.vehicle_opens_door import side_lane

    for d in (distance, distance + 5.0):
        ahead = move_along(wp, d, step=5.0)
        if ahead is None or side_lane(ahead, "right") is None:
            return False
    return _opposite_flow_room_at(town, wp, distance)


def _sidewalk_ahead(town: Map, wp: Waypoint) -> bool:
    """A sidewalk on the right where the blocker and the pedestrian stand (40–51 m after the trigger)."""
    return _sidewalk_at(town, wp, 40.0)


def _sidewalk_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """A sidewalk on the right ``distance`` to ``distance + 11`` m after the trigger (blocker, then pedestrian)."""
    ahead: Waypoint | None = move_along(wp, distance, step=10.0)
    for step in (5.0, 6.0, 0.0):
        if ahead is None or find_side_lane(ahead, "right", LaneType.SIDEWALK) is None:
            return False
        if step:
            ahead = move_along(ahead, step, step=step)
    return True


def _parked_car_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """ParkingCrossingPedestrian: a parking lane on the right around a car ``distance`` m after the trigger."""
    return _parking_ahead((distance - 2.0, distance + 2.0, distance + 7.0))(town, wp)


def _parking_slot(town: Map, wp: Waypoint) -> bool:
    """A parking lane on the right that extends 14 m back and forward."""
    parking = wp.get_right_lane()
    if parking is None or not parking.lane_type & LaneType.PARKING:
        return False
    for forward in (True, False):
        end = move_along(parking, 14.0, forward=forward)
        if end is None or not end.lane_type & LaneType.PARKING:
            return False
    return True


def _parking_ahead(distances: Sequence[float]) -> Callable[[Map, Waypoint], bool]:
    """A parking lane on the right at each of ``distances`` m after the trigger."""

    def check(town: Map, wp: Waypoint) -> bool:
        for distance in distances:
            ahead = move_along(wp, distance, step=2.0)
            parking = ahead.get_right_lane() if ahead is not None else None
            if parking is None or not parking.lane_type & LaneType.PARKING:
                return False
        return True

    return check


def _red_light_runner(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Directions whose straight crossing meets the ego: left/right for a straight ego, opposite for a left turn."""
    directions = ("left", "right") if conn.turn == "straight" else ("opposite",) if conn.turn == "left" else ()
    out = []
    for direction in directions:
        for entry in entries_from(lanes, conn.entry, direction):
            if connection(lanes, entry, "straight") is not None:
                out.append({"direction": {"value": direction}})
                break
    return out


def _sidewalk_at_entry(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Junction entries with a sidewalk on the right and no parking lane before it (where PedestrianCrossing's
    group waits; parked cars would stop the walkers)."""
    current = conn.entry
    while True:
        right = current.get_right_lane()
        if right is None or right.lane_id * current.lane_id <= 0 or right.lane_type & LaneType.PARKING:
            return []
        if right.lane_type & LaneType.SIDEWALK:
            return [{}]
        current = right


def _three_arms(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Junctions where three roads meet (a T)."""
    return [{}] if len({lane.entry.road_id for lane in lanes}) == 3 else []


def _flow_from(direction: str) -> Callable[[JunctionLane, list[JunctionLane]], list[dict[str, dict[str, str]]]]:
    def check(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
        for entry in entries_from(lanes, conn.entry, direction):
            straight = connection(lanes, entry, "straight")
            if straight is not None and move_along(straight.exit, 45.0, step=CHECK_STEP) is not None:
                return [{}]
        return []

    return check


def _flow_into_ego_exit(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """An opposite entry turning right onto the road the ego turns left into."""
    for entry in entries_from(lanes, conn.entry, "opposite"):
        if flow_into_exit(lanes, entry, conn.exit) is not None:
            return [{}]
    return []


#: EnterActorFlow's flow starts this far before the junction (less where an earlier junction is nearer) and ends
#: this far after it (m), as in Bench2Drive's routes (45-60 m before, 20-25 m after).
ENTER_FLOW_BACK, ENTER_FLOW_AFTER = 55.0, 22.0


def _xml_location(wp: Waypoint) -> dict[str, str]:
    loc = wp.transform.location
    return {"x": f"{loc.x:.1f}", "y": f"{loc.y:.1f}", "z": f"{loc.z:.1f}"}


def _enter_flow(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """A left entry whose straight lane reaches the road the ego turns right into: the flow's start and end."""
    for entry in entries_from(lanes, conn.entry, "left"):
        flow = flow_into_exit(lanes, entry, conn.exit, turn="straight")
        if flow is None:
            continue
        end = move_along(flow.exit, ENTER_FLOW_AFTER, step=2.0)
        if end is None or end.is_junction:
            continue
        start = walk_back_to_source(flow.entry, ENTER_FLOW_BACK)
        return [{"start_actor_flow": _xml_location(start), "end_actor_flow": _xml_location(end)}]
    return []


#: CrossingBicycleFlow's bicycles start this far before the junction on the bike lane (m).
BICYCLE_FLOW_BACK = 30.0


def _bicycle_flow(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """A bike lane right of an opposite entry that runs straight through the junction: the flow's start and end."""
    for entry in entries_from(lanes, conn.entry, "opposite"):
        bike = find_side_lane(entry, "right", LaneType.BIKING)
        if bike is None:
            continue
        start = walk_back_to_source(bike, BICYCLE_FLOW_BACK)
        try:
            path = bicycle_path(start, conn.junction_id)
        except ScenarioError:
            continue
        return [{"start_actor_flow": _xml_location(start), "end_actor_flow": _xml_location(path[-1])}]
    return []


#: Interurban roads are faster than this (km/h); town streets and boulevards are 30–60.
INTERURBAN_MIN_LIMIT = 65.0


def _interurban_turn(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The ego leaves a fast road with priority (no stop sign) that goes on straight across the junction."""
    if town.speed_limit(conn.entry) <= INTERURBAN_MIN_LIMIT:
        return False
    keys = {(conn.entry.road_id, conn.entry.lane_id), (conn.start.road_id, conn.start.lane_id)}
    if keys & _signal_lanes(town.stop_signs()):
        return False
    opposite = entries_from(lanes, conn.entry, "opposite")
    return any(town.speed_limit(e) > INTERURBAN_MIN_LIMIT for e in opposite)


def _interurban_flow(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The opposite entry's straight lane as the flow: source 70 m before the junction, sink 40 m after it."""
    for entry in entries_from(lanes, conn.entry, "opposite"):
        straight = connection(lanes, entry, "straight")
        if straight is None:
            continue
        source = walk_back_to_source(straight.entry, 70.0)
        sink = move_along(straight.exit, 40.0, step=CHECK_STEP)
        if sink is None or source.transform.location.distance_2d(straight.entry.transform.location) < 50.0:
            continue
        return [{"start_actor_flow": _xml_location(source), "end_actor_flow": _xml_location(sink)}]
    return []


def _onto_interurban(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The ego turns from a side road onto a fast road that runs straight across the junction."""
    # the limit just after a junction is still the previous road's (speed signs stand a little way in)
    onto = move_along(conn.exit, 30.0, step=CHECK_STEP)
    fast = town.speed_limit(onto) if onto is not None else 0.0
    if not (fast > INTERURBAN_MIN_LIMIT and town.speed_limit(conn.entry) < fast):
        return False
    # flow 1 drives along the fast road on both sides of the junction (not into or out of a town street)
    for entry in entries_from(lanes, conn.entry, "left"):
        straight = connection(lanes, entry, "straight")
        beyond = move_along(straight.exit, 30.0, step=CHECK_STEP) if straight is not None else None
        if beyond is not None and min(town.speed_limit(entry), town.speed_limit(beyond)) > INTERURBAN_MIN_LIMIT:
            return True
    return False


def _interurban_two_flows(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Flow 1 on the left entry's straight lane, 60 m before the junction to 40 m after it (flow 2 runs back on the
    lanes beside it, into the ego's exit lane)."""
    for entry in entries_from(lanes, conn.entry, "left"):
        straight = connection(lanes, entry, "straight")
        if straight is None:
            continue
        source = walk_back_to_source(straight.entry, 60.0)
        sink = move_along(straight.exit, 40.0, step=CHECK_STEP)
        if sink is None or source.transform.location.distance_2d(straight.entry.transform.location) < 50.0:
            continue
        return [{"direction": {"value": "right"}, "start_actor_flow": _xml_location(source),
                 "end_actor_flow": _xml_location(sink)}]  # fmt: skip
    return []


def _lane_change_ok(wp: Waypoint, side: str) -> Waypoint | None:
    """The same-direction driving lane on ``side`` when the marking allows changing into it."""
    other = same_direction_driving_neighbour(wp, side)
    allowed = LaneChange.LEFT if side == "left" else LaneChange.RIGHT
    return other if other is not None and wp.lane_change & allowed else None


#: SequentialLaneChange: metres before the first lane change and between the first and the second.
SEQUENTIAL_RUNS = ((50.0, 60.0), (35.0, 45.0))
#: SequentialLaneChange: the first keypoint after a lane change is this far ahead in the new lane. The planner
#: lands 5 m ahead in the new lane (CARLA's ``trace_route``); a keypoint closer than that makes the next leg
#: start behind where it landed, and the route would double back.
SEQUENTIAL_CHANGE_REACH = 6.0


def _sequential_lanes(trigger: Waypoint, rng: np.random.Generator, length: float) -> list[Waypoint] | None:
    """Lane waypoints 2 m apart over ``length`` m that change lane twice (``SEQUENTIAL_RUNS``): first into a
    neighbour (side drawn at random among those allowed), then on the same way if a further lane exists, else back.
    Across each change the keypoints jump ``SEQUENTIAL_CHANGE_REACH`` m."""
    step = KEYPOINT_SPACING
    sides = ["left", "right"] if rng.uniform() < 0.5 else ["right", "left"]
    path = [trigger]
    travelled = 0.0
    first: str | None = None
    for change in range(3):
        run = float(rng.uniform(*SEQUENTIAL_RUNS[change])) if change < 2 else length - travelled
        walk = lane_walk(path[-1], run, step=step)
        if (len(walk) - 1) * step < run - 1e-6 or any(wp.is_junction for wp in walk):
            return None
        path += walk[1:]
        travelled += (len(walk) - 1) * step
        if change == 2:
            break
        order = sides if first is None else [first, "right" if first == "left" else "left"]
        target = None
        for side in order:
            target = _lane_change_ok(path[-1], side)
            if target is not None:
                first = first or side
                break
        ahead = move_along(target, SEQUENTIAL_CHANGE_REACH, step=step) if target is not None else None
        if ahead is None or ahead.is_junction:
            return None
        path.append(ahead)
        travelled += SEQUENTIAL_CHANGE_REACH
    return path


#: Highways are at least this fast (km/h); CARLA's Town04/06 highways are 90, generated ones 90–100.
HIGHWAY_MIN_LIMIT = 80.0
#: Largest heading change (deg) from an on-ramp's entry to the lane it merges into (Town04's curved ramps: ~50).
MERGE_MAX_ANGLE = 60.0
#: How far up the on-ramp HighwayCutIn's car waits (m before the merge junction).
CUT_IN_RAMP_DISTANCE = 60.0


def _merge_lane(conn: JunctionLane, lanes: list[JunctionLane]) -> JunctionLane | None:
    """The connection from another road into the lane right of ``conn``'s exit at a shallow angle (an on-ramp
    merging beside it, not a side street turning in)."""
    right = same_direction_driving_neighbour(conn.exit, "right")
    if right is None:
        return None
    for other in lanes:
        into_right = (other.exit.road_id, other.exit.lane_id) == (right.road_id, right.lane_id)
        if into_right and abs(other.angle) < MERGE_MAX_ANGLE and other.entry.road_id != conn.entry.road_id:
            return other
    return None


def _highway_merge(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The ego drives straight on a highway through a junction where an on-ramp joins the lane on its right."""
    fast = min(town.speed_limit(conn.entry), town.speed_limit(conn.exit)) >= HIGHWAY_MIN_LIMIT
    return fast and _merge_lane(conn, lanes) is not None


def _cut_in_car(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The cut-in car 60 m up the ramp (less where the ramp is shorter); end_location 10 m past the merge."""
    merge = _merge_lane(conn, lanes)
    if merge is None:
        return []
    car = walk_back_to_source(merge.entry, CUT_IN_RAMP_DISTANCE, step=2.0)
    end = move_along(merge.exit, 10.0)
    if end is None or car.transform.location.distance_2d(merge.entry.transform.location) < 15.0:
        return []
    return [{"other_actor_location": _xml_location(car), "end_location": _xml_location(end)}]


#: MergerIntoSlowTraffic: the flow starts this far up the highway before the merge junction and ends this far
#: after it, on the highway lane the acceleration lane runs beside (m; B2D's routes: ~25 m behind the trigger,
#: 120-230 m ahead of it).
SLOW_FLOW_BACK, SLOW_FLOW_AFTER = 60.0, 75.0


def _ramp_into_acceleration_lane(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The route comes down an on-ramp and through its merge junction onto the acceleration lane of a highway."""
    for other in lanes:
        if other.turn == "straight" and _highway_merge(town, other, lanes) and _merge_lane(other, lanes) is conn:
            return True
    return False


def _slow_flow_beside(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The slow flow on the highway lane left of the acceleration lane: from before the merge to after it."""
    for other in lanes:
        if other.turn != "straight" or _merge_lane(other, lanes) is not conn:
            continue
        source = walk_back_to_source(other.entry, SLOW_FLOW_BACK)
        sink = move_along(other.exit, SLOW_FLOW_AFTER, step=CHECK_STEP)
        if sink is None or sink.is_junction:
            continue
        return [{"start_actor_flow": _xml_location(source), "end_actor_flow": _xml_location(sink)}]
    return []


#: HighwayExit: metres of route on the ego's lane before its planned change across the flow; metres between that
#: change and the junction (or the change into a deceleration lane); where the deceleration lane is at least
#: ``EXIT_LANE_MIN_WIDTH`` m wide, the share of it before the junction where the route enters it.
EXIT_START_RUN, EXIT_CHANGE_RUN, EXIT_LANE_SHARE = (15.0, 25.0), (85.0, 105.0), (0.35, 0.55)
EXIT_LANE_MIN_WIDTH = 3.0
#: HighwayExit's flow starts this far behind the route's start and ends this far past the junction (m), as in
#: Bench2Drive's routes (26-28 m behind the trigger point).
EXIT_FLOW_BEHIND, EXIT_FLOW_AFTER = 28.0, 30.0


def _exit_lanes(conn: JunctionLane, lanes: list[JunctionLane]) -> tuple[JunctionLane, Waypoint] | None:
    """For an exit connection: the flow lane's connection staying on the highway and the ego's lane left of it.

    The flow lane is the exit lane itself where it also goes straight on (Town04), else the lane left of it (a
    deceleration lane, the generated towns). ``conn`` is an exit when no other lane of its road goes its way.
    """
    e = conn.entry
    sign = e.lane_id > 0
    others = [o for o in lanes if o.entry.road_id == e.road_id and (o.entry.lane_id > 0) == sign]
    highway = {o.exit.road_id for o in others if o.entry.lane_id != e.lane_id}
    if not highway or conn.exit.road_id in highway:
        return None
    own = [o for o in others if o.entry.lane_id == e.lane_id and o.exit.road_id in highway]
    flow_entry = e if own else same_direction_driving_neighbour(e, "left")
    if flow_entry is None:
        return None
    through = [o for o in others if o.entry.lane_id == flow_entry.lane_id and o.exit.road_id in highway]
    ego_lane = same_direction_driving_neighbour(flow_entry, "left")
    if not through or ego_lane is None:
        return None
    straight = min(through, key=lambda o: abs(o.angle))
    if conn.angle <= straight.angle:  # the exit leaves to the left
        return None
    return straight, ego_lane


def _highway_exit(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """A highway (>= 80 km/h) lane leaving by an exit on the right, with a flow lane and the ego's lane left of it."""
    found = _exit_lanes(conn, lanes)
    return (
        found is not None
        and min(town.speed_limit(conn.entry), town.speed_limit(found[0].exit)) >= HIGHWAY_MIN_LIMIT
        and conn.angle - found[0].angle < MERGE_MAX_ANGLE  # a ramp leaving at a shallow angle, not a side street
    )


def _wide_run_back(wp: Waypoint, min_width: float, cap: float) -> float:
    """Metres back from ``wp`` along its lane while the lane is at least ``min_width`` m wide (2 m steps)."""
    run, current = 0.0, wp
    while run < cap:
        prev = move_along(current, KEYPOINT_SPACING, forward=False, step=KEYPOINT_SPACING)
        if prev is None or prev.is_junction or prev.lane_width < min_width or prev.lane_id != current.lane_id:
            break
        run, current = run + KEYPOINT_SPACING, prev
    return run


def _exit_route(conn: JunctionLane, rng: np.random.Generator) -> tuple[list[Waypoint], Waypoint] | None:
    """The ego's lane, a change right across the flow lane, (a change into the deceleration lane,) the exit."""
    step = KEYPOINT_SPACING
    junction = conn.start.get_junction()
    found = _exit_lanes(conn, junction_lanes(junction)) if junction is not None else None
    if found is None:
        return None
    flow_entry = same_direction_driving_neighbour(found[1], "right")
    if flow_entry is None:
        return None
    d_fe = 0.0
    decel = not same_lane(flow_entry, conn.entry)
    if decel:
        wide = _wide_run_back(conn.entry, EXIT_LANE_MIN_WIDTH, 200.0)
        if wide < 30.0:
            return None
        d_fe = step * round(float(rng.uniform(*EXIT_LANE_SHARE)) * wide / step)
    d_gf = d_fe + step * round(float(rng.uniform(*EXIT_CHANGE_RUN)) / step)
    d_start = d_gf + step * round(float(rng.uniform(*EXIT_START_RUN)) / step)
    f_gf = move_along(flow_entry, d_gf, forward=False, step=step)
    g_gf = same_direction_driving_neighbour(f_gf, "left") if f_gf is not None else None
    if g_gf is None:
        return None
    g_run = lane_walk(g_gf, d_start - d_gf, forward=False, step=step)
    f_next = move_along(f_gf, step, step=step)
    if len(g_run) * step < d_start - d_gf or f_next is None:
        return None
    path = list(reversed(g_run)) + lane_walk(f_next, d_gf - d_fe - step, step=step)
    if decel:
        e_next = same_direction_driving_neighbour(move_along(path[-1], step, step=step) or path[-1], "right")
        if e_next is None:
            return None
        path += lane_walk(e_next, d_fe - step, step=step)
    through = _through_junction(conn, float(rng.uniform(30.0, 40.0)), 30.0)
    if through is None or any(wp.is_junction for wp in path):
        return None
    return path + through, path[int(rng.integers(0, 2))]


def _exit_flow(conn: JunctionLane | None, path: list[Waypoint]) -> dict[str, dict[str, str]] | None:
    """The flow: from ``EXIT_FLOW_BEHIND`` m behind the route's start on the lane right of it to
    ``EXIT_FLOW_AFTER`` m past the junction on the highway."""
    junction = conn.start.get_junction() if conn is not None else None
    found = _exit_lanes(conn, junction_lanes(junction)) if conn is not None and junction is not None else None
    beside = same_direction_driving_neighbour(path[0], "right")
    if found is None or beside is None:
        return None
    source = walk_back_to_source(beside, EXIT_FLOW_BEHIND, step=2.0)
    sink = move_along(found[0].exit, EXIT_FLOW_AFTER)
    if sink is None or sink.is_junction:
        return None
    return {"start_actor_flow": _xml_location(source), "end_actor_flow": _xml_location(sink)}


#: Obstacles passed on the other side of the lane: a same-direction lane left of a right-hand obstacle and vice versa.
PASS_OTHER_SIDE: Mapping[str, Callable[[Waypoint], bool]] = {"right": _multi_lane_left, "left": _multi_lane_right}

#: The layout of each implemented scenario type.
LAYOUTS: dict[str, Layout] = {
    "Accident": Layout("multi_lane", "two same-direction lanes, 120 m junction-free and straight-ish", _multi_lane_left,
                       clear_after=120.0, max_turn=STRAIGHTISH, directions=PASS_OTHER_SIDE, reach_param="distance"),
    "ParkedObstacleTwoWays": Layout("two_way_street", "one lane each way, 100 m junction-free, opposite lane "
                                    "continuing ~105 m around the obstacle", _two_way_single, clear_after=100.0,
                                    extra=_opposite_flow_room, max_turn=STRAIGHTISH, reach_param="distance",
                                    reach_ok=_opposite_flow_room_at),
    "HazardAtSideLane": Layout("multi_lane", "two same-direction lanes (ego on the right one), 130 m junction-free",
                               _multi_lane_rightmost, clear_after=130.0, max_turn=STRAIGHTISH,
                               reach_param="distance"),
    "HazardAtSideLaneTwoWays": Layout("two_way_street", "one lane each way, 130 m junction-free",
                                      _two_way_single, clear_after=130.0, max_turn=STRAIGHTISH,
                                      reach_param="distance"),
    "VehicleOpensDoorTwoWays": Layout("parking_lane", "one lane each way with a parking lane (or a shoulder of "
                                      "2 m) on the right 37–59 m ahead, 115 m junction-free", _two_way_single,
                                      clear_after=115.0, extra=_door_side_lane, max_turn=STRAIGHTISH,
                                      reach_param="distance", reach_ok=_door_side_lane_at),
    "InvadingTurn": Layout("two_way_street", "one lane each way, 100 m junction-free", _two_way_single,
                           clear_after=100.0, reach_param="distance"),
    "HardBreakRoute": Layout("road", "any driving lane, 60 m junction-free", _any_lane, clear_after=60.0),
    "DynamicObjectCrossing": Layout("sidewalk", "rightmost lane with a sidewalk on the right, 110 m junction-free",
                                    _rightmost, clear_after=110.0, extra=_sidewalk_ahead, max_turn=STRAIGHTISH,
                                    reach_param="distance", reach_ok=_sidewalk_at),
    # Longer than the others: the scenario may last 10 s after the trigger, ~200 m on a fast road. The vehicle
    # starts ``distance`` m behind the trigger and closes in at 25 km/h (7 m/s): each metre further back takes the
    # ego up to four metres further (at 100 km/h) before the vehicle is near and the 10 s have passed. Generated
    # highways have no 600 m without a ramp junction, so the lengthened stretch may cross junctions straight on.
    "YieldToEmergencyVehicle": Layout("multi_lane", "two same-direction lanes, 35 m behind and 200 m ahead "
                                      "junction-free", _multi_lane_any, clear_before=35.0, clear_after=200.0,
                                      max_turn=STRAIGHTISH, length=230.0, reach_param="distance",
                                      reach_ahead=4.0, reach_behind=1.0, reach_through_junctions=True),
    "ParkedObstacle": Layout("multi_lane", "two same-direction lanes, 100 m junction-free and straight-ish",
                             _multi_lane_left, clear_after=100.0, max_turn=STRAIGHTISH, directions=PASS_OTHER_SIDE,
                             reach_param="distance"),
    "ConstructionObstacle": Layout("multi_lane", "two same-direction lanes, 110 m junction-free and straight-ish",
                                   _multi_lane_left, clear_after=110.0, max_turn=STRAIGHTISH,
                                   directions=PASS_OTHER_SIDE, reach_param="distance"),
    "AccidentTwoWays": Layout("two_way_street", "one lane each way, 120 m junction-free, opposite lane continuing "
                              "~105 m around the obstacle", _two_way_single, clear_after=120.0,
                              extra=_opposite_flow_room, max_turn=STRAIGHTISH, reach_param="distance",
                              reach_ok=_opposite_flow_room_at),
    "ConstructionObstacleTwoWays": Layout("two_way_street", "one lane each way, 110 m junction-free, opposite lane "
                                          "continuing ~105 m around the obstacle", _two_way_single,
                                          clear_after=110.0, extra=_opposite_flow_room, max_turn=STRAIGHTISH,
                                          reach_param="distance", reach_ok=_opposite_flow_room_at),
    "ParkingExit": Layout("parking_lane", "a parking lane right of a driving lane, 40 m junction-free", _any_lane,
                          clear_before=0.0, clear_after=40.0, pre=(0.0, 0.0), extra=_parking_slot),
    "OppositeVehicleRunningRedLight": Layout(
        "signalized_junction", "a signalised junction crossed straight (or turning left) with a straight crossing "
        "entry", turns=("straight", "left"), signalized=True, junction_extra=_red_light_runner),
    "SignalizedJunctionLeftTurn": Layout(
        "signalized_junction", "a signalised junction where the route turns left, with an opposite entry going "
        "straight", turns=("left",), signalized=True, junction_extra=_flow_from("opposite")),
    "NonSignalizedJunctionLeftTurn": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns left, with an opposite entry going "
        "straight", turns=("left",), signalized=False, junction_extra=_flow_from("opposite")),
    "SignalizedJunctionLeftTurnEnterFlow": Layout(
        "signalized_junction", "a signalised junction where the route turns left, with an opposite entry turning "
        "right into the same road", turns=("left",), signalized=True, junction_extra=_flow_into_ego_exit),
    "NonSignalizedJunctionLeftTurnEnterFlow": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns left, with an opposite entry "
        "turning right into the same road", turns=("left",), signalized=False, junction_extra=_flow_into_ego_exit),
    "EnterActorFlow": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns right into a road that a left "
        "entry's straight lane continues on", turns=("right",), signalized=False, departure=(35.0, 45.0),
        junction_extra=_enter_flow),
    "CrossingBicycleFlow": Layout(
        "bike_lane", "a junction where the route turns left across an opposite bike lane that continues straight "
        "through it", turns=("left",), junction_extra=_bicycle_flow),
    "SignalizedJunctionRightTurn": Layout(
        "signalized_junction", "a signalised junction where the route turns right, with a left entry going "
        "straight", turns=("right",), signalized=True, junction_extra=_flow_from("left")),
    "NonSignalizedJunctionRightTurn": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns right, with a left entry going "
        "straight", turns=("right",), signalized=False, junction_extra=_flow_from("left")),
    "VanillaSignalizedTurnEncounterRedLight": Layout(
        "signalized_junction", "a signalised junction where the route turns", turns=("left", "right"),
        signalized=True, approach=(28.0, 36.0), departure=(18.0, 26.0), trigger_offset=(3.0, 5.0)),
    "VanillaNonSignalizedTurnEncounterStopsign": Layout(
        "stop_sign_junction", "an unsignalised junction with a stop sign on the approach where the route turns",
        turns=("left", "right"), signalized=False, stop_sign=True, approach=(28.0, 36.0), departure=(18.0, 26.0),
        trigger_offset=(3.0, 5.0)),
    "VanillaNonSignalizedTurn": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns", turns=("left", "right"),
        signalized=False, approach=(28.0, 36.0), departure=(18.0, 26.0), trigger_offset=(3.0, 5.0)),
    # bench2drive220's geometry (routes 25968 and 25975 on Town07, measured on the dense route: the route starts
    # 9.8–10.2 m before the junction, the trigger 7.0 m after the start, 2.8–3.2 m before the junction): the route
    # starts 10 m before the junction and the trigger is the keypoint 2 or 4 m before it, so the ego, starting from
    # rest, meets the 5 s of green at the stop line. With the trigger 14–19 m before the junction (approach 16–22 m)
    # an ego that stopped for crossing cars on its way could still have its tail over the line when all lights
    # turned red (3 of 20 routes).
    "VanillaSignalizedTurnEncounterGreenLight": Layout(
        "signalized_junction", "a signalised junction where the route turns", turns=("left", "right"),
        signalized=True, approach=(9.0, 10.0), departure=(24.0, 30.0), trigger_offset=(6.0, 8.0)),
    "T_Junction": Layout(
        "t_junction", "a junction of three roads that the route crosses", turns=("left", "right", "straight"),
        junction_extra=_three_arms, approach=(30.0, 38.0), departure=(22.0, 30.0), trigger_offset=(20.0, 26.0)),
    "OppositeVehicleTakingPriority": Layout(
        "unsignalized_junction", "an unsignalised junction crossed straight (or turning left) with a straight "
        "crossing entry", turns=("straight", "left"), signalized=False, junction_extra=_red_light_runner),
    "ParkingCrossingPedestrian": Layout("parking_lane", "rightmost lane with a parking lane on the right 34–52 m "
                                        "ahead, 100 m junction-free", _rightmost, clear_after=100.0,
                                        extra=_parking_ahead((34.0, 40.0, 46.0, 52.0)), max_turn=STRAIGHTISH,
                                        reach_param="distance", reach_ok=_parked_car_at),
    "ParkingCutIn": Layout("parking_lane", "rightmost lane with a parking lane on the right 24–40 m ahead, 100 m "
                           "junction-free", _rightmost, clear_after=100.0, pre=(12.0, 14.0),
                           extra=_parking_ahead((24.0, 28.0, 32.0, 36.0, 40.0)), max_turn=STRAIGHTISH),
    "StaticCutIn": Layout("multi_lane", "two same-direction lanes (ego on the left one), 130 m junction-free",
                          _multi_lane_right, clear_after=130.0, max_turn=STRAIGHTISH,
                          directions={"right": _multi_lane_right, "left": _multi_lane_left}, reach_param="distance"),
    "ControlLoss": Layout("road", "any driving lane, 115 m junction-free", _any_lane, clear_after=115.0,
                          length=130.0),
    "PedestrianCrossing": Layout(
        "sidewalk_junction", "a junction entry with a sidewalk on the right", turns=("straight", "left", "right"),
        junction_extra=_sidewalk_at_entry, trigger_offset=(4.0, 10.0)),
    "VehicleTurningRoutePedestrian": Layout(
        "junction_turn", "a junction where the route turns", turns=("left", "right"), departure=(45.0, 50.0)),
    "VehicleTurningRoute": Layout(
        "junction_turn", "a junction where the route turns", turns=("left", "right"), departure=(50.0, 55.0)),
    "BlockedIntersection": Layout(
        "junction_turn", "a junction where the route turns", turns=("left", "right")),
    # Plain routes with background traffic only (no <scenario>): through one junction, any turn.
    NO_SCENARIO: Layout(
        "junction", "a junction the route crosses", turns=("left", "right", "straight"), approach=(30.0, 40.0),
        departure=(30.0, 40.0)),
    "InterurbanActorFlow": Layout(
        "interurban", "an unsignalised junction where the route turns left off a road faster than 65 km/h, with an "
        "opposite entry going straight on for 40 m", turns=("left",), signalized=False,
        junction_extra=_interurban_flow, junction_ok=_interurban_turn),
    "InterurbanAdvancedActorFlow": Layout(
        "interurban", "an unsignalised junction where the route turns left from a side road onto a road faster than "
        "65 km/h, with a left entry going straight on", turns=("left",), signalized=False,
        junction_extra=_interurban_two_flows, junction_ok=_onto_interurban, departure=(70.0, 85.0)),
    "SequentialLaneChange": Layout(
        "multi_lane", "two or more same-direction lanes with broken markings, 140 m junction-free", _multi_lane_any,
        clear_before=0.0, clear_after=140.0, pre=(0.0, 0.0), length=140.0, path_builder=_sequential_lanes),
    "HighwayCutIn": Layout(
        "highway_ramps", "a highway (>= 80 km/h) crossed straight through a junction where an on-ramp joins the lane "
        "right of the route", turns=("straight",), junction_ok=_highway_merge, junction_extra=_cut_in_car,
        approach=(50.0, 70.0), departure=(60.0, 80.0), trigger_offset=(0.0, 4.0)),
    "MergerIntoSlowTraffic": Layout(
        "highway_ramps", "an on-ramp merging into a highway (>= 80 km/h) through a junction onto an acceleration "
        "lane beside the highway's right lane", turns=("straight", "left", "right"),
        junction_ok=_ramp_into_acceleration_lane, junction_extra=_slow_flow_beside, approach=(40.0, 50.0),
        departure=(95.0, 105.0), trigger_offset=(2.0, 6.0), merge_left_after=(16.0, 30.0)),
    "HighwayExit": Layout(
        "highway_exit", "a highway (>= 80 km/h) exit on the right, with a flow lane to cross and the ego's lane left "
        "of it", turns=("straight", "right"), junction_ok=_highway_exit, approach=(20.0, 30.0),
        departure=(30.0, 40.0), route_path=_exit_route, path_parameters=_exit_flow),
    # LB2.0-only training types: their placement rules live in their catalog modules
    "EnterActorFlowV2": Layout(
        "highway_ramps", "an on-ramp whose lane runs on beside a highway (>= 80 km/h) lane after its junction",
        turns=("straight", "left", "right"), junction_ok=enter_flow_v2.dedicated_entry,
        junction_extra=enter_flow_v2.flow_beside, approach=enter_flow_v2.APPROACH, departure=enter_flow_v2.DEPARTURE,
        trigger_offset=enter_flow_v2.TRIGGER_OFFSET, merge_left_after=enter_flow_v2.MERGE_AFTER),
    "PriorityAtJunction": Layout(
        "signalized_junction", "a signalised junction the route drives through",
        turns=priority_at_junction.LAYOUT_TURNS, signalized=True),
}  # fmt: skip
# V2 (Town06's entries with their own lanes) merges the same way on generated towns; only the background differs.
LAYOUTS["MergerIntoSlowTrafficV2"] = LAYOUTS["MergerIntoSlowTraffic"]


def _check_type(scenario_type: str) -> Layout:
    if scenario_type != NO_SCENARIO:
        scenario_class(scenario_type)  # unknown types: error listing the known ones
    try:
        return LAYOUTS[scenario_type]
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
        if spec.extra is not None and not spec.extra(town, wp):
            continue
        out.append(Candidate(scenario_type, spec.name, wp))
    return out


def _signal_lanes(signals) -> set[tuple[int, int]]:
    return {(lane.road_id, lane.lane_id) for s in signals for lane in s.lanes}


def _junction_candidates(town: Map, scenario_type: str, spec: Layout) -> list[Candidate]:
    lights = town.traffic_lights()
    lit_junctions = {s.junction_id for s in lights}
    lit_lanes = _signal_lanes(lights)
    stop_lanes = _signal_lanes(town.stop_signs())
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
                out.append(Candidate(scenario_type, spec.name, conn.entry, conn, fixed))
    return out


def find_candidates(town: Map, scenario_type: str, params: str | ParamSet = DEFAULT_PARAMS) -> list[Candidate]:
    """Every place in ``town`` where ``scenario_type``'s layout exists for the parameter set, in a fixed order."""
    spec = _check_type(scenario_type)
    if spec.is_junction:
        found = _junction_candidates(town, scenario_type, spec)
    else:
        found = _straight_candidates(town, scenario_type, spec, param_set(params))
    log.info("%s: %d candidate places for %s", town.name, len(found), scenario_type)
    return found


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
    spec = LAYOUTS[candidate.scenario_type]
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
    spec = LAYOUTS[candidate.scenario_type]
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
) -> list[Route]:
    """``n`` routes holding one ``scenario_type`` scenario each, on distinct places while there are enough.

    ``weathers`` lists the preset ids to draw from (default: all 23); ``params`` names the parameter ranges
    (:mod:`~b2d_data.scenarios.param_ranges`: ``training``, the default, or ``bench2drive220``). A place too short
    for the drawn distances is skipped, so long distances come from the towns' longer roads. Raises
    :class:`PlacementError` when the town lacks the layout (message names it) or no candidate survives the checks.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    ranges = param_set(params)
    spec = _check_type(scenario_type)
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
    rng = np.random.default_rng([int(seed), zlib.crc32(scenario_type.encode("utf-8"))])
    order = [int(i) for i in rng.permutation(len(candidates))]
    routes: list[Route] = []
    usable: list[Candidate] = []
    for i in order:
        if len(routes) >= n:
            break
        k = len(routes)
        route = _route_for(
            town,
            candidates[i],
            rng,
            route_id(seed, scenario_type, k),
            k + 1,
            pool[int(rng.integers(len(pool)))],
            ranges,
        )
        if route is not None:
            routes.append(route)
            usable.append(candidates[i])
    if not usable and n > 0:
        raise PlacementError(
            f"{town.name}: none of the {len(candidates)} places with layout '{spec.name}' gives a valid "
            f"{scenario_type} route"
        )
    # more routes than places: reuse the good places with fresh parameters and route extents
    attempts = 0
    while len(routes) < n and attempts < 20 * n:
        attempts += 1
        k = len(routes)
        candidate = usable[k % len(usable)]
        route = _route_for(
            town,
            candidate,
            rng,
            route_id(seed, scenario_type, k),
            k + 1,
            pool[int(rng.integers(len(pool)))],
            ranges,
        )
        if route is not None:
            routes.append(route)
    if len(routes) < n:
        raise PlacementError(f"{town.name}: only {len(routes)} of {n} {scenario_type} routes could be built")
    return routes
