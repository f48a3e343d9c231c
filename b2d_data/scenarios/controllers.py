"""Controllers for scenario actors (expert-and-scenarios.md §2.1 "Actor controllers", §5).

- :class:`ConstantVelocityAgent`: follows a path at a forced constant speed (CARLA's ConstantVelocityAgent:
  "infinite acceleration"); optionally brakes for vehicles in its path (the emergency vehicle, actor flows after
  their first collision), else ignores everything (actor flows until then, the red-light runner).
- :class:`LaneFollowingAgent`: follows its lane (with a lateral offset) at a target speed with bounded
  acceleration, braking for vehicles ahead in its path (BasicAgent: bicycles, opposite flows, the car beside
  a parked ego).
- :class:`WalkerController`: walks a pedestrian in a fixed direction at a fixed speed for a fixed distance.

Every controller talks to the world only through :class:`~b2d_data.sim.api.Simulator` methods. Vehicles get a
steer from pure pursuit on the path and their speed through ``set_target_velocity``; the control they report
matches what they do (throttle 0 while cruising, brake while slowing down), because the expert forecasts other
vehicles from their last control.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from b2d_data.format.transform import Location, Vector3D
from b2d_data.maps import Waypoint
from b2d_data.sim.api import FIXED_DELTA_SECONDS, ActorState, Simulator, Snapshot, VehicleControl, WalkerControl
from b2d_data.sim.blueprints import DEFAULT_GEOMETRY

log = logging.getLogger(__name__)

#: Spacing of controller paths (m).
PATH_STEP = 1.0
#: PDM-Lite's forecast of other vehicles: acceleration per unit of throttle (m/s²); reported throttle uses it.
FORECAST_THROTTLE_ACCEL = 0.56338


class PathTrack:
    """A 2-D polyline with arc length and heading, plus a monotone projection cursor."""

    def __init__(self, points: np.ndarray) -> None:
        pts = np.asarray(points, dtype=np.float64)[:, :3] if len(points) else np.zeros((0, 3))
        if pts.shape[0] >= 2:
            keep = np.concatenate([[True], np.hypot(*np.diff(pts[:, :2], axis=0).T) > 1e-6])
            pts = pts[keep]
        if pts.shape[0] < 2:
            raise ValueError("a path needs at least two distinct points")
        self.points = pts
        seg = np.hypot(*np.diff(pts[:, :2], axis=0).T)
        self.s = np.concatenate([[0.0], np.cumsum(seg)])
        d = np.diff(pts[:, :2], axis=0)
        yaw = np.arctan2(d[:, 1], d[:, 0])
        self.yaw = np.concatenate([yaw, yaw[-1:]])

    @classmethod
    def from_waypoints(cls, waypoints: Sequence[Waypoint], lateral_offset: float = 0.0) -> PathTrack:
        """The lane centres of ``waypoints``, shifted ``lateral_offset`` metres to the right of the lane."""
        rows = []
        for wp in waypoints:
            loc = wp.transform.location
            yaw = math.radians(wp.transform.rotation.yaw)
            # CARLA's right vector of a yaw (left-handed frame, y to the south): (-sin, cos)
            rows.append((loc.x - math.sin(yaw) * lateral_offset, loc.y + math.cos(yaw) * lateral_offset, loc.z))
        return cls(np.array(rows))

    @property
    def length(self) -> float:
        """Total arc length (m)."""
        return float(self.s[-1])

    def project(self, x: float, y: float, start: int = 0, window: int | None = None) -> tuple[int, float, float]:
        """(segment index, arc length, signed lateral offset, + to the right) of the closest point on the path."""
        n = len(self.s)
        lo = min(max(start, 0), n - 2)
        hi = n - 1 if window is None else min(n - 1, lo + window)
        a = self.points[lo:hi, :2]
        b = self.points[lo + 1 : hi + 1, :2]
        ab = b - a
        denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
        t = np.clip(np.einsum("ij,ij->i", np.array([x, y]) - a, ab) / denom, 0.0, 1.0)
        proj = a + ab * t[:, None]
        dist = np.hypot(proj[:, 0] - x, proj[:, 1] - y)
        k = int(np.argmin(dist))
        seg = lo + k
        s = float(self.s[seg] + t[k] * (self.s[seg + 1] - self.s[seg]))
        fx, fy = ab[k] / math.sqrt(denom[k])
        lateral = float((y - proj[k, 1]) * fx - (x - proj[k, 0]) * fy)  # right of the path is positive
        return seg, s, lateral

    def points_from(self, seg: int, length: float) -> np.ndarray:
        """The path's (x, y) points from segment ``seg``'s start over at least ``length`` metres (to its end)."""
        seg = min(max(seg, 0), len(self.s) - 2)
        end = int(np.searchsorted(self.s, self.s[seg] + length, side="left")) + 1
        return self.points[seg : max(end, seg + 2), :2].copy()

    def point_at(self, s: float) -> tuple[float, float, float]:
        """(x, y, yaw in radians) at arc length ``s`` (clamped to the path)."""
        s = min(max(s, 0.0), self.length)
        i = int(np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.s) - 2))
        t = (s - self.s[i]) / max(self.s[i + 1] - self.s[i], 1e-12)
        p = self.points[i, :2] + t * (self.points[i + 1, :2] - self.points[i, :2])
        return float(p[0]), float(p[1]), float(self.yaw[i])


def follow_lane(start: Waypoint, distance: float, step: float = PATH_STEP) -> list[Waypoint]:
    """Waypoints every ``step`` m along the lane from ``start``; at branches the straightest successor is taken."""
    out = [start]
    wp = start
    travelled = 0.0
    while travelled < distance:
        options = wp.next(step)
        if not options:
            break
        yaw = wp.transform.rotation.yaw
        wp = min(options, key=lambda o: abs((o.transform.rotation.yaw - yaw + 180.0) % 360.0 - 180.0))
        out.append(wp)
        travelled += step
    return out


def pure_pursuit_steer(actor: ActorState, track: PathTrack, s_now: float, lookahead: float) -> float:
    """Normalised steer that brings the actor onto the path point ``lookahead`` metres ahead (pure pursuit)."""
    tx, ty, _ = track.point_at(s_now + lookahead)
    loc = actor.location
    yaw = math.radians(actor.transform.rotation.yaw)
    dx, dy = tx - loc.x, ty - loc.y
    # target in the actor frame (x forward, y right)
    fx = math.cos(yaw) * dx + math.sin(yaw) * dy
    fy = -math.sin(yaw) * dx + math.cos(yaw) * dy
    dist2 = fx * fx + fy * fy
    if dist2 < 1e-6:
        return 0.0
    curvature = 2.0 * fy / dist2
    return DEFAULT_GEOMETRY.steer_for_curvature(curvature)


def _forward(actor: ActorState) -> tuple[float, float]:
    yaw = math.radians(actor.transform.rotation.yaw)
    return math.cos(yaw), math.sin(yaw)


def _corners(actor: ActorState) -> list[tuple[float, float]]:
    """The four horizontal corners of an actor's bounding box (world frame)."""
    box = actor.bounding_box
    yaw = math.radians(actor.transform.rotation.yaw)
    c, s = math.cos(yaw), math.sin(yaw)
    loc = actor.location
    cx = loc.x + c * box.location.x - s * box.location.y
    cy = loc.y + s * box.location.x + c * box.location.y
    ex, ey = box.extent.x, box.extent.y
    return [
        (cx + c * dx * ex - s * dy * ey, cy + s * dx * ex + c * dy * ey)
        for dx, dy in ((1, 1), (1, -1), (-1, 1), (-1, -1))
    ]


