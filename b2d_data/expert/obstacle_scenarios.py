"""Obstacle scenarios: route shifts, waiting and overtaking driven by the scenarios' hints (§1.9).

Every frame the expert takes the nearest still-relevant hint (by distance to its first actor; hints whose actors
are gone are dropped) and handles only that one:

- one-way obstacles (Accident, ConstructionObstacle, ParkedObstacle): shift into the lane away from the obstacle
  once within 50 m; the forecast then waits for a gap in that lane (a construction site: the ego first waits
  before the shift start until the target lane is clear behind it, see :func:`is_target_lane_clear_behind`);
- two-way obstacles (*TwoWays): shift part or all of the way into the opposite lane, wait with IDM before the
  shift start until the path-clear test passes within 8 m of it, then commit at the overtaking speed without
  forecasting until 2 m before the shift end;
- HazardAtSideLaneTwoWays: shift left around the bicycles only when the opposite lane is clear, then commit;
- HazardAtSideLane: shift left around the bicycles and keep extending the shift past the last one;
- YieldToEmergencyVehicle: shift into a neighbouring lane ahead, extended every frame until the EV is in front;
- InvadingTurn: offset the route to the right around the cones.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.idm import idm_target_speed
from b2d_data.expert.route_processing import DenseRoute
from b2d_data.expert.route_shifting import (
    extend_shift,
    shift_route_around_actors,
    shift_route_for_invading_turn,
    shift_route_smoothly,
)
from b2d_data.maps import LaneChange
from b2d_data.sim.api import OPPOSITE_LANE_OPEN, ActorState, ScenarioHint, Snapshot

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint

log = logging.getLogger(__name__)

ONE_WAY = ("Accident", "ConstructionObstacle", "ParkedObstacle")
#: One-way obstacles made of props, which the vehicle forecast does not see.
PROP_OBSTACLES = ("ConstructionObstacle",)
TWO_WAYS = ("AccidentTwoWays", "ConstructionObstacleTwoWays", "ParkedObstacleTwoWays", "VehicleOpensDoorTwoWays")
HANDLED = ONE_WAY + TWO_WAYS + ("HazardAtSideLane", "HazardAtSideLaneTwoWays", "YieldToEmergencyVehicle",
                                "InvadingTurn")  # fmt: skip


@dataclass
class ScenarioRecord:
    """The expert's bookkeeping for one published scenario (PDM-Lite keeps it in the scenario's data list)."""

    changed_route: bool = False
    from_index: int = 0
    to_index: int = 0
    path_clear: bool = False
    to_left: bool = True
    done: bool = False


@dataclass(frozen=True)
class ReducedBy:
    """The object that lowered the target speed most: (speed, type id, actor id, distance)."""

    speed: float
    type_id: str | None
    actor_id: int | None
    distance: float


@dataclass(frozen=True)
class ObstacleResult:
    """What the scenario manager decided this frame."""

    target_speed: float
    keep_driving: bool = False
    reduced_by: ReducedBy | None = None
    scenario: str | None = None


def _xyz(actor: ActorState) -> np.ndarray:
    loc = actor.location
    return np.array([loc.x, loc.y, loc.z])


def opposite_lane_open(hint: ScenarioHint) -> bool:
    """Whether a two-way obstacle's scenario lets the ego into the opposite lane yet (True when it does not say).

    Not PDM-Lite: LB2.0 switches the wrong-direction test off only 5 s after the ego came within 50 m of the
    obstacle, and an ego that keeps its speed reaches the shift in ~4.5 s; crossing the centre line before that
    is an outside-route-lanes infraction (route 151250003 on Town100, seed 151), and committing that fast the
    steering cut the short shift into the parked car (151250001 and 151250005 on Town101). The ego waits at the
    shift start.
    """
    return bool(int(hint.extra.get(OPPOSITE_LANE_OPEN, 1)))


def horizontal_distance(a: ActorState, b: ActorState) -> float:
    """Distance between two actors ignoring z."""
    return math.hypot(a.location.x - b.location.x, a.location.y - b.location.y)


def min_time_for_distance(config: ExpertConfig, distance: float, target_speed: float, ego_speed: float) -> float:
    """Seconds the ego needs for ``distance`` when accelerating per tick by PDM-Lite's empirical polynomial (§1.9)."""
    c0, c1, c2, c3 = config.min_time_params
    dt = config.dt
    remaining, speed, t = distance, ego_speed, 0.0
    while remaining - speed * dt >= 0.0:
        remaining -= speed * dt
        t += dt
        u = speed / 120.0
        gain = max(0.0, c0 + c1 * u + c2 * u * u + c3 * u**3)
        speed = float(np.clip(120.0 * (u + gain), 0.0, target_speed))
        if speed <= 0.0 and remaining > 0.0:
            return math.inf  # cannot move at all (target speed 0)
    return t + (remaining / speed if speed > 0.0 else 0.0)


