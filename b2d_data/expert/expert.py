"""The PDM-Lite-style privileged expert (expert-and-scenarios.md §1.3): one :meth:`Expert.run_step` per tick.

Per frame: track the dense route, derive the base target speed from the speed limit (× 0.72, capped before
junctions), let the obstacle-scenario manager shift the route or decide to keep driving, otherwise take the
minimum of the hazard target speeds (leading vehicles by IDM, forecast box hits, red lights, stop signs),
then the longitudinal and lateral controllers, steering noise, and the anti-roll / anti-block rules.
It reads only the simulator protocol (:mod:`b2d_data.sim.api`), the map and the format package.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.crossing_flow import (
    Crossing, NO_CROSSING, ROUTE_STEP, box_clearance, crossing_cars, crossing_flow_paths, densify, lengthened,
)
from b2d_data.expert.forecasting import (
    BoxTrack,
    along_path,
    colliding,
    forecast_ego_boxes,
    forecast_vehicles,
    forecast_walkers,
    leading_vehicle_ids,
    num_future_frames,
    trailing_vehicle_ids,
    valid_vehicle,
    with_extents,
)
from b2d_data.expert.hazard_heuristic import should_brake
from b2d_data.expert.idm import idm_target_speed
from b2d_data.expert.lane_change import LaneChangePlanner
from b2d_data.expert.lane_change_gap import LaneChangeGate
from b2d_data.expert.lateral_controller import LateralPIDController, heading_error, lookahead_index
from b2d_data.expert.lights_and_signs import StopSignTracker, red_light_target_speed, stop_sign_centre
from b2d_data.expert.longitudinal_controller import make_longitudinal_controller
from b2d_data.expert.merging import SlowFlowMerge, merge_hint
from b2d_data.expert.obstacle_scenarios import ObstacleScenarioManager, ReducedBy
from b2d_data.expert.route_processing import DenseRoute, build_dense_route
from b2d_data.expert.route_shifting import still_before_shift
from b2d_data.expert.state import CloseSignal, ExpertState
from b2d_data.format.road_option import RoadOption
from b2d_data.sim.api import ActorState, ScenarioHint, Snapshot, TrafficLightState, VehicleControl

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint

log = logging.getLogger(__name__)

#: PDM-Lite's constants as published (CARLA-fitted controller); see :meth:`ExpertConfig.for_builtin`.
DEFAULT_CONFIG = ExpertConfig()


@dataclass
class _Hazards:
    """Outcome of the hazard checks of one frame."""

    brake: bool
    target_speed: float
    reduced_by: ReducedBy | None
    vehicle_hazard: bool = False
    vehicle_id: int | None = None
    walker_hazard: bool = False
    walker_id: int | None = None
    light_hazard: bool = False
    stop_sign_hazard: bool = False
    near_lane_change: bool = False


def _xyz(actor: ActorState) -> np.ndarray:
    loc = actor.location
    return np.array([loc.x, loc.y, loc.z])


def _closer_than(actor: ActorState, centre: np.ndarray, radius: float) -> bool:
    """``norm(actor's location − centre) < radius``, the norm skipped where one axis alone is over a metre farther."""
    loc = actor.location
    if _beyond((loc.x, loc.y, loc.z), centre, radius):
        return False
    return bool(np.linalg.norm(_xyz(actor) - centre) < radius)


def _beyond(point: np.ndarray | tuple[float, float, float], centre: np.ndarray, radius: float) -> bool:
    """Whether one axis alone puts ``point`` over a metre beyond ``radius`` of ``centre`` (so its norm is too)."""
    return bool(abs(point[0] - centre[0]) > radius + 1.0 or abs(point[1] - centre[1]) > radius + 1.0
                or abs(point[2] - centre[2]) > radius + 1.0)


def _lower(current: ReducedBy | None, limit: float, speed: float, type_id: str | None, actor_id: int | None,
           distance: float) -> ReducedBy | None:
    """Keep the object that caused the lowest target speed (only objects that lowered it below ``limit``)."""
    if speed < limit and (current is None or current.speed > speed):
        return ReducedBy(speed, type_id, actor_id, distance)
    return current


class Expert:
    """PDM-Lite-style rule-based driver on a leaderboard route (the 1 m route from ``interpolate_trajectory``)."""

    def __init__(self, map: Map, route: Sequence[tuple[Waypoint, RoadOption]], config: ExpertConfig = DEFAULT_CONFIG,
                 seed: int = 0) -> None:
        if len(route) < 2:
            raise ValueError(f"the expert needs a route of at least 2 points, got {len(route)}")
        self.map = map
        self.leaderboard_route = list(route)
        self.config = config
        self.rng = np.random.default_rng(seed)
        self.lateral = LateralPIDController(config)
        self.longitudinal = make_longitudinal_controller(config)
        self.stop_signs = StopSignTracker(config)
        self.obstacles = ObstacleScenarioManager(config, map)
        self.lane_changes = LaneChangePlanner()
        self.merge = SlowFlowMerge(config, map)
        self.lane_change_gate = LaneChangeGate(config, map) if config.lane_change_gap_acceptance else None
        self.route: DenseRoute | None = None
        self.state: ExpertState | None = None
        self.blocked_ticks = 0
        self._signal_centres: dict[int, np.ndarray] = {}  # lights and signs do not move: trigger centres once
        self._ego_tracks: dict[tuple[bool, float], BoxTrack] | None = None  # during _hazards: see _ego_boxes

    # -- public ------------------------------------------------------------------------------------------------
    def run_step(self, snapshot: Snapshot, hints: Sequence[ScenarioHint] = ()) -> VehicleControl:
        """Control for the ego (the actor with role ``hero``) at this snapshot; :attr:`state` describes why."""
        ego = snapshot.hero()
        if ego is None:
            raise ValueError("the snapshot has no actor with role_name 'hero'")
        cfg = self.config
        if self.route is None:
            self.route = build_dense_route(self.map, self.leaderboard_route, _xyz(ego), snapshot.traffic_lights,
                                           snapshot.traffic_signs, cfg)
        route = self.route
        position = _xyz(ego)
        yaw = math.radians(ego.transform.rotation.yaw)
        speed = ego.speed()
        index = route.update_index(position)
        # Route lane changes: across a scenario's flow the gate waits beside the flow for a gap (flows keep moving,
        # so one comes); elsewhere the planner follows the route's change and, if the new lane has become a standing
        # queue, holds the old lane and drives on (lane_change.py). One of the two owns a route at a time.
        gate = self.lane_change_gate if self.lane_change_gate is not None and _scenario_vehicles(snapshot) else None
        if gate is None:
            self.lane_changes.step(snapshot, ego, route)
        lane_change_cap = self.lane_changes.speed_cap if gate is None else math.inf

        speed_limit = float(route.speed_limits[index])
        target_speed = min(speed_limit * cfg.ratio_target_speed_limit, lane_change_cap)
        if route.is_junction[index : index + cfg.points(cfg.junction_lookahead)].any():
            target_speed = min(target_speed, cfg.max_speed_in_junction)
        # the flow checks below act only while a scenario whose flow never brakes for the ego runs (its hint)
        flows = any(h.scenario_type in FLOW_TYPES for h in hints)
        paths = {k: v for h in hints for k, v in h.paths.items()}
        keep_up = self._flow_speed_along_route(snapshot, ego, route, paths) if flows else 0.0
        if keep_up > target_speed:
            # A deviation from PDM-Lite: a flow that never brakes for the ego (LB2.0's ActorFlow) and drives where
            # the ego drives is driven with at its own speed, even above the speed limit (LB2.0 scores no speeding),
            # or its cars run into the ego from behind (EnterActorFlow's 12-14 m/s flows on 40 km/h roads).
            target_speed = min(keep_up, lane_change_cap, max(target_speed, cfg.max_speed_in_junction))

        crossing_paths = crossing_flow_paths(cfg, hints)
        crossing_lines = (self._crossing_lines(snapshot, ego, route, crossing_paths, target_speed)
                          if flows and crossing_paths else {})  # fmt: skip
        if crossing_lines:
            # A deviation from PDM-Lite: a flow that never yields is crossed at least at its own speed (within the
            # speed limit and the junction cap): at 0.72 x 40 km/h the ego spends ~1.4 s on a left turn's oncoming
            # lane, and a 10 m/s flow 22-26 m apart never leaves that long a gap (SignalizedJunctionLeftTurn 97310002
            # on Town100, seed 97).
            fastest = max(snapshot.actors[i].speed() for i in crossing_lines)
            target_speed = max(target_speed, min(fastest, speed_limit, lane_change_cap, cfg.max_speed_in_junction))
        if gate is not None:
            target_speed = min(target_speed, gate.step(snapshot.vehicles(), ego, route, target_speed).target_speed)
        follower_floor = 0.0
        if flows:
            # waiting for a gap to change lanes (the gate slows down toward one, or stops at the last point) in a
            # lane whose flow never brakes: the car behind would run into the ego (route 53130004, HighwayExit on
            # Town100, seed 53: hit from behind while slowing in the flow's lane before the exit lane)
            follower_floor = min(self._flow_follower_floor(snapshot, ego), speed_limit * 1.5)
            target_speed = max(target_speed, follower_floor)
        obstacle = self.obstacles.step(snapshot, ego, route, hints, target_speed)
        if obstacle.keep_driving:
            hazards = _Hazards(False, obstacle.target_speed, None)
        else:
            hazards = self._hazards(snapshot, ego, route, target_speed, obstacle.reduced_by, flows, paths,
                                    crossing_lines, follower_floor)
        final_speed = min(hazards.target_speed, obstacle.target_speed)
        merging = merge_hint(hints)
        if merging is not None and not obstacle.keep_driving:
            final_speed, hazards.reduced_by = self._merge_speed(snapshot, ego, route, merging, final_speed,
                                                                hazards.reduced_by)
        if index > route.end_index >= 0:
            # past the leaderboard route's end (runners stop there): halt before the extension runs out
            remaining = (len(route) - 1 - index) / cfg.points_per_meter
            final_speed = min(final_speed, idm_target_speed(cfg, final_speed, speed, 0.0, 0.0, remaining,
                                                            cfg.idm_stop_sign_s0, cfg.idm_stop_sign_T))
        brake = hazards.brake or final_speed <= 0.0
        reduced_by = hazards.reduced_by
        if obstacle.reduced_by is not None and (reduced_by is None or obstacle.reduced_by.speed < reduced_by.speed):
            reduced_by = obstacle.reduced_by

        ego_wp = self.map.get_waypoint(ego.location)
        junction = bool(ego_wp.is_junction) if ego_wp is not None else False

        throttle, control_brake = self.longitudinal.get_throttle_and_brake(brake, final_speed, speed)
        # A deviation from PDM-Lite: while braking for a vehicle outside its own lane and still on that lane before a
        # planned lane shift, steer along the unshifted route. PDM-Lite keeps steering into the shift while it brakes,
        # which drives it into the very car it brakes for (HazardAtSideLane beside a slower car). Braking for the
        # obstacle in its own lane (Accident), it still edges into the shift as PDM-Lite does.
        blocker = snapshot.actors.get(hazards.vehicle_id) if hazards.vehicle_id is not None else None
        holding = (blocker is not None and not self.lane_changes.holding
                   and still_before_shift(route, position, _xyz(blocker), cfg.hold_lane_tolerance,
                                          cfg.lateral_max_lookahead))
        ahead_points = (route.original_points if holding else route.points)[index:]
        steer = round(self.lateral.step(ahead_points, speed, position[:2], yaw), 3)
        aim = ahead_points[lookahead_index(cfg, speed, ahead_points.shape[0])].copy()
        angle = math.degrees(heading_error(position, yaw, aim)) / 90.0
        applied_steer = float(np.clip(steer + cfg.steer_noise * self.rng.standard_normal(), -1.0, 1.0))
        applied_brake = 1.0 if (brake or control_brake) else 0.0
        if throttle == 0.0 and speed < cfg.min_speed_prevent_rolling_back:
            applied_brake = 1.0  # keeps a standing car from rolling
        planar = math.hypot(ego.velocity.x, ego.velocity.y)
        self.blocked_ticks = self.blocked_ticks + 1 if planar < cfg.blocked_speed else 0
        if self.blocked_ticks >= cfg.max_blocked_ticks:
            # PDM-Lite's own anti-block rule (its autopilot, "apply throttle if the vehicle is blocked for too long",
            # §1.3 step 6), kept as is: full throttle every tick from 170 ticks below 0.1 m/s on until the ego
            # moves. PDM-Lite wrote it against the agent-blocked test, which LB2.0 pauses while a scenario's
            # ScenarioTimeout runs (framework.py); it fires there too in CARLA, so it does here.
            throttle, applied_brake = 1.0, 0.0
        control = VehicleControl(throttle=float(throttle), steer=applied_steer, brake=applied_brake)

        light_id = route.next_light[index]
        light = snapshot.traffic_lights.get(light_id) if light_id is not None else None
        stop_id = route.next_stop[index]
        light_red = light is not None and light.state in (TrafficLightState.RED, TrafficLightState.YELLOW)
        tcp_light = light_red and route.light_distance[index] < cfg.light_radius
        tcp_stop = (stop_id is not None and not self.stop_signs.cleared
                    and route.stop_distance[index] < cfg.stop_sign_max_distance)
        others = [v for v in snapshot.vehicles() if v.id != ego.id]
        tcp_brake = should_brake(cfg, ego, others, snapshot.walkers(), tcp_light, tcp_stop)

        # the recorded route samples (§1.11); "changed" means the shift reaches into them
        recorded = route.samples(route.points, cfg.route_record_first, cfg.route_record_points)
        recorded_original = route.samples(route.original_points, cfg.route_record_first, cfg.route_record_points)
        self.state = ExpertState(
            frame=snapshot.frame, control=control, target_speed=float(final_speed), speed_limit=speed_limit,
            speed=speed, route_index=index, command=route.commands[index], junction=junction,
            vehicle_hazard=hazards.vehicle_hazard, vehicle_affecting_id=hazards.vehicle_id,
            walker_hazard=hazards.walker_hazard, walker_affecting_id=hazards.walker_id,
            light_hazard=hazards.light_hazard, stop_sign_hazard=hazards.stop_sign_hazard,
            stop_sign_close=hazards.stop_sign_hazard, walker_close=hazards.walker_hazard,
            walker_close_id=hazards.walker_id,
            speed_reduced_by_obj_type=None if reduced_by is None else reduced_by.type_id,
            speed_reduced_by_obj_id=None if reduced_by is None else reduced_by.actor_id,
            speed_reduced_by_obj_distance=None if reduced_by is None else reduced_by.distance,
            brake=bool(brake), control_brake=bool(control_brake), should_brake=tcp_brake,
            aim_point=aim, angle=float(angle), changed_route=bool(np.any(recorded != recorded_original)),
            route=recorded, route_original=recorded_original,
            near_lane_change=hazards.near_lane_change, keep_driving=obstacle.keep_driving,
            active_scenario=obstacle.scenario, next_traffic_light_id=light_id,
            distance_to_traffic_light=float(route.light_distance[index]), next_stop_sign_id=stop_id,
            distance_to_stop_sign=float(route.stop_distance[index]),
            close_traffic_lights=self._close_lights(snapshot, position, light_id),
            close_stop_signs=self._close_stop_signs(snapshot, position, stop_id),
        )  # fmt: skip
        return control

    def remaining_route(self, step: float = 1.0) -> tuple[np.ndarray, list[RoadOption]]:
        """World points (M, 3) and commands of the working route from the current index, every ``step`` metres."""
        if self.route is None:
            pts = np.array([[wp.transform.location.x, wp.transform.location.y, wp.transform.location.z]
                            for wp, _ in self.leaderboard_route])
            return pts, [RoadOption(int(c)) for _, c in self.leaderboard_route]
        every = max(1, self.config.points(step))
        idx = range(self.route.index, len(self.route), every)
        return self.route.points[list(idx)].copy(), [self.route.commands[i] for i in idx]

    def _merge_speed(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, hint: ScenarioHint,
                     speed: float, reduced_by: ReducedBy | None) -> tuple[float, ReducedBy | None]:
        """A merge scenario's gap acceptance (:mod:`b2d_data.expert.merging`) on top of the hazard speeds."""
        vehicles = [v for v in snapshot.vehicles() if v.id != ego.id and valid_vehicle(v)]
        merge_speed, leader = self.merge.target_speed(hint, ego, route, vehicles, speed)
        if leader is not None:
            distance = float(np.linalg.norm(_xyz(leader) - _xyz(ego)))
            reduced_by = _lower(reduced_by, speed, merge_speed, leader.type_id, leader.id, distance)
        return min(speed, merge_speed), reduced_by

    # -- hazards -----------------------------------------------------------------------------------------------
    def _hazards(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, initial_speed: float,
                 reduced_by: ReducedBy | None, flows: bool = False,
                 paths: Mapping[int, np.ndarray] | None = None,
                 crossing_lines: Mapping[int, float] | None = None, follower_floor: float = 0.0) -> _Hazards:
        """Target speeds for every hazard class and their minimum (§1.6–1.7); ``brake`` when it is 0.

        ``follower_floor`` is the speed a flow car behind the ego needs it to keep (``_flow_follower_floor``).
        """
        self._ego_tracks = {}
        try:
            return self._hazard_speeds(snapshot, ego, route, initial_speed, reduced_by, flows, paths, crossing_lines,
                                       follower_floor)
        finally:
            self._ego_tracks = None

    def _ego_boxes(self, ego: ActorState, route: DenseRoute, target_speed: float, frames: int,
                   braking: bool = False) -> BoxTrack:
        """``forecast_ego_boxes`` over ``frames``, run once per hazard check for each target speed and braking flag.

        Within one check the ego, the route, its index and the controllers' state do not change, and each forecast
        frame follows from the frame before alone, so a shorter forecast is the start of a longer one, to the bit.
        """
        key = (braking, target_speed)
        track = self._ego_tracks.get(key) if self._ego_tracks is not None else None
        if track is None or track.centres.shape[0] < frames:
            track = forecast_ego_boxes(self.config, ego, route, self.lateral, self.longitudinal, target_speed, frames,
                                       braking=braking)
            if self._ego_tracks is not None:
                self._ego_tracks[key] = track
        if track.centres.shape[0] == frames:
            return track
        return BoxTrack(track.actor_id, track.centres[:frames], track.yaws[:frames], track.extents[:frames])

    def _hazard_speeds(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute, initial_speed: float,
                       reduced_by: ReducedBy | None, flows: bool, paths: Mapping[int, np.ndarray] | None,
                       crossing_lines: Mapping[int, float] | None, follower_floor: float) -> _Hazards:
        """The body of :meth:`_hazards`."""
        cfg = self.config
        ego_loc = _xyz(ego)
        speed = ego.speed()
        index = route.index
        # a lane change committed after waiting (lane_change.py) follows the cars ahead by IDM like any leader:
        # forecast-only braking would keep it standing across both lanes
        near_lc = route.near_lane_change(speed) and not self.lane_changes.committed
        frames = num_future_frames(cfg, near_lc)
        vehicles = [v for v in snapshot.vehicles() if v.id != ego.id and valid_vehicle(v)]
        nearby = [v for v in vehicles if _closer_than(v, ego_loc, cfg.detection_radius)]
        walkers = [w for w in snapshot.walkers() if _closer_than(w, ego_loc, cfg.detection_radius)]
        result = _Hazards(False, initial_speed, reduced_by, near_lane_change=near_lc)

        leading = leading_vehicle_ids(cfg, route, vehicles)
        trailing = trailing_vehicle_ids(cfg, route, vehicles)
        speed_leading = initial_speed
        if not near_lc:
            for v in nearby:
                if v.id not in leading:
                    continue
                distance = float(np.linalg.norm(_xyz(v) - ego_loc))
                s = idm_target_speed(cfg, initial_speed, speed, 2.0 * v.bounding_box.extent.x, v.speed(), distance,
                                     cfg.idm_leading_vehicle_s0, cfg.idm_leading_vehicle_T)
                gap = distance - v.bounding_box.extent.x - ego.bounding_box.extent.x
                if follower_floor > s and gap > cfg.idm_leading_vehicle_s0:
                    # A deviation from PDM-Lite: between two cars of a flow that never brakes, IDM (whose desired
                    # speed is at most the flow's) settles below the leader's speed and the follower runs into the
                    # ego (route 151130003, HighwayExit on Town100, seed 151). The leader's speed keeps the gap.
                    s = max(s, min(follower_floor, v.speed()))
                speed_leading = min(speed_leading, s)
                result.reduced_by = _lower(result.reduced_by, initial_speed, speed_leading, v.type_id, v.id,
                                           distance)

        if flows and any(v.role_name == _SCENARIO_ROLE and v.speed() >= cfg.other_vehicle_slow_speed for v in nearby):
            # the flow checks below forecast the ego over the longer commit horizon: one forecast serves both
            self._ego_boxes(ego, route, initial_speed, max(frames, int(cfg.fps * cfg.commit_forecast_length)))
        ego_track = self._ego_boxes(ego, route, initial_speed, frames)
        # a flow crossing the route has its own gap acceptance (crossing_flow.py): its cars leave the checks below
        crossing = (self._crossing_flow(ego, route, [v for v in nearby if v.id in crossing_lines], crossing_lines,
                                        initial_speed, paths)
                    if crossing_lines and paths else NO_CROSSING)  # fmt: skip
        skip = (set() if near_lc else leading | trailing) | crossing.cars
        # in a committed route lane change the cars behind are left to brake for the ego (lane_change.py)
        checked = [v for v in nearby if v.id not in skip and not self.lane_changes.yields_to_ego(ego, v)]
        tracks = forecast_vehicles(cfg, checked, frames, near_lc)
        by_id = {v.id: v for v in checked}
        speed_bicycle = speed_vehicle = speed_walker = initial_speed
        hits = colliding(ego_track, tracks)
        flow_hits, drive_on = (self._flow_cars(ego, route, [v for v in nearby if v.id not in crossing.cars], leading,
                                               set(hits), initial_speed, paths)
                               if flows else (set(), set()))  # fmt: skip
        by_id.update({v.id: v for v in nearby})
        # flow cars only the long forecast meets and whose paths join the route: wait for them just short of their
        # paths, not where the long forecast first meets them
        joining = ({i for i in flow_hits - set(hits) if i in paths and self._joins_route(route, paths[i])}
                   if flows and paths else set())  # fmt: skip
        hold = self._conflict_hold(ego, route, [paths[i] for i in joining]) if joining else None
        hits = sorted((set(hits) | flow_hits | set(crossing.blocking)) - drive_on,
                      key=lambda i: float(np.linalg.norm(_xyz(by_id[i]) - ego_loc)))  # fmt: skip
        for actor_id in hits:
            actor = by_id[actor_id]
            distance = float(np.linalg.norm(_xyz(actor) - ego_loc))
            yaw_difference = abs((actor.transform.rotation.yaw - ego.transform.rotation.yaw + 180.0) % 360 - 180.0)
            # A deviation from PDM-Lite, whose IDM takes every bicycle as one riding ahead of the ego: while a flow
            # scenario runs, a bicycle that crosses or comes toward the ego is braked for like a car (a crossing
            # flow's bicycles never brake for the ego, LB2.0's BicycleFlow).
            if actor.base_type == "bicycle" and (not flows or yaw_difference < cfg.leading_max_yaw_difference):
                s = idm_target_speed(cfg, initial_speed, speed, 2.0 * actor.bounding_box.extent.x, actor.speed(),
                                     distance, cfg.idm_bicycle_s0, cfg.idm_bicycle_T)
                speed_bicycle = min(speed_bicycle, s)
                result.reduced_by = _lower(result.reduced_by, initial_speed, speed_bicycle, actor.type_id,
                                           actor.id, distance)
            else:
                s = 0.0
                if actor_id in joining and hold is not None:
                    s = idm_target_speed(cfg, initial_speed, speed, 0.0, 0.0, hold, cfg.idm_red_light_s0,
                                         cfg.idm_red_light_T)
                elif actor_id in crossing.blocking and not crossing.committed and crossing.line:
                    # wait short of the line as at a red light's: the run-up takes the ego across the lane sooner
                    s = idm_target_speed(cfg, initial_speed, speed, 0.0, 0.0, crossing.line, cfg.idm_red_light_s0,
                                         cfg.idm_red_light_T)
                if s == 0.0 and not result.vehicle_hazard:
                    result.vehicle_hazard, result.vehicle_id = True, actor.id
                speed_vehicle = min(speed_vehicle, s)
                result.reduced_by = _lower(result.reduced_by, initial_speed, s, actor.type_id, actor.id, distance)

        walker_by_id = {w.id: w for w in walkers}
        walker_target: dict[int, float] = {}
        for actor_id in colliding(ego_track, forecast_walkers(cfg, walkers, frames)):
            walker = walker_by_id[actor_id]
            distance = float(np.linalg.norm(_xyz(walker) - ego_loc))
            s = idm_target_speed(cfg, initial_speed, speed, 0.5 + ego.bounding_box.extent.x, 0.0, distance,
                                 cfg.idm_pedestrian_s0, cfg.idm_pedestrian_T)
            walker_target[actor_id] = s
            speed_walker = min(speed_walker, s)
            result.reduced_by = _lower(result.reduced_by, initial_speed, speed_walker, walker.type_id, walker.id,
                                       distance)

        light_id = route.next_light[index]
        light = snapshot.traffic_lights.get(light_id) if light_id is not None else None
        light_distance = float(route.light_distance[index])
        speed_light = red_light_target_speed(cfg, initial_speed, speed, light_distance, light)
        if light is not None:
            result.reduced_by = _lower(result.reduced_by, initial_speed, speed_light, "traffic.traffic_light", light.id,
                                       light_distance)

        stop_id = route.next_stop[index]
        sign = snapshot.traffic_signs.get(stop_id) if stop_id is not None else None
        speed_stop, stop_distance = self.stop_signs.target_speed(initial_speed, speed, ego_loc, sign)
        if sign is not None:
            result.reduced_by = _lower(result.reduced_by, initial_speed, speed_stop, sign.type_id, sign.id,
                                       stop_distance)

        target = min(speed_leading, speed_bicycle, speed_vehicle, speed_walker, speed_light, speed_stop)
        result.target_speed = target
        if target == speed_walker and speed_walker != initial_speed:
            result.walker_hazard = True
            result.walker_id = min(walker_target, key=walker_target.get)
        elif target == speed_light and speed_light != initial_speed:
            result.light_hazard = True
        elif target == speed_stop and speed_stop != initial_speed:
            result.stop_sign_hazard = True
        result.brake = target == 0.0
        return result

    def _crossing_lines(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute,
                        paths: Mapping[int, np.ndarray], target_speed: float) -> dict[int, float]:
        """The moving flow cars within ``detection_radius`` whose hinted paths cross the route within reach of the
        long forecast (and do not join it): id → metres the ego may drive before its box comes within
        ``flow_hold_margin`` m of that car's path (crossing_flow.py)."""
        cfg = self.config
        moving = [v for v in snapshot.vehicles() if v.role_name == _SCENARIO_ROLE and v.id in paths
                  and v.speed() >= cfg.other_vehicle_slow_speed and valid_vehicle(v)
                  and v.location.distance_2d(ego.location) < cfg.detection_radius
                  and not self._joins_route(route, paths[v.id])]  # fmt: skip
        if not moving:
            return {}
        fastest = max([target_speed, ego.speed(), *(v.speed() for v in moving)])
        reach = max(cfg.flow_hold_range, cfg.commit_forecast_length * fastest + 10.0)
        step = max(1, round(ROUTE_STEP * cfg.points_per_meter))
        end = route.index + cfg.points(reach)
        return crossing_cars(route.points[route.index : end : step], route.headings[route.index : end : step], ego,
                             moving, paths, cfg.flow_hold_margin)

    def _crossing_flow(self, ego: ActorState, route: DenseRoute, cars: list[ActorState], lines: Mapping[int, float],
                       initial_speed: float, paths: Mapping[int, np.ndarray]) -> Crossing:
        """The gap acceptance across the crossing flow ``cars`` (their ``lines``, see :meth:`_crossing_lines`)."""
        cfg = self.config
        if not cars:
            return Crossing(frozenset(lines))
        frames = int(cfg.fps * cfg.commit_forecast_length)
        # committed: a full brake from now on would leave the ego's box on a crossing car's path
        stop = self._ego_boxes(ego, route, initial_speed, frames, braking=True)
        e = ego.bounding_box.extent
        committed = any(float(box_clearance(stop.centres[-1:, :2], stop.yaws[-1:], (e.x, e.y),
                                            densify(paths[v.id]))[0]) < v.bounding_box.extent.y for v in cars)
        if committed:
            # it drives on: standing on the flow's path it would be struck by this car or a later one, or stand in
            # another flow's way (InterurbanAdvancedActorFlow 101150002, Town100, seed 101)
            return Crossing(frozenset(lines), (), min(lines[v.id] for v in cars), True)
        # the cars as their agents drive them: along their paths at their speeds
        tracks = [along_path(cfg, t, v, paths[v.id]) for t, v in zip(forecast_vehicles(cfg, cars, frames, False), cars)]
        go = with_extents(self._ego_boxes(ego, route, initial_speed, frames), ego, cfg.commit_margin)
        seconds = cfg.flow_crossing_accept_time
        blocking = colliding(go, [lengthened(t, v, seconds) for t, v in zip(tracks, cars)])
        return Crossing(frozenset(lines), tuple(blocking), min(lines[v.id] for v in cars), False)

    def _conflict_hold(self, ego: ActorState, route: DenseRoute, paths: list[np.ndarray]) -> float | None:
        """Metres the ego's front may still drive before its box would come within ``flow_hold_margin`` m of a flow
        car on one of ``paths`` (a car ~2 m wide on its path), looking ``flow_hold_range`` m ahead; None when the
        route does not come near them that soon or the ego is already that close."""
        cfg = self.config
        index = route.index
        ahead = route.points[index : index + cfg.points(cfg.flow_hold_range), :2]
        if ahead.shape[0] == 0:
            return None
        known = [p for p in paths if p.shape[0]]
        if not known:  # cars at the ends of their paths
            return None
        lanes = np.concatenate(known, axis=0)
        near = np.min(np.hypot(ahead[:, None, 0] - lanes[None, :, 0], ahead[:, None, 1] - lanes[None, :, 1]), axis=1)
        # the route's point where the ego's front would stand when its centre comes that close
        clearance = ego.bounding_box.extent.y + FLOW_CAR_HALF_WIDTH + cfg.flow_hold_margin
        inside = np.flatnonzero(near < clearance)
        if inside.size == 0:
            return None
        distance = int(inside[0]) / cfg.points_per_meter - ego.bounding_box.extent.x
        return distance if distance > 0.0 else None

    def _joins_route(self, route: DenseRoute, path: np.ndarray) -> bool:
        """Whether a flow car's hinted path runs along the route within ``flow_route_ahead`` m ahead of the ego."""
        cfg = self.config
        end = route.index + cfg.points(cfg.flow_route_ahead)
        step = cfg.points_per_meter
        return _path_joins(path, route.points[route.index : end : step, :2], route.headings[route.index : end : step],
                           cfg)

    def _flow_speed_along_route(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute,
                                paths: Mapping[int, np.ndarray] | None = None) -> float:
        """The highest speed of the cars of a scenario's flow within ``detection_radius`` that drive along the route
        from ``flow_route_ahead`` metres behind the ego to as far ahead (within ``leading_max_yaw_difference`` of
        its heading there and ``flow_route_distance`` of it), or whose hinted path joins the route within the
        ``flow_route_ahead`` m ahead of the ego (a flow the ego turns into: its cars come up from behind the junction
        exit, off the route behind the ego); 0 when there is none."""
        cfg = self.config
        flow = [v for v in snapshot.vehicles() if v.role_name == _SCENARIO_ROLE and v.base_type != "bicycle"
                and v.speed() >= cfg.other_vehicle_slow_speed
                and v.location.distance_2d(ego.location) < cfg.detection_radius]  # fmt: skip
        if not flow or route.index >= len(route):
            return 0.0
        step = cfg.points_per_meter
        begin = max(0, route.index - cfg.points(cfg.flow_route_ahead))
        end = route.index + cfg.points(cfg.flow_route_ahead)
        points = route.points[begin:end:step, :2]
        headings = route.headings[begin:end:step]
        ahead = (route.index - begin) // step
        best = 0.0
        for v in flow:
            d = np.hypot(points[:, 0] - v.location.x, points[:, 1] - v.location.y)
            k = int(np.argmin(d))
            diff = abs((headings[k] - v.transform.rotation.yaw + 180.0) % 360.0 - 180.0)
            if d[k] < cfg.flow_route_distance and diff < cfg.leading_max_yaw_difference:
                best = max(best, v.speed())
            elif paths and v.id in paths and _path_joins(paths[v.id], points[ahead:], headings[ahead:], cfg):
                best = max(best, v.speed())
        return best

    def _flow_follower_floor(self, snapshot: Snapshot, ego: ActorState) -> float:
        """The lowest speed that keeps every flow car behind the ego in its lane ``flow_follower_time`` s from
        closing its bumper gap to ``flow_follower_margin`` m (0 when none follows within ``flow_follower_range``)."""
        cfg = self.config
        yaw = math.radians(ego.transform.rotation.yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        floor = 0.0
        for v in snapshot.vehicles():
            if v.role_name != _SCENARIO_ROLE or v.id == ego.id or v.base_type == "bicycle":
                continue
            dx, dy = v.location.x - ego.location.x, v.location.y - ego.location.y
            along, across = dx * c + dy * s, -dx * s + dy * c
            diff = abs((v.transform.rotation.yaw - ego.transform.rotation.yaw + 180.0) % 360.0 - 180.0)
            if along >= 0.0 or -along > cfg.flow_follower_range or abs(across) > 1.8 or diff > 30.0:
                continue
            gap = -along - ego.bounding_box.extent.x - v.bounding_box.extent.x
            floor = max(floor, v.speed() - max(0.0, gap - cfg.flow_follower_margin) / cfg.flow_follower_time)
        return floor

    def _flow_cars(self, ego: ActorState, route: DenseRoute, nearby: list[ActorState], leading: set[int],
                   hits: set[int], initial_speed: float,
                   paths: Mapping[int, np.ndarray] | None = None) -> tuple[set[int], set[int]]:
        """Cars that never brake for the ego (a scenario's flows): (those to brake for, forecast hits to drive on
        past). A deviation from PDM-Lite, whose 2 s forecast and trailing-car exemption assume that others brake.

        LB2.0's ActorFlow cars ignore vehicles until their first collision, so (1) they are checked over
        ``commit_forecast_length`` too, the trailing ones included (not those behind that go the ego's way),
        against the ego driving on at its target speed, so that it waits before it enters a flow's path rather
        than in it; and (2) where braking to a stand
        from now on would meet such a car anyway (the ego has already edged into its path, or the car comes from
        behind), braking is no escape: the ego drives on when driving on at the target speed clears that car's
        real box by ``commit_margin``, or when the car comes from behind. Bicycles count too (LB2.0's BicycleFlow
        ignores vehicles). A car whose path the scenario hints is forecast along that path at its speed: one about
        to turn into the ego's exit is otherwise forecast straight on until it steers, under a second before the
        conflict (route 28087 on Town04).
        """
        cfg = self.config
        flow = [v for v in nearby if v.role_name == _SCENARIO_ROLE and v.speed() >= cfg.other_vehicle_slow_speed]
        if not flow:
            return set(), set()
        frames = int(cfg.fps * cfg.commit_forecast_length)
        tracks = [along_path(cfg, t, by, paths[by.id]) if paths and by.id in paths else t
                  for t, by in zip(forecast_vehicles(cfg, flow, frames, False), flow)]
        go = self._ego_boxes(ego, route, initial_speed, frames)
        by_id = {v.id: v for v in flow}
        yaw = math.radians(ego.transform.rotation.yaw)

        def behind(v: ActorState) -> bool:
            dx, dy = v.location.x - ego.location.x, v.location.y - ego.location.y
            return dx * math.cos(yaw) + dy * math.sin(yaw) < 0.0

        def following(v: ActorState) -> bool:
            diff = abs((v.transform.rotation.yaw - ego.transform.rotation.yaw + 180.0) % 360.0 - 180.0)
            return behind(v) and diff < cfg.leading_max_yaw_difference

        # cars behind that go the ego's way are the merge's and the lane-change gate's business (their gaps) and
        # would otherwise hold a slow ego at the end of a ramp for ever; the long check is for crossing paths
        late = set(colliding(go, [t for t in tracks if t.actor_id not in leading
                                  and not following(by_id[t.actor_id])]))  # fmt: skip
        threats = late | (hits & {v.id for v in flow})
        if not threats:
            return set(), set()
        real = {t.actor_id: with_extents(t, by_id[t.actor_id]) for t in tracks if t.actor_id in threats}
        stop = with_extents(self._ego_boxes(ego, route, initial_speed, frames, braking=True), ego)
        struck = set(colliding(stop, list(real.values())))
        if not struck:
            return late, set()
        blocked = set(colliding(with_extents(go, ego, cfg.commit_margin), [real[i] for i in struck]))
        drive_on = (struck - blocked) | {i for i in struck if behind(by_id[i])}
        if drive_on:
            log.debug("braking would leave the ego in the path of %s: it drives on", sorted(drive_on))
        return late - drive_on, drive_on

    # -- dataset helpers ---------------------------------------------------------------------------------------
    def _close_lights(self, snapshot: Snapshot, position: np.ndarray, affecting: int | None) -> tuple[CloseSignal, ...]:
        out = []
        for light_id in sorted(snapshot.traffic_lights):
            light = snapshot.traffic_lights[light_id]
            loc = self._signal_centres.get(light_id)
            if loc is None:
                centre = light.transform.transform_point(light.trigger_volume.location)
                loc = self._signal_centres.setdefault(light_id, np.array([centre.x, centre.y, centre.z]))
            if _beyond(loc, position, self.config.light_radius):
                continue
            if np.linalg.norm(loc - position) <= self.config.light_radius:
                out.append(CloseSignal(light_id, "traffic.traffic_light", loc, light.transform.rotation.yaw,
                                       light_id == affecting, light.state))
        return tuple(out)

    def _close_stop_signs(self, snapshot: Snapshot, position: np.ndarray,
                          affecting: int | None) -> tuple[CloseSignal, ...]:
        out = []
        for sign_id in sorted(snapshot.traffic_signs):
            sign = snapshot.traffic_signs[sign_id]
            if not sign.type_id.startswith("traffic.stop"):
                continue
            loc = self._signal_centres.get(sign_id)
            if loc is None:
                loc = self._signal_centres.setdefault(sign_id, stop_sign_centre(sign))
            if _beyond(loc, position, self.config.light_radius):
                continue
            if np.linalg.norm(loc - position) <= self.config.light_radius:
                out.append(CloseSignal(sign_id, sign.type_id, loc, sign.transform.rotation.yaw,
                                       sign_id == affecting and not self.stop_signs.cleared))
        return tuple(out)


#: Scenarios whose flows (LB2.0's ActorFlow, BicycleFlow) never brake for the ego; their hints switch the expert's
#: flow checks on (``_flow_cars``, ``_flow_speed_along_route``, crossing bicycles braked for like cars).
FLOW_TYPES = frozenset({
    "SignalizedJunctionLeftTurn", "NonSignalizedJunctionLeftTurn", "SignalizedJunctionLeftTurnEnterFlow",
    "NonSignalizedJunctionLeftTurnEnterFlow", "SignalizedJunctionRightTurn", "NonSignalizedJunctionRightTurn",
    "EnterActorFlow", "InterurbanActorFlow", "InterurbanAdvancedActorFlow", "MergerIntoSlowTraffic",
    "MergerIntoSlowTrafficV2", "HighwayExit", "CrossingBicycleFlow", "EnterActorFlowV2",
})  # fmt: skip

#: ``role_name`` of the actors a scenario spawns (``scenarios.framework.SCENARIO_ROLE``; the expert is privileged).
_SCENARIO_ROLE = "scenario"


#: Half the width of a flow's car (m; CARLA's cars: 0.9-1.1) where only its path is known.
FLOW_CAR_HALF_WIDTH = 1.0


def _path_joins(path: np.ndarray, points: np.ndarray, headings: np.ndarray, cfg: ExpertConfig) -> bool:
    """Whether a flow car's path ((N, 2), from the car on) runs along the route ``points`` (within
    ``flow_route_distance`` of one, heading within ``leading_max_yaw_difference`` of the route's there)."""
    if path.shape[0] < 2 or points.shape[0] == 0:
        return False
    d = np.hypot(path[:, None, 0] - points[None, :, 0], path[:, None, 1] - points[None, :, 1])
    i, k = np.unravel_index(int(np.argmin(d)), d.shape)
    if d[i, k] >= cfg.flow_route_distance:
        return False
    j = min(i, path.shape[0] - 2)
    yaw = math.degrees(math.atan2(path[j + 1, 1] - path[j, 1], path[j + 1, 0] - path[j, 0]))
    return abs((headings[k] - yaw + 180.0) % 360.0 - 180.0) < cfg.leading_max_yaw_difference


def _scenario_vehicles(snapshot: Snapshot) -> bool:
    """Whether any vehicle of a scenario (a flow, a cut-in car, ...) is in the world."""
    return any(v.role_name == _SCENARIO_ROLE for v in snapshot.vehicles())