def leader_gap(
    snapshot: Snapshot,
    actor: ActorState,
    track: PathTrack,
    s_now: float,
    horizon: float,
    ignore: Iterable[int] = (),
    lateral_margin: float = 0.3,
    predict: float = 0.0,
) -> tuple[float, int | None]:
    """Gap (m) from the actor's front to the nearest vehicle whose box reaches into its path within ``horizon``.

    A vehicle counts when one of its box corners projects onto the path ahead within the actor's half width plus a
    margin, or when its box lies across the path (BasicAgent's bounding-box detection of its planned path); the gap
    is measured to its nearest corner ahead. With
    ``predict`` > 0 the corners are also tested where the vehicle will be after that many seconds at its current
    velocity, so that a vehicle about to cut into the path counts already.
    """
    skip = set(ignore) | {actor.id}
    loc = actor.location
    half_len = actor.bounding_box.extent.x
    corridor = actor.bounding_box.extent.y + lateral_margin
    best, best_id = math.inf, None
    start = int(np.clip(np.searchsorted(track.s, s_now) - 1, 0, len(track.s) - 2))
    stop = int(np.searchsorted(track.s, s_now + horizon + 10.0)) + 1
    for other in snapshot.vehicles():
        if other.id in skip or other.parent_id is not None:
            continue
        o = other.location
        if math.hypot(o.x - loc.x, o.y - loc.y) > horizon + 15.0:
            continue
        corners = _corners(other)
        if predict > 0.0 and other.speed() > 0.5:
            vx, vy = other.velocity.x * predict, other.velocity.y * predict
            corners += [(x + vx, y + vy) for x, y in corners]
        ahead = []
        for x, y in corners:
            _, s_other, lateral = track.project(x, y, start, stop - start)
            if s_other > s_now and s_other - s_now - half_len <= horizon:
                ahead.append((s_other, lateral))
        if not ahead:
            continue
        laterals = [lat for _, lat in ahead]
        # a corner inside the corridor, or a box lying across it (corners on both sides)
        if min(abs(lat) for lat in laterals) > corridor and not (min(laterals) < 0.0 < max(laterals)):
            continue
        gap = min(s for s, _ in ahead) - s_now - half_len
        if gap < best:
            best, best_id = gap, other.id
    return best, best_id