def previous_road_lane_ids(start: Waypoint, steps: int) -> set[tuple[int, int]]:
    """(road id, lane id) of a lane traced back ``steps`` metres against its own driving direction."""
    ids = {(start.road_id, start.lane_id)}
    wp = start
    for _ in range(steps):
        prev = wp.previous(1.0)
        if not prev:
            break
        wp = prev[0]
        ids.add((wp.road_id, wp.lane_id))
    return ids


def _ego_time_to(config: ExpertConfig, route: DenseRoute, ego: ActorState, to_index: int,
                 speed: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(point ``to_index``, ego location, ego forward, time the ego needs to cover the distance to that point + its
    length + the path-clear safety distance, accelerating to ``speed``)."""
    to_location = route.points[min(to_index, len(route) - 1)]
    ego_location = _xyz(ego)
    ego_distance = float(np.linalg.norm(to_location - ego_location)) + 2.0 * ego.bounding_box.extent.x \
        + config.path_clear_safety_distance
    ego_time = min_time_for_distance(config, ego_distance, speed, ego.speed())
    return to_location, ego_location, ego.transform.get_forward_vector().to_array(), ego_time


def is_overtaking_path_clear(config: ExpertConfig, town: Map, route: DenseRoute, ego: ActorState,
                             vehicles: Sequence[ActorState], to_index: int, target_speed: float,
                             lane_ids: set[tuple[int, int]], overtake_speed: float) -> bool:
    """Two-way path-clear test: can the ego reach the shift end before any vehicle in the target lane does?

    The ego covers (distance to the shift end) + its length + 10 m from its current speed up to the overtaking
    speed; a vehicle ahead in the target lane blocks when it is already inside the overtaking zone or reaches
    the shift end sooner than the ego's time + 0.2 s.
    """
    to_location, ego_location, ego_forward, ego_time = _ego_time_to(
        config, route, ego, to_index, min(overtake_speed, target_speed))
    for vehicle in vehicles:
        if vehicle.id == ego.id:
            continue
        wp = town.get_waypoint(vehicle.location)
        if wp is None or (wp.road_id, wp.lane_id) not in lane_ids:
            continue
        location = _xyz(vehicle)
        if float(ego_forward @ (location - ego_location)) < 0.0:
            continue  # behind the ego: not on the overtaking path
        forward = vehicle.transform.get_forward_vector().to_array()
        if float(forward @ (to_location - location)) < 0.0:
            return False  # the shift end is behind it: it is already inside the overtaking zone
        other_distance = float(np.linalg.norm(to_location - location)) - vehicle.bounding_box.extent.x
        other_time = other_distance / max(1.0, vehicle.speed())
        if other_time < ego_time + config.path_clear_safety_time:
            return False
    return True


def is_target_lane_clear_behind(config: ExpertConfig, town: Map, route: DenseRoute, ego: ActorState,
                                 vehicles: Sequence[ActorState], to_index: int, target_speed: float,
                                 lane_ids: set[tuple[int, int]]) -> bool:
    """One-way shift test: can the ego reach the end of its ramp (``to_index``) before a car of the target lane
    that is beside or behind it gets there?

    The ego covers (distance to the ramp end) + its length + 10 m as in :func:`is_overtaking_path_clear`; such a
    car blocks when its front would reach the ego's rear at the ramp end sooner than the ego's time + 0.2 s. The
    10 m matter: with the ramp end alone a car 26 m behind at 21 m/s passed, closed in on the ego slowed for the
    board, and the forecast stopped it in the ramp (route 151030001 on Town100, seed 151). Cars wholly ahead are
    leaders for the forecast.
    """
    to_location, ego_location, ego_forward, ego_time = _ego_time_to(config, route, ego, to_index, target_speed)
    for vehicle in vehicles:
        if vehicle.id == ego.id:
            continue
        location = _xyz(vehicle)
        if float(ego_forward @ (location - ego_location)) > ego.bounding_box.extent.x + vehicle.bounding_box.extent.x:
            continue
        wp = town.get_waypoint(vehicle.location)
        if wp is None or (wp.road_id, wp.lane_id) not in lane_ids:
            continue
        gap = float(np.linalg.norm(to_location - location)) - vehicle.bounding_box.extent.x \
            - ego.bounding_box.extent.x
        if gap <= 0.0 or gap / max(1.0, vehicle.speed()) < ego_time + config.path_clear_safety_time:
            return False
    return True


class ObstacleScenarioManager:
    """Handles the nearest published obstacle scenario each frame and remembers what it did to the route."""

    def __init__(self, config: ExpertConfig, town: Map) -> None:
        self.config = config
        self.town = town
        self.records: dict[tuple[str, int], ScenarioRecord] = {}

    def step(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, hints: Sequence[ScenarioHint],
             target_speed: float) -> ObstacleResult:
        """Possibly shift the route; return the scenario's target speed and whether to skip the hazard checks."""
        candidates = []
        for hint in hints:
            if hint.scenario_type not in HANDLED or hint.first_actor_id is None:
                continue
            first = snapshot.actors.get(hint.first_actor_id)
            last = snapshot.actors.get(hint.last_actor_id) if hint.last_actor_id is not None else None
            if first is None or (hint.last_actor_id is not None and last is None):
                continue  # its actors are gone (scenario ended or timed out)
            key = (hint.scenario_type, hint.first_actor_id)
            record = self.records.setdefault(key, ScenarioRecord())
            if record.done:
                continue
            distance = float(np.linalg.norm(_xyz(first) - _xyz(ego)))
            candidates.append((distance, hint.scenario_type, hint.first_actor_id, hint, first, last, record))
        if not candidates:
            return ObstacleResult(target_speed)
        candidates.sort(key=lambda c: (c[0], c[1], c[2]))
        _, kind, _, hint, first, last, record = candidates[0]
        if kind == "InvadingTurn":
            return self._invading_turn(ego, route, hint, first, last, record, target_speed)
        if kind in ONE_WAY:
            return self._one_way(snapshot, ego, route, hint, first, last, record, target_speed)
        if kind in TWO_WAYS:
            return self._two_ways(snapshot, ego, route, hint, first, last, record, target_speed)
        if kind == "HazardAtSideLaneTwoWays":
            return self._hazard_two_ways(snapshot, ego, route, first, last, record, target_speed)
        if kind == "HazardAtSideLane":
            return self._hazard_side_lane(ego, route, first, last, record, target_speed)
        return self._emergency_vehicle(ego, route, first, record, target_speed)

    # -- the scenario kinds ----------------------------------------------------------------------------------
    def _invading_turn(self, ego: ActorState, route: DenseRoute, hint: ScenarioHint, first: ActorState,
                       last: ActorState | None, record: ScenarioRecord, target_speed: float) -> ObstacleResult:
        near = float(np.linalg.norm(_xyz(first) - _xyz(ego))) < self.config.max_distance_to_process_scenario
        if near or self.config.invading_turn_shift_from_trigger:
            offset = float(hint.offset) if hint.offset is not None else 0.0
            start, end = shift_route_for_invading_turn(route, _xyz(first), _xyz(last or first), offset)
            record.changed_route, record.from_index, record.to_index, record.done = True, start, end, True
            log.debug("InvadingTurn: route offset %.2f m over [%d, %d)", offset, start, end)
        return ObstacleResult(target_speed, scenario="InvadingTurn")

    def _one_way(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, hint: ScenarioHint,
                 first: ActorState, last: ActorState | None, record: ScenarioRecord,
                 target_speed: float) -> ObstacleResult:
        cfg = self.config
        props = hint.scenario_type in PROP_OBSTACLES
        if horizontal_distance(ego, first) < cfg.max_distance_to_process_scenario and not record.changed_route:
            transition = cfg.points(cfg.transition_length_construction if hint.scenario_type == "ConstructionObstacle"
                                    else cfg.transition_length)
            start, end = shift_route_around_actors(
                route, _xyz(first), first.bounding_box.extent.x, None if last is None else _xyz(last),
                0.0 if last is None else last.bounding_box.extent.x, hint.direction, transition,
            )  # fmt: skip
            # props stay handled until the ego has passed the first one (see _stand_before_props)
            record.changed_route, record.from_index, record.to_index, record.done = True, start, end, not props
            log.debug("%s: route shifted over [%d, %d)", hint.scenario_type, start, end)
        if props and record.changed_route:
            if float(ego.transform.get_forward_vector().to_array() @ (_xyz(first) - _xyz(ego))) < 0.0:
                record.done = True
                return ObstacleResult(target_speed, scenario=hint.scenario_type)
            if not record.path_clear:
                waiting = self._wait_for_target_lane(snapshot, ego, route, hint, first, record, target_speed)
                if waiting is not None:
                    return waiting
            return self._stand_before_props(ego, route, first, target_speed, hint.scenario_type)
        return ObstacleResult(target_speed, scenario=hint.scenario_type)

    def _wait_for_target_lane(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, hint: ScenarioHint,
                              first: ActorState, record: ScenarioRecord,
                              target_speed: float) -> ObstacleResult | None:
        """A deviation from PDM-Lite: before a construction site's shift the ego waits short of the shift start
        until no car of the target lane is beside or behind it; None once that lane is clear (committed).

        The shift ends at the board, ~12 m on: a car the forecast meets only once the ego steers into the ramp
        stopped it too close to the board to swing out from a standstill, and after touching the board it stood
        there for good (routes 151030002/03 on Town100, seed 151). The decision is taken, as for the two-way
        obstacles, within 8 m of the shift start; until then the ego slows toward its waiting point.
        """
        cfg = self.config
        if record.from_index - route.index < cfg.points(cfg.max_distance_to_overtake_two_ways):
            here = route.waypoint(route.index)
            target_lane = here.get_left_lane() if hint.direction == "right" else here.get_right_lane()
            lane_ids = (set() if target_lane is None
                        else previous_road_lane_ids(target_lane, cfg.path_clear_lane_trace_distance))
            ramp_end = record.from_index + cfg.points(cfg.transition_length_construction)
            record.path_clear = target_lane is None or is_target_lane_clear_behind(
                cfg, self.town, route, ego, snapshot.vehicles(), ramp_end, target_speed, lane_ids,
            )  # fmt: skip
            if record.path_clear:
                log.debug("%s: target lane clear behind the ego, committing", hint.scenario_type)
                return None
        return self._wait_before_shift(ego, route, first, record, target_speed, hint.scenario_type)

    def _wait_before_shift(self, ego: ActorState, route: DenseRoute, first: ActorState, record: ScenarioRecord,
                           target_speed: float, kind: str) -> ObstacleResult:
        """Wait behind a virtual standing leader just past the start of the planned shift (IDM)."""
        cfg = self.config
        distance = (record.from_index + cfg.points(cfg.two_way_wait_offset) - route.index) / cfg.points_per_meter
        speed = idm_target_speed(cfg, target_speed, ego.speed(), ego.bounding_box.extent.x, 0.0, distance,
                                 cfg.idm_two_way_s0, cfg.idm_two_way_T)
        return ObstacleResult(speed, reduced_by=ReducedBy(speed, first.type_id, first.id, distance), scenario=kind)

    def _stand_before_props(self, ego: ActorState, route: DenseRoute, first: ActorState, target_speed: float,
                            kind: str) -> ObstacleResult:
        """A deviation from PDM-Lite: props are no vehicles, so nothing else stops the ego before a construction
        site while the forecast holds it in its lane for traffic in the target lane; until it has left its lane the
        first prop is a standing leader (IDM as for the two-way wait)."""
        cfg = self.config
        index = min(route.index, len(route) - 1)
        off_lane = float(np.linalg.norm(_xyz(ego)[:2] - route.original_points[index, :2]))
        if off_lane > cfg.hold_lane_tolerance:
            return ObstacleResult(target_speed, scenario=kind)
        distance = horizontal_distance(ego, first)
        speed = idm_target_speed(cfg, target_speed, ego.speed(), ego.bounding_box.extent.x + first.bounding_box.extent.x,
                                 0.0, distance, cfg.idm_two_way_s0, cfg.idm_two_way_T)
        return ObstacleResult(speed, reduced_by=ReducedBy(speed, first.type_id, first.id, distance), scenario=kind)

    def _two_ways(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, hint: ScenarioHint,
                  first: ActorState, last: ActorState | None, record: ScenarioRecord,
                  target_speed: float) -> ObstacleResult:
        cfg = self.config
        kind = hint.scenario_type
        overtake_speed = (cfg.overtake_speed_vehicle_opens_door if kind == "VehicleOpensDoorTwoWays"
                          else cfg.default_overtake_speed)
        if horizontal_distance(ego, first) < cfg.max_distance_to_process_scenario and not record.changed_route:
            extra = cfg.points(cfg.extra_length_two_ways[kind])
            start, end = shift_route_around_actors(
                route, _xyz(first), first.bounding_box.extent.x, None if last is None else _xyz(last),
                0.0 if last is None else last.bounding_box.extent.x, hint.direction,
                cfg.points(cfg.transition_length_two_ways), cfg.lane_transition_factor_two_ways[kind], extra, extra,
            )  # fmt: skip
            record.changed_route, record.from_index, record.to_index = True, start, end
            log.debug("%s: route shifted over [%d, %d)", kind, start, end)
        if (record.changed_route and not record.path_clear and opposite_lane_open(hint)
                and record.from_index - route.index < cfg.points(cfg.max_distance_to_overtake_two_ways)):
            here = route.waypoint(route.index)
            target_lane = here.get_left_lane() if hint.direction == "right" else here.get_right_lane()
            if target_lane is None:
                return ObstacleResult(target_speed, scenario=kind)
            lane_ids = previous_road_lane_ids(target_lane, cfg.path_clear_lane_trace_distance)
            if here.lane_id * target_lane.lane_id > 0:
                # a route file's two-way type on a multi-lane road (Bench2Drive v0.0.4 val 25783, Town04): LB2.0's
                # "opposite" flow drives the ego's way in the lane to its left, coming from behind; the oncoming
                # test saw its cars ahead, driving away, as inside the overtaking zone and waited for good
                ramp_end = record.from_index + cfg.points(cfg.transition_length_two_ways)
                record.path_clear = is_target_lane_clear_behind(
                    cfg, self.town, route, ego, snapshot.vehicles(), ramp_end, target_speed, lane_ids,
                )  # fmt: skip
            else:
                record.path_clear = is_overtaking_path_clear(
                    cfg, self.town, route, ego, snapshot.vehicles(), record.to_index, target_speed, lane_ids,
                    overtake_speed,
                )  # fmt: skip
            if record.path_clear:
                log.debug("%s: overtaking path clear, committing", kind)
        if record.path_clear:
            if route.index >= record.to_index - cfg.points(cfg.distance_to_delete_two_ways):
                record.done = True
            return ObstacleResult(overtake_speed, keep_driving=True, scenario=kind)
        if not record.changed_route:
            return ObstacleResult(target_speed, scenario=kind)
        return self._wait_before_shift(ego, route, first, record, target_speed, kind)

    def _hazard_two_ways(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, first: ActorState,
                         last: ActorState | None, record: ScenarioRecord, target_speed: float) -> ObstacleResult:
        cfg = self.config
        kind = "HazardAtSideLaneTwoWays"
        if horizontal_distance(ego, first) < cfg.max_distance_hazard_at_side_lane_two_ways and not record.changed_route:
            last_location = _xyz(last or first)
            # the bicycles are assumed to ride at most 7.5 m while the ego overtakes
            to_index = route.closest_index(route.index, last_location) + cfg.points(cfg.hazard_two_ways_extra_length)
            from_index = route.index
            here = route.waypoint(route.index)
            target_lane = here.get_left_lane()
            if target_lane is None:
                return ObstacleResult(target_speed, scenario=kind)
            lane_ids = previous_road_lane_ids(target_lane, cfg.path_clear_lane_trace_distance)
            clear = is_overtaking_path_clear(cfg, self.town, route, ego, snapshot.vehicles(), to_index, target_speed,
                                             lane_ids, cfg.default_overtake_speed)
            if clear:
                shift_route_smoothly(route, from_index, to_index, True, cfg.points(cfg.transition_length))
                record.changed_route, record.from_index, record.to_index, record.path_clear = True, from_index, \
                    to_index, True
                log.debug("%s: opposite lane clear, overtaking over [%d, %d)", kind, from_index, to_index)
        if record.path_clear:
            if route.index >= record.to_index:
                record.done = True
            return ObstacleResult(cfg.default_overtake_speed, keep_driving=True, scenario=kind)
        return ObstacleResult(target_speed, scenario=kind)

    def _hazard_side_lane(self, ego: ActorState, route: DenseRoute, first: ActorState, last: ActorState | None,
                          record: ScenarioRecord, target_speed: float) -> ObstacleResult:
        cfg = self.config
        last = last or first
        transition = cfg.points(cfg.transition_length)
        if horizontal_distance(ego, last) < cfg.max_distance_hazard_at_side_lane and not record.changed_route:
            start, end = shift_route_around_actors(route, _xyz(first), first.bounding_box.extent.x, _xyz(last),
                                                   last.bounding_box.extent.x, "right", transition)
            record.changed_route, record.from_index, record.to_index = True, start, end - transition
        if record.changed_route:
            obstacle_index = route.closest_index(route.index, _xyz(last))
            target_end = obstacle_index + int(cfg.points_per_meter * last.bounding_box.extent.x) + 2 * transition
            record.to_index = extend_shift(route, record.to_index, target_end, True, transition)
        if record.changed_route and route.index > record.to_index:
            record.done = True
        return ObstacleResult(target_speed, scenario="HazardAtSideLane")

    def _emergency_vehicle(self, ego: ActorState, route: DenseRoute, ev: ActorState, record: ScenarioRecord,
                           target_speed: float) -> ObstacleResult:
        cfg = self.config
        transition = cfg.points(cfg.transition_length)
        if horizontal_distance(ego, ev) < cfg.max_distance_to_process_scenario and not record.changed_route:
            from_index = min(route.index + cfg.points(cfg.emergency_shift_start), len(route) - 1)
            to_index = from_index + cfg.points(cfg.emergency_shift_length)
            # left unless the map only allows a change to the right there
            record.to_left = route.waypoint(from_index).lane_change != LaneChange.RIGHT
            shift_route_smoothly(route, from_index, to_index, record.to_left, transition)
            record.changed_route, record.from_index, record.to_index = True, from_index, to_index - transition
            log.debug("YieldToEmergencyVehicle: shifting %s from %d", "left" if record.to_left else "right", from_index)
        if record.changed_route:
            target_end = route.index + cfg.points(cfg.emergency_extension_length) + 2 * transition
            record.to_index = extend_shift(route, record.to_index, target_end, record.to_left, transition)
            # done once the EV is in front: the shift is no longer extended and the route ramps back
            if float(ego.transform.get_forward_vector().to_array() @ (_xyz(ev) - _xyz(ego))) > 0.0:
                record.done = True
        return ObstacleResult(target_speed, scenario="YieldToEmergencyVehicle")
