"""Forecast boxes of the ego, other vehicles and walkers, and sort vehicles into leading / trailing (§1.6).

All forecasts are at the simulation rate (20 Hz) over 2.0 s, or 1.1 s near a lane change. Collision checks are
between the ego's box at frame i and every actor's box at the same frame i (:mod:`b2d_data.expert.obb`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.kinematic_bicycle import forecast_ego, slip_angle
from b2d_data.expert.lateral_controller import LateralPIDController
from b2d_data.expert.longitudinal_controller import LinearRegressionController, PIDLongitudinalController
from b2d_data.expert.obb import overlap_many, yaw_axes
from b2d_data.expert.route_processing import DenseRoute
from b2d_data.sim.api import ActorState, VehicleControl, WalkerControl


@dataclass(frozen=True)
class BoxTrack:
    """Forecast boxes of one actor over F frames: centres (F, 3), yaws (F,) in radians, half extents (F, 3)."""

    actor_id: int
    centres: np.ndarray
    yaws: np.ndarray
    extents: np.ndarray


def num_future_frames(config: ExpertConfig, near_lane_change: bool) -> int:
    """Forecast horizon in frames (40 normally, 22 near a lane change)."""
    seconds = config.forecast_length_lane_change if near_lane_change else config.forecast_length
    return int(config.fps * seconds)


def _box_offset(actor: ActorState, yaw: np.ndarray) -> np.ndarray:
    """World offset (F, 3) of the bounding-box centre from the actor origin for headings ``yaw``."""
    loc = actor.bounding_box.location
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * loc.x - s * loc.y, s * loc.x + c * loc.y, np.full_like(yaw, loc.z)], axis=-1)


def valid_vehicle(actor: ActorState) -> bool:
    """Vehicles with a real box (CARLA's bugged two-wheelers have zero extents and are ignored)."""
    e = actor.bounding_box.extent
    return min(e.x, e.y, e.z) >= 1e-3


def forecast_vehicles(config: ExpertConfig, vehicles: list[ActorState], frames: int,
                      near_lane_change: bool) -> list[BoxTrack]:
    """Kinematic-bicycle forecasts of other vehicles holding their last applied control (§1.6)."""
    if not vehicles or frames <= 0:
        return []
    n = len(vehicles)
    x = np.array([v.location.x for v in vehicles])
    y = np.array([v.location.y for v in vehicles])
    z = np.array([v.location.z for v in vehicles])
    yaw = np.radians([v.transform.rotation.yaw for v in vehicles])
    speed = np.array([v.speed() for v in vehicles])
    controls = [v.control if isinstance(v.control, VehicleControl) else VehicleControl() for v in vehicles]
    steer = np.array([c.steer for c in controls])
    throttle = np.array([c.throttle for c in controls])
    brake = np.array([c.brake for c in controls])
    braking = brake >= config.other_vehicle_brake_threshold
    accel = np.where(braking, config.other_brake_acceleration, throttle * config.other_throttle_acceleration)
    beta = slip_angle(config, steer)  # constant: the control is held over the horizon
    dt = config.dt
    turn = np.sin(beta) / config.rear_wheel_base * dt
    # Euler steps, frame i + 1 from frame i: speed' = max(0, speed + dt·accel), yaw' = yaw + speed·turn and the
    # position moves with the speed and heading before the step. Each is a running sum (np.add.accumulate adds in
    # order, as the step-by-step loop did); the speed, never negative, is clamped for good once its sum goes below
    # 0 (accel is constant), so clamping the running sum gives the same speeds.
    speeds = np.maximum(0.0, _running_sum(speed, np.broadcast_to(dt * accel, (frames, n))))  # frames 0..F
    yaws = _running_sum(yaw, speeds[:-1] * turn)
    heading = yaws[:-1] + beta
    xs = _running_sum(x, speeds[:-1] * np.cos(heading) * dt)[1:]
    ys = _running_sum(y, speeds[:-1] * np.sin(heading) * dt)[1:]
    yaws, speeds = yaws[1:], speeds[1:]
    x_factor_fast = (config.other_vehicle_extent_x_factor_lane_change if near_lane_change
                     else config.other_vehicle_extent_x_factor)
    growth = np.arange(frames) / frames
    # every vehicle's boxes at once, (vehicle, frame) rows: the same element-wise arithmetic as one vehicle at a
    # time, without a dozen small numpy calls per vehicle
    slow = (speeds < config.other_vehicle_slow_speed).T
    # boxes of moving vehicles grow with the horizon to cover forecasting errors
    fx = np.where(slow, 1.0, np.maximum(x_factor_fast, config.other_vehicle_extent_x_factor * growth))
    fy = np.where(slow, 1.0, np.maximum(config.other_vehicle_min_extent_y_factor,
                                        config.other_vehicle_extent_y_factor * growth))
    boxes = [v.bounding_box for v in vehicles]
    extent = np.array([(b.extent.x, b.extent.y, b.extent.z) for b in boxes])
    offset = np.array([(b.location.x, b.location.y, b.location.z) for b in boxes])
    extents = np.empty((n, frames, 3))
    extents[:, :, 0] = extent[:, 0:1] * fx
    extents[:, :, 1] = extent[:, 1:2] * fy
    extents[:, :, 2] = extent[:, 2:3]
    yaws = np.ascontiguousarray(yaws.T)
    c, s = np.cos(yaws), np.sin(yaws)
    lx, ly = offset[:, 0:1], offset[:, 1:2]
    centres = np.empty((n, frames, 3))
    centres[:, :, 0] = xs.T + (c * lx - s * ly)  # _box_offset's arithmetic
    centres[:, :, 1] = ys.T + (s * lx + c * ly)
    centres[:, :, 2] = (z + offset[:, 2])[:, None]
    return [BoxTrack(v.id, centres[k], yaws[k], extents[k]) for k, v in enumerate(vehicles)]


def _running_sum(start: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """(F + 1, n): ``start`` then ``start`` plus the first k rows of ``steps`` (F, n), added one row at a time."""
    out = np.empty((steps.shape[0] + 1,) + start.shape)
    out[0] = start
    out[1:] = steps
    return np.add.accumulate(out, axis=0, out=out)


def along_path(config: ExpertConfig, track: BoxTrack, vehicle: ActorState, path: np.ndarray) -> BoxTrack:
    """``track`` with ``vehicle`` driving ``path`` ((N, 2) x, y ahead of it) at its current speed instead of
    holding its control (a scenario's flow car: its agent follows that path at constant speed); extents kept.

    A vehicle more than 3 m off the path (pushed aside in a collision) keeps its kinematic forecast.
    """
    path = np.asarray(path, dtype=np.float64)[:, :2]
    if path.shape[0] < 2:
        return track
    ab = np.diff(path, axis=0)
    seg = np.hypot(ab[:, 0], ab[:, 1])
    if float(seg.sum()) < 1e-6:
        return track
    s = np.concatenate([[0.0], np.cumsum(seg)])
    here = np.array([vehicle.location.x, vehicle.location.y])
    t = np.clip(np.einsum("ij,ij->i", here - path[:-1], ab) / np.maximum(seg * seg, 1e-12), 0.0, 1.0)
    gap = np.hypot(*(path[:-1] + ab * t[:, None] - here).T)
    k = int(np.argmin(gap))
    if gap[k] > 3.0:
        return track
    frames = track.centres.shape[0]
    dist = s[k] + t[k] * seg[k] + vehicle.speed() * config.dt * np.arange(1, frames + 1)
    x, y = np.interp(dist, s, path[:, 0]), np.interp(dist, s, path[:, 1])
    index = np.clip(np.searchsorted(s, dist, side="right") - 1, 0, seg.size - 1)
    yaws = np.arctan2(ab[index, 1], ab[index, 0])
    centres = np.stack([x, y, np.full(frames, vehicle.location.z)], axis=1) + _box_offset(vehicle, yaws)
    return BoxTrack(track.actor_id, centres, yaws, track.extents)


def forecast_walkers(config: ExpertConfig, walkers: list[ActorState], frames: int) -> list[BoxTrack]:
    """Constant-velocity forecasts along each walker's control direction, speed ≥ 0.5 m/s, boxes ≥ 3 × 3 m."""
    tracks = []
    steps = np.arange(1, frames + 1)[:, None] * config.dt
    for walker in walkers:
        control = walker.control if isinstance(walker.control, WalkerControl) else WalkerControl()
        direction = np.array([control.direction.x, control.direction.y, control.direction.z])
        speed = max(walker.speed(), config.min_walker_speed)
        yaw = math.radians(walker.transform.rotation.yaw + walker.bounding_box.rotation.yaw)
        origin = np.array([walker.location.x, walker.location.y, walker.location.z])
        yaws = np.full(frames, yaw)
        centres = origin[None, :] + steps * direction[None, :] * speed + _box_offset(walker, yaws)
        e = walker.bounding_box.extent
        extent = np.array([max(e.x, config.walker_min_extent), max(e.y, config.walker_min_extent), e.z])
        tracks.append(BoxTrack(walker.id, centres, yaws, np.tile(extent, (frames, 1))))
    return tracks


def forecast_ego_boxes(config: ExpertConfig, ego: ActorState, route: DenseRoute, lateral: LateralPIDController,
                       longitudinal: LinearRegressionController | PIDLongitudinalController, target_speed: float,
                       frames: int, braking: bool = False) -> BoxTrack:
    """The ego driving the route at the *unreduced* target speed, assuming it does not brake (§1.6).

    Steering re-runs the lateral PID on the route at each forecast pose; the route index, the PID history and the
    longitudinal state are restored afterwards. ``braking`` forecasts a full brake from now on instead (where the
    ego would come to a stand).
    """
    route.save()
    lateral.save_state()
    longitudinal.save()
    try:
        x, y = ego.location.x, ego.location.y
        z = ego.location.z
        yaw = math.radians(ego.transform.rotation.yaw)
        speed = ego.speed()
        throttle = 0.0 if braking else longitudinal.get_throttle_extrapolation(target_speed, speed)
        steer = lateral.step(route.points[route.index :], speed, (x, y), yaw)
        poses = []
        for _ in range(frames):
            # positions as plain tuples: the loop runs 40-80 times per forecast, an array each time costs more
            # than the arithmetic it feeds
            x, y, yaw, speed = forecast_ego(config, x, y, yaw, speed, steer, throttle, braking)
            route.update_index((x, y))
            steer = lateral.step(route.points[route.index :], speed, (x, y), yaw)
            throttle = 0.0 if braking else longitudinal.get_throttle_extrapolation(target_speed, speed)
            poses.append((x, y, z, yaw))
        pose = np.array(poses, dtype=np.float64).reshape(frames, 4)
        centres, yaws = pose[:, :3], pose[:, 3].copy()
    finally:
        route.load()
        lateral.load_state()
        longitudinal.load()
    e = ego.bounding_box.extent
    # the ego's boxes grow with its *current* speed; standing still they keep the real size
    fast = ego.speed() >= config.ego_slow_speed
    fx, fy = (config.ego_extent_x_factor, config.ego_extent_y_factor) if fast else (1.0, 1.0)
    extents = np.tile(np.array([e.x * fx, e.y * fy, e.z]), (frames, 1))
    return BoxTrack(ego.id, centres + _box_offset(ego, yaws), yaws, extents)


def with_extents(track: BoxTrack, actor: ActorState, margin: float = 0.0) -> BoxTrack:
    """``track`` with the actor's real box (plus ``margin`` m on every horizontal side) at every frame."""
    e = actor.bounding_box.extent
    extents = np.tile(np.array([e.x + margin, e.y + margin, e.z]), (track.centres.shape[0], 1))
    return BoxTrack(track.actor_id, track.centres, track.yaws, extents)


def colliding(ego: BoxTrack, others: list[BoxTrack]) -> list[int]:
    """Ids of the actors whose forecast box overlaps the ego's box at the same frame, in the given order."""
    if not others:
        return []
    frames = min([ego.centres.shape[0]] + [t.centres.shape[0] for t in others])
    centres = np.stack([t.centres[:frames] for t in others])
    extents = np.stack([t.extents[:frames] for t in others])
    # Most actors never come near the ego's boxes: the separating-axis test (the expert's costliest numpy) runs
    # only for those whose footprint circle comes within CIRCLE_MARGIN of the ego's at some frame. The others
    # are separated by far more than rounding along one of their face normals, so the test would say no.
    near = np.flatnonzero(_circles_meet(ego.centres[:frames], ego.extents[:frames], centres, extents))
    if near.size == 0:
        return []
    count = near.size
    # every (actor, frame) pair in one vectorised separating-axis test; each pair's arithmetic does not depend on
    # the others in the batch, so leaving actors out does not change the answer for the rest
    yaws = np.stack([others[int(k)].yaws[:frames] for k in near])
    ego_c = np.broadcast_to(ego.centres[:frames], (count, frames, 3))
    ego_e = np.broadcast_to(ego.extents[:frames], (count, frames, 3))
    ego_axes = np.broadcast_to(yaw_axes(ego.yaws[:frames]), (count, frames, 3, 3))
    hit = overlap_many(ego_c, ego_axes, ego_e, centres[near], yaw_axes(yaws), extents[near]).any(axis=1)
    return [others[int(k)].actor_id for k, h in zip(near, hit) if h]


#: Footprint circles farther apart than this (m) never count as touching (see :func:`colliding`).
CIRCLE_MARGIN = 0.1


def _circles_meet(ego_centres: np.ndarray, ego_extents: np.ndarray, centres: np.ndarray,
                  extents: np.ndarray) -> np.ndarray:
    """Per actor (rows of ``centres`` (A, F, 3)): whether its footprint's circumcircle comes within
    :data:`CIRCLE_MARGIN` of the ego's at any frame (yaw-only boxes: circle radius = hypot of the half extents)."""
    gap = np.hypot(centres[:, :, 0] - ego_centres[None, :, 0], centres[:, :, 1] - ego_centres[None, :, 1])
    reach = (np.hypot(extents[:, :, 0], extents[:, :, 1]) + np.hypot(ego_extents[:, 0], ego_extents[:, 1])[None, :]
             + CIRCLE_MARGIN)
    return (gap <= reach).any(axis=1)


def _route_corridor(points: np.ndarray, headings: np.ndarray, vehicles: list[ActorState]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per vehicle: distance to the nearest sampled route point and |yaw − route heading| there (degrees)."""
    loc = np.array([[v.location.x, v.location.y] for v in vehicles])
    d = np.linalg.norm(loc[:, None, :] - points[None, :, :2], axis=2)
    nearest = d.argmin(axis=1)
    yaw = np.array([v.transform.rotation.yaw for v in vehicles])
    diff = np.abs((headings[nearest] - yaw + 180.0) % 360.0 - 180.0)
    return d.min(axis=1), diff


def leading_vehicle_ids(config: ExpertConfig, route: DenseRoute, vehicles: list[ActorState]) -> set[int]:
    """Vehicles within 2.5 m of the next 80 m of route (sampled every metre) and heading within 35° of it."""
    if not vehicles or route.index >= len(route):
        return set()
    end = route.index + config.points(config.leading_detection_length)
    step = config.points_per_meter
    points = route.points[route.index : end : step]
    headings = route.headings[route.index : end : step]
    dist, diff = _route_corridor(points, headings, vehicles)
    keep = (dist < config.leading_max_route_distance) & (diff < config.leading_max_yaw_difference)
    return {v.id for v, k in zip(vehicles, keep) if k}


def trailing_vehicle_ids(config: ExpertConfig, route: DenseRoute, vehicles: list[ActorState]) -> set[int]:
    """Vehicles within 3 m (6 m after a recent lane change) of the last 80 m of route, heading within 30°."""
    if not vehicles or route.index == 0:
        return set()
    max_dist = (config.trailing_max_route_distance_lane_change if route.lane_changed_recently()
                else config.trailing_max_route_distance)
    start = max(0, route.index - config.points(config.trailing_detection_length))
    step = config.points_per_meter
    points = route.points[start : route.index : step]
    headings = route.headings[start : route.index : step]
    if points.shape[0] == 0:
        return set()
    dist, diff = _route_corridor(points, headings, vehicles)
    keep = (dist < max_dist) & (diff < config.trailing_max_yaw_difference)
    return {v.id for v, k in zip(vehicles, keep) if k}