def allowed_speed(gap: float, comfort_decel: float, stop_gap: float) -> float:
    """The speed from which the vehicle can still stop ``stop_gap`` metres short of an obstacle ``gap`` m ahead."""
    return math.sqrt(2.0 * comfort_decel * max(gap - stop_gap, 0.0))


def speed_control(previous: float, allowed: float, accel: float, decel: float) -> tuple[float, VehicleControl]:
    """Next commanded speed toward ``allowed`` within the bounds, and the throttle/brake that describe it.

    The reported control follows PDM-Lite's forecast model of other vehicles (throttle 0 keeps the speed,
    throttle × 0.563 m/s² accelerates, any brake decelerates), so that the expert predicts what the vehicle does.
    """
    dt = FIXED_DELTA_SECONDS
    if allowed < previous:
        command = max(allowed, previous - decel * dt)
    else:
        command = min(allowed, previous + accel * dt)
    change = (command - previous) / dt
    throttle = min(1.0, change / FORECAST_THROTTLE_ACCEL) if change > 1e-3 else 0.0
    brake = min(1.0, -change / 8.0) if change < -1e-3 else 0.0
    if command <= 1e-3 and allowed <= 1e-3:
        brake = 1.0
    return command, VehicleControl(throttle=throttle, brake=brake)


class ConstantVelocityAgent:
    """Drives a vehicle along a path at ``speed`` m/s, velocity forced every tick (CARLA's ConstantVelocityAgent).

    The vehicle starts at full speed at once ("infinite acceleration"). With ``detect_vehicles`` it slows down for
    a vehicle in its path closer than ``base_threshold + speed_ratio × speed [km/h]`` metres (so as to stop 2 m
    short of it, or ``crossing_stop_gap`` m short of a vehicle crossing its path, braking up to ``max_brake`` ×
    8 m/s²) and, once the path is clear, speeds up again at ``resume_accel``. ``done`` becomes True at the end of
    the path (the vehicle then brakes and stays).

    ``match_leader`` gives CARLA 0.9.15's own hazard rule instead: a vehicle in the path within
    ``base_threshold + speed [m/s]`` metres makes the forced velocity jump to the leader's velocity along the
    actor's heading at once (``ConstantVelocityAgent.run_step`` sets ``hazard_speed`` as the constant velocity).

    ``stop_at_collision`` gives CARLA's collision sensor rule: at the actor's first collision the forced velocity is
    dropped for good (``stop_constant_velocity``; ``restart_time`` is infinite by default) and every later step
    applies an empty ``VehicleControl()``, so the vehicle coasts.
    """

    def __init__(
        self,
        sim: Simulator,
        actor_id: int,
        path: PathTrack,
        speed: float,
        detect_vehicles: bool = False,
        base_threshold: float = 10.0,
        speed_ratio: float = 0.15,
        max_brake: float = 0.5,
        ignore: Iterable[int] = (),
        predict: float = 0.0,
        resume_accel: float = 3.0,
        crossing_stop_gap: float = 2.0,
        lateral_margin: float = 0.3,
        match_leader: bool = False,
        stop_at_collision: bool = False,
    ) -> None:
        self.sim = sim
        self.match_leader = match_leader
        self.stop_at_collision = stop_at_collision
        self.collided = False
        self.crossing_stop_gap = crossing_stop_gap
        self.lateral_margin = lateral_margin
        self.predict = predict
        self.actor_id = actor_id
        self.path = path
        self.speed = float(speed)
        self.detect_vehicles = detect_vehicles
        self.base_threshold = base_threshold
        self.speed_ratio = speed_ratio
        self.max_brake = max_brake
        self.resume_accel = resume_accel
        self.ignore = set(ignore)
        self.done = False
        self.travelled = 0.0
        self.blocked_by: int | None = None
        self._seg = 0
        self._last: Location | None = None
        self._seen = False
        self._command: float | None = None

    def path_ahead(self, length: float) -> np.ndarray:
        """(x, y) of the path from the actor's segment (at its last projection) over ``length`` metres."""
        return self.path.points_from(self._seg, length)

    def progress(self, snapshot: Snapshot) -> float:
        """Arc length of the actor's projection on the path (0 when it is gone)."""
        actor = snapshot.actors.get(self.actor_id)
        if actor is None:
            return 0.0
        self._seg, s, _ = self.path.project(actor.location.x, actor.location.y, self._seg, 40)
        return s

    def run_step(self, snapshot: Snapshot) -> VehicleControl | None:
        """Compute and apply this tick's control; None when the actor no longer exists."""
        actor = snapshot.actors.get(self.actor_id)
        if actor is None:
            # spawned this tick (not in the snapshot yet) or destroyed since
            self.done = self.done or self._seen
            return None
        self._seen = True
        if self.stop_at_collision and not self.collided:
            self.collided = any(c.actor_id == self.actor_id for c in snapshot.collisions)
        if self.collided:
            control = VehicleControl()
            self.sim.apply_control(self.actor_id, control)
            return control
        s_now = self.progress(snapshot)
        loc = actor.location
        if self._last is not None:
            self.travelled += math.hypot(loc.x - self._last.x, loc.y - self._last.y)
        self._last = loc
        if s_now >= self.path.length - 0.5:
            self.done = True
        if self.done:
            control = VehicleControl(brake=1.0)
            self.sim.apply_control(self.actor_id, control)
            return control
        lookahead = max(3.0, min(12.0, 0.6 * max(self.speed, actor.speed())))
        steer = pure_pursuit_steer(actor, self.path, s_now, lookahead)
        allowed = self.speed
        self.blocked_by = None
        hazard_speed: float | None = None
        if self.detect_vehicles and self.match_leader:
            threshold = self.base_threshold + actor.speed()
            gap, other = leader_gap(
                snapshot, actor, self.path, s_now, threshold, self.ignore, self.lateral_margin, self.predict
            )
            if gap < threshold and other is not None:
                self.blocked_by = other
                fx, fy = _forward(actor)
                leader = snapshot.actors[other].velocity
                hazard_speed = max(0.0, fx * leader.x + fy * leader.y)
                allowed = min(allowed, hazard_speed)
        elif self.detect_vehicles:
            threshold = self.base_threshold + self.speed_ratio * max(actor.speed(), self.speed) * 3.6
            gap, other = leader_gap(
                snapshot, actor, self.path, s_now, threshold, self.ignore, self.lateral_margin, self.predict
            )
            if gap < threshold and other is not None:
                self.blocked_by = other
                heading = snapshot.actors[other].transform.rotation.yaw - actor.transform.rotation.yaw
                crossing = abs((heading + 180.0) % 360.0 - 180.0) > 45.0
                stop_gap = self.crossing_stop_gap if crossing else 2.0
                allowed = min(allowed, allowed_speed(gap, 0.5 * self.max_brake * 8.0, stop_gap))
        previous = self._command if self._command is not None else self.speed
        # CARLA's hazard rule has no deceleration bound: the constant velocity is simply reset to the leader's
        decel = math.inf if hazard_speed is not None else self.max_brake * 8.0
        command, control = speed_control(previous, allowed, self.resume_accel, decel)
        self._command = command
        control = VehicleControl(throttle=control.throttle, steer=steer, brake=control.brake)
        self.sim.apply_control(self.actor_id, control)
        fx, fy = _forward(actor)
        self.sim.set_target_velocity(self.actor_id, Vector3D(fx * command, fy * command, 0.0))
        return control


class LaneFollowingAgent:
    """A lane follower with a target speed (m/s) and lateral offset that brakes for vehicles ahead (BasicAgent).

    The path is the lane from ``start`` (straightest branch at forks), extended as the vehicle advances, or a fixed
    ``waypoints`` list. Speed follows the target with ``accel``/``decel`` bounds; a vehicle in the path closer than
    ``base_threshold + speed_ratio × speed [km/h]`` metres (now, or in ``predict`` s at its current velocity) makes
    it stop (a vehicle counts when its box comes within ``lateral_margin`` of the path's swept width).
    ``max_distance`` (m) ends the drive: the vehicle then stops with the hand brake (``done``).
    """

    def __init__(
        self,
        sim: Simulator,
        actor_id: int,
        start: Waypoint | Sequence[Waypoint],
        target_speed: float,
        lateral_offset: float = 0.0,
        max_distance: float | None = None,
        accel: float = 2.5,
        decel: float = 4.0,
        detect_vehicles: bool = True,
        base_threshold: float = 5.0,
        speed_ratio: float = 0.5,
        ignore: Iterable[int] = (),
        predict: float = 1.0,
        lateral_margin: float = 0.3,
    ) -> None:
        self.sim = sim
        self.actor_id = actor_id
        self.predict = predict
        self.lateral_margin = lateral_margin
        self.target_speed = float(target_speed)
        self.lateral_offset = float(lateral_offset)
        self.max_distance = max_distance
        self.accel = accel
        self.decel = decel
        self.detect_vehicles = detect_vehicles
        self.base_threshold = base_threshold
        self.speed_ratio = speed_ratio
        self.ignore = set(ignore)
        self._fixed = not isinstance(start, Waypoint)
        self._waypoints: list[Waypoint] = list(start) if self._fixed else follow_lane(start, 60.0)
        self.path = PathTrack.from_waypoints(self._waypoints, self.lateral_offset)
        self.done = False
        self.travelled = 0.0
        self._seg = 0
        self._last: Location | None = None
        self._seen = False
        self._speed_cmd: float | None = None

    def path_ahead(self, length: float) -> np.ndarray:
        """(x, y) of the path from the actor's segment (at its last projection) over ``length`` metres."""
        return self.path.points_from(self._seg, length)

    def _extend(self, s_now: float) -> None:
        if self._fixed or self.path.length - s_now > 40.0:
            return
        more = follow_lane(self._waypoints[-1], 60.0)[1:]
        if not more:
            self._fixed = True  # dead end: drive to it and stop
            return
        # keep 20 m behind the vehicle so that the projection stays cheap
        behind = max(0, int(s_now / PATH_STEP) - 20)
        self._waypoints = self._waypoints[behind:] + more
        self.path = PathTrack.from_waypoints(self._waypoints, self.lateral_offset)
        self._seg = 0

    def run_step(self, snapshot: Snapshot) -> VehicleControl | None:
        """Compute and apply this tick's control; None when the actor no longer exists."""
        actor = snapshot.actors.get(self.actor_id)
        if actor is None:
            self.done = self.done or self._seen
            return None
        self._seen = True
        self._seg, s_now, _ = self.path.project(actor.location.x, actor.location.y, self._seg, 40)
        self._extend(s_now)
        self._seg, s_now, _ = self.path.project(actor.location.x, actor.location.y, self._seg, 40)
        loc = actor.location
        if self._last is not None:
            self.travelled += math.hypot(loc.x - self._last.x, loc.y - self._last.y)
        self._last = loc
        if self.max_distance is not None and self.travelled >= self.max_distance:
            self.done = True
        if s_now >= self.path.length - 1.0:
            self.done = True
        if self.done:
            control = VehicleControl(brake=1.0, hand_brake=True)
            self.sim.apply_control(self.actor_id, control)
            return control
        v = max(0.0, actor.forward_speed())
        if self._speed_cmd is None:
            self._speed_cmd = v
        allowed = self.target_speed
        if self.detect_vehicles:
            threshold = self.base_threshold + self.speed_ratio * v * 3.6
            gap, _ = leader_gap(snapshot, actor, self.path, s_now, threshold, self.ignore, self.lateral_margin,
                                self.predict)
            if gap < threshold:
                allowed = min(allowed, allowed_speed(gap, self.decel, 2.0))
        self._speed_cmd, longitudinal = speed_control(self._speed_cmd, allowed, self.accel, 2.0 * self.decel)
        lookahead = max(2.5, min(10.0, 0.8 * max(v, 1.0) + 1.5))
        steer = pure_pursuit_steer(actor, self.path, s_now, lookahead)
        throttle, brake = longitudinal.throttle, longitudinal.brake
        control = VehicleControl(throttle=throttle, steer=steer, brake=brake)
        self.sim.apply_control(self.actor_id, control)
        fx, fy = _forward(actor)
        self.sim.set_target_velocity(self.actor_id, Vector3D(fx * self._speed_cmd, fy * self._speed_cmd, 0.0))
        return control


@dataclass
class WalkerController:
    """Walks a pedestrian along ``direction`` (world frame, normalised here) at ``speed`` m/s for ``distance`` m.

    The walk also ends after ``timeout`` s (default: 1.5 × the walking time + 2 s), so that a pedestrian blocked by
    a vehicle in its way does not stand in the road for good.
    """

    sim: Simulator
    actor_id: int
    direction: Vector3D
    speed: float
    distance: float
    timeout: float | None = None
    travelled: float = 0.0
    done: bool = False
    _last: Location | None = None
    _start: float | None = None

    def __post_init__(self) -> None:
        norm = math.hypot(self.direction.x, self.direction.y)
        if norm < 1e-9:
            raise ValueError("a walker needs a non-zero walking direction")
        self.direction = Vector3D(self.direction.x / norm, self.direction.y / norm, 0.0)
        if self.timeout is None:
            self.timeout = 1.5 * self.distance / max(self.speed, 0.1) + 2.0

    def run_step(self, snapshot: Snapshot) -> WalkerControl | None:
        """Apply this tick's walker control; stops (speed 0) once the distance is walked or the time is up.

        A walker not in the snapshot yet (spawned this tick) is just started; one that disappeared is done.
        """
        if self._start is None:
            self._start = snapshot.timestamp
        actor = snapshot.actors.get(self.actor_id)
        if actor is None:
            self.done = self.done or self._last is not None
            return None
        loc = actor.location
        if self._last is not None:
            self.travelled += math.hypot(loc.x - self._last.x, loc.y - self._last.y)
        self._last = loc
        timed_out = self.timeout is not None and snapshot.timestamp - self._start >= self.timeout
        if self.travelled >= self.distance or timed_out:
            self.done = True
        control = WalkerControl(direction=self.direction, speed=0.0 if self.done else self.speed)
        self.sim.apply_control(self.actor_id, control)
        return control


def park(sim: Simulator, actor_id: int) -> None:
    """Keep a vehicle in place with its hand brake pulled (parked and crashed cars)."""
    sim.apply_control(actor_id, VehicleControl(brake=1.0, hand_brake=True))
