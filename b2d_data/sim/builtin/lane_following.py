"""Lane-following driving logic: a Snapshot and the Map in, vehicle controls out.

Traffic-Manager-like behaviour for background traffic (expert-and-scenarios.md §3.1), usable by scenario
controllers too (it only needs :mod:`b2d_data.sim.api` types, the blueprint library and the map):

- :class:`LanePath` — lane-centre points 1 m apart ahead of a vehicle, extended lazily; at branches a
  seeded choice (or a caller's chooser) picks the successor. No lane changes.
- :func:`pure_pursuit_steer` — steer toward a look-ahead point, inverted through the kinematic bicycle of
  expert-and-scenarios.md §1.6 so that the commanded curvature is the one the simulator drives.
- :func:`idm_accel` — Intelligent Driver Model; :class:`IdmParams` holds TM-like constants (10 m gap).
- :class:`StopLines` — where red/yellow lights and stop signs stop a vehicle on its path.
- :class:`JunctionArbiter` — a deterministic first-come reservation of conflicting junction lanes, so that
  background vehicles never cross each other's path inside a junction at the same time.
- :class:`TrafficDriver` — puts these together for many vehicles per tick.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorKind, ActorState, Snapshot, TrafficLightState, VehicleControl
from b2d_data.sim.builtin.kinematic_bicycle import accel_for_many

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint

#: Spacing of path points (m).
PATH_STEP = 1.0
#: A path is extended to this many metres ahead when it gets shorter than 3/4 of it.
PATH_HORIZON = 60.0
#: Farther than this from its path a vehicle re-plans from the map (m).
REPLAN_DISTANCE = 3.0


# -- paths ------------------------------------------------------------------------------------------------


class LanePath:
    """Lane-centre waypoints ahead of a vehicle, 1 m apart (the first one is at or just behind it).

    The points are also kept as arrays (position with the lateral offset applied, yaw, lane width), updated
    incrementally as the path is extended and consumed.
    """

    def __init__(self, start: Waypoint, rng: np.random.Generator | None = None, lateral_offset: float = 0.0,
                 chooser: Callable[[Sequence[Waypoint]], int] | None = None) -> None:
        self.waypoints: list[Waypoint] = []
        self.lateral_offset = lateral_offset
        self._rng = rng
        self._chooser = chooser
        self._xy = np.zeros((0, 2))
        self._yaw = np.zeros(0)
        self._width = np.zeros(0)
        self.version = 0  # bumps whenever the point list changes
        self.dead_end = False
        self.stop_marks: dict[int, int] = {}  # stop-line owner id → index of its path point (StopLines.mark)
        self.marked_upto = 0
        self._junction_cache: tuple[int, Any] = (-1, None)
        self._append([start])

    @classmethod
    def from_waypoints(cls, waypoints: Sequence[Waypoint], lateral_offset: float = 0.0) -> LanePath:
        """A path along given waypoints (e.g. a route); it is not extended past their end."""
        path = cls(waypoints[0], lateral_offset=lateral_offset)
        path._append(list(waypoints[1:]))
        path.dead_end = True
        return path

    def _choose(self, options: Sequence[Waypoint]) -> Waypoint:
        if len(options) == 1:
            return options[0]
        if self._chooser is not None:
            return options[self._chooser(options)]
        if self._rng is not None:
            return options[int(self._rng.integers(len(options)))]
        return options[0]

    @property
    def length(self) -> float:
        """Arc length covered by the points (m)."""
        return (len(self.waypoints) - 1) * PATH_STEP

    def extend(self, horizon: float = PATH_HORIZON) -> None:
        """Append successors until the path is ``horizon`` m long (or the lane network ends)."""
        if self.length >= 0.75 * horizon or self.dead_end:
            return
        new: list[Waypoint] = []
        last = self.waypoints[-1]
        while self.length + len(new) * PATH_STEP < horizon:
            options = last.next(PATH_STEP)
            if not options:
                self.dead_end = True
                break
            last = self._choose(options)
            new.append(last)
        self._append(new)

    def _append(self, wps: list[Waypoint]) -> None:
        if not wps:
            return
        n = len(wps)
        xy, yaw, width = np.empty((n, 2)), np.empty(n), np.empty(n)
        for i, wp in enumerate(wps):
            t = wp.transform
            xy[i] = (t.location.x, t.location.y)
            yaw[i] = math.radians(t.rotation.yaw)
            width[i] = wp.lane_width
        if self.lateral_offset:
            xy[:, 0] -= np.sin(yaw) * self.lateral_offset
            xy[:, 1] += np.cos(yaw) * self.lateral_offset
        self.waypoints.extend(wps)
        self._xy = np.concatenate([self._xy, xy])
        self._yaw = np.concatenate([self._yaw, yaw])
        self._width = np.concatenate([self._width, width])
        self.version += 1

    def advance(self, x: float, y: float) -> float:
        """Drop points the vehicle at (x, y) has passed; returns its distance to the path."""
        xy = self._xy
        window = min(len(xy), 12)
        d = np.hypot(xy[:window, 0] - x, xy[:window, 1] - y)
        k = int(np.argmin(d))
        if k + 1 < len(xy):
            t = xy[k + 1] - xy[k]
            # keep the point just behind the vehicle
            k_keep = k if (x - xy[k, 0]) * t[0] + (y - xy[k, 1]) * t[1] > 0.0 else max(0, k - 1)
        else:
            k_keep = k
        if k_keep > 0:
            del self.waypoints[:k_keep]
            self._xy, self._yaw, self._width = self._xy[k_keep:], self._yaw[k_keep:], self._width[k_keep:]
            self.stop_marks = {sid: i - k_keep for sid, i in self.stop_marks.items() if i - k_keep >= 0}
            self.marked_upto = max(0, self.marked_upto - k_keep)
            self.version += 1
        return float(d[k])

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(xy (K, 2) with the lateral offset applied, yaw in rad (K,), arc length (K,), lane width (K,))."""
        return self._xy, self._yaw, _arc_lengths(len(self._xy)), self._width

    def first_junction(self) -> tuple[int, int, int, tuple[tuple[int, int, int], ...]] | None:
        """(junction id, entry index, exit index, lane keys) of the first junction on the path, if any.

        ``entry`` is the first point inside the junction, ``exit`` the first point after it (or the path end).
        """
        if self._junction_cache[0] == self.version:
            return self._junction_cache[1]
        found = None
        entry = None
        for i, wp in enumerate(self.waypoints):
            if wp.is_junction and entry is None:
                entry = i
            elif entry is not None and not wp.is_junction:
                found = self._junction_record(entry, i)
                break
        if found is None and entry is not None:
            found = self._junction_record(entry, len(self.waypoints))
        self._junction_cache = (self.version, found)
        return found

    def _junction_record(self, entry: int, exit_: int) -> tuple[int, int, int, tuple[tuple[int, int, int], ...]]:
        keys: list[tuple[int, int, int]] = []
        for wp in self.waypoints[entry:exit_]:
            key = (wp.road_id, wp.section_id, wp.lane_id)
            if not keys or keys[-1] != key:
                keys.append(key)
        return self.waypoints[entry].junction_id, entry, exit_, tuple(keys)


def _arc_lengths(count: int) -> np.ndarray:
    """0, 1, ... ``count`` − 1 path steps (m); read-only, shared by every path of that many points."""
    arc = _ARCS.get(count)
    if arc is None:
        arc = np.arange(count) * PATH_STEP
        arc.flags.writeable = False
        arc = _ARCS.setdefault(count, arc)
    return arc


#: :func:`_arc_lengths` by point count (paths hold at most ~60 points, so this stays small).
_ARCS: dict[int, np.ndarray] = {}


# -- steering and speed -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class IdmParams:
    """Intelligent Driver Model constants (TM-like: a 10 m standstill gap to the leader)."""

    max_accel: float = 2.5  # a (m/s²)
    comfort_decel: float = 3.0  # b (m/s²)
    min_gap: float = 10.0  # s0 (m), bumper to bumper
    headway: float = 1.0  # T (s)
    delta: float = 4.0
    stop_line_gap: float = 1.0  # s0 toward stop lines (m)
    max_decel: float = 8.0  # hardest braking the model asks for (m/s²)
    lateral_accel: float = 2.5  # bends are taken at sqrt(lateral_accel / curvature) at most (m/s²)


def idm_accel(v: float, v0: float, gap: float | None, v_lead: float, p: IdmParams, s0: float | None = None) -> float:
    """IDM acceleration (m/s²) at speed v toward desired speed v0, behind a leader ``gap`` m ahead (None: free)."""
    if v0 <= 0.05:
        return -min(4.0, p.max_decel)
    free = 1.0 - (max(v, 0.0) / v0) ** p.delta
    if gap is None:
        return max(-p.max_decel, p.max_accel * free)
    s0 = p.min_gap if s0 is None else s0
    s_star = s0 + max(0.0, v * p.headway + v * (v - v_lead) / (2.0 * math.sqrt(p.max_accel * p.comfort_decel)))
    s = max(gap, 0.1)
    return max(-p.max_decel, p.max_accel * (free - (s_star / s) ** 2))


def lookahead_distance(speed: float) -> float:
    """Pure-pursuit look-ahead (m): short enough that bends are not cut by more than a few decimetres."""
    return min(8.0, max(3.0, 2.0 + 0.3 * abs(speed)))


def pure_pursuit_steer(x: float, y: float, yaw_rad: float, speed: float, path_xy: np.ndarray,
                       geometry: blueprints.BicycleGeometry, lookahead: float | None = None) -> float:
    """Normalised steer that drives the actor origin onto the path, through the bicycle model's curvature."""
    if len(path_xy) < 2:
        return 0.0
    ld = lookahead if lookahead is not None else lookahead_distance(speed)
    d = np.hypot(path_xy[:, 0] - x, path_xy[:, 1] - y)
    ahead = np.nonzero(d >= ld)[0]
    k = int(ahead[0]) if ahead.size else len(path_xy) - 1
    dx, dy = path_xy[k, 0] - x, path_xy[k, 1] - y
    dist = math.hypot(dx, dy)
    if dist < 1e-3:
        return 0.0
    alpha = math.atan2(dy, dx) - yaw_rad
    alpha = math.atan2(math.sin(alpha), math.cos(alpha))
    curvature = 2.0 * math.sin(alpha) / dist
    if speed < 0.0:
        curvature = -curvature
    return geometry.steer_for_curvature(curvature)


def speed_control(actor: ActorState, accel: float, hold_when_stopped: bool = True,
                  speed: float | None = None) -> tuple[float, float]:
    """(throttle, brake) giving ``accel`` at the actor's speed through its blueprint's longitudinal model."""
    return speed_controls([actor], [accel], [actor.forward_speed() if speed is None else speed], hold_when_stopped)[0]


def speed_controls(actors: Sequence[ActorState], accels: Sequence[float], speeds: Sequence[float],
                   hold_when_stopped: bool = True) -> list[tuple[float, float]]:
    """:func:`speed_control` of many actors at their given speeds (the longitudinal models solved together)."""
    out: list[tuple[float, float] | None] = []
    todo: list[int] = []
    for k, (actor, accel, speed) in enumerate(zip(actors, accels, speeds)):
        v = max(0.0, speed)
        if hold_when_stopped and v < 0.05 and accel <= 0.0:
            out.append((0.0, 1.0))  # standing still: keep the brake on, as TM does
        else:
            out.append(None)
            todo.append(k)
    if todo:
        solved = accel_for_many([_dynamics(actors[k].type_id) for k in todo], [max(0.0, speeds[k]) for k in todo],
                                [accels[k] for k in todo])
        for k, control in zip(todo, solved):
            out[k] = control
    return out  # type: ignore[return-value]  # every None was replaced


def _dynamics(type_id: str) -> blueprints.LongitudinalModel:
    """The longitudinal model of a blueprint (a car's for unknown ones)."""
    blueprint = blueprints.BLUEPRINTS.get(type_id)
    return blueprint.dynamics if blueprint is not None and blueprint.dynamics is not None else blueprints.CAR_DYNAMICS


# -- stop lines -------------------------------------------------------------------------------------------

#: A path point marks a stop line when it lies this close to the stop waypoint (paths are sampled every 1 m)
#: and heads within this angle of it (so the opposite lane's line is never taken).
_MARK_RADIUS = 1.05
_MARK_YAW = math.radians(45.0)


@dataclass(frozen=True)
class StopLine:
    """A stop line on one lane: position, lane yaw (rad), the light or sign actor that owns it."""

    owner_id: int
    is_light: bool
    x: float
    y: float
    yaw: float
    key: tuple[int, int]  # (road_id, lane_id)
    ahead: float = 0.0  # the stop line lies this far past the waypoint (front edge of the trigger box)


class StopLines:
    """Every light's and stop sign's stop line, indexed by lane, to mark them on paths.

    A light's or sign's stop waypoints sit at the centre of its trigger box (CARLA's ``get_stop_waypoints``);
    the line a vehicle stops at is the box's front edge, half the box length further on.
    """

    def __init__(self, snapshot: Snapshot, town: Map) -> None:
        lines: list[StopLine] = []
        for light_id, info in snapshot.traffic_lights.items():
            for wp in info.stop_waypoints:
                lines.append(_stop_line(light_id, True, wp, info.trigger_volume.extent.x))
        signs = {info.opendrive_id: (sign_id, info) for sign_id, info in snapshot.traffic_signs.items()
                 if info.type_id.startswith("traffic.stop")}
        for signal in town.stop_signs():
            found = signs.get(str(signal.id))
            if found is None:
                continue
            for wp in signal.stop_waypoints:
                lines.append(_stop_line(found[0], False, wp, found[1].trigger_volume.extent.x))
        self.lines = lines
        self.ahead = {line.owner_id: line.ahead for line in lines}
        self._by_key: dict[tuple[int, int], list[StopLine]] = {}
        for line in lines:
            self._by_key.setdefault(line.key, []).append(line)

    def mark(self, path: LanePath) -> None:
        """Record on ``path`` the index of each stop line it crosses (only points not checked yet)."""
        wps = path.waypoints
        for i in range(path.marked_upto, len(wps)):
            wp = wps[i]
            for line in self._by_key.get((wp.road_id, wp.lane_id), ()):
                if line.owner_id in path.stop_marks:
                    continue
                loc = wp.transform.location
                if math.hypot(loc.x - line.x, loc.y - line.y) <= _MARK_RADIUS:
                    dyaw = math.radians(wp.transform.rotation.yaw) - line.yaw
                    if abs(math.atan2(math.sin(dyaw), math.cos(dyaw))) < _MARK_YAW:
                        path.stop_marks[line.owner_id] = i
        path.marked_upto = len(wps)


def _stop_line(owner_id: int, is_light: bool, wp: Any, ahead: float) -> StopLine:
    t = wp.transform
    return StopLine(owner_id, is_light, t.location.x, t.location.y, math.radians(t.rotation.yaw),
                    (wp.road_id, wp.lane_id), ahead)


# -- junction reservations --------------------------------------------------------------------------------

LaneKey = tuple[int, int, int]
#: A leader heading within 45° of the path counts as driving along it (a queue), not across it.
_ALONG_COS = math.cos(math.radians(45.0))
#: Two junction lanes conflict when their centre lines come this close (m): a wide car (2.2 m) plus what two
#: vehicles may stray from their centre lines in a turn.
CONFLICT_DISTANCE = 3.0
#: The lane key of a vehicle whose way through a junction is unknown: it conflicts with every lane.
ANY_LANE: LaneKey = (-1, -1, -1)


class JunctionArbiter:
    """First-come reservations of junction lanes: a vehicle enters only if no conflicting lane is held.

    Lanes leaving from the same entry lane never conflict (their vehicles queue and IDM keeps them apart);
    any other pair whose centre lines come within :data:`CONFLICT_DISTANCE` does, and so does a lane whose
    centre line is unknown (e.g. :data:`ANY_LANE`, held by vehicles whose path nobody knows). Vehicles already
    inside a junction always hold their lanes. Requests are served in the order of the tick a vehicle first
    asked (then by id), and none overtakes an earlier one it conflicts with.
    """

    def __init__(self) -> None:
        self._polylines: dict[LaneKey, np.ndarray] = {}
        self._entry_of: dict[LaneKey, tuple[int, int, int] | None] = {}
        self._conflicts: dict[tuple[LaneKey, LaneKey], bool] = {}
        self.holders: dict[int, tuple[int, tuple[LaneKey, ...]]] = {}
        self._asked: dict[int, int] = {}

    def learn(self, path: LanePath) -> None:
        """Remember the whole centre lines (from the map) of the junction lanes on a path's next junction, and
        the lane each one is entered from (for the conflict test)."""
        record = path.first_junction()
        if record is not None:
            self.learn_lanes(path.waypoints[record[1]:record[2]])

    def learn_lanes(self, waypoints: Sequence[Waypoint]) -> None:
        """Remember the whole centre lines (from the map) of the junction lanes these waypoints lie on."""
        for wp in waypoints:
            if not wp.is_junction:
                continue
            key = (wp.road_id, wp.section_id, wp.lane_id)
            if key in self._polylines:
                continue
            # the whole lane, not the part a path covers: a path ends 60 m ahead, so the lanes of a long
            # junction would otherwise stay unknown and conflict with every other lane for good
            self._polylines[key], before = _whole_lane(wp, key)
            if before is not None:
                self._entry_of.setdefault(key, before)

    def conflict(self, a: LaneKey, b: LaneKey) -> bool:
        """Do two junction lanes cross or merge (unknown centre lines count as conflicting)?"""
        if a == b:
            return False
        pair = (a, b) if a <= b else (b, a)
        cached = self._conflicts.get(pair)
        if cached is not None:
            return cached
        ea, eb = self._entry_of.get(a), self._entry_of.get(b)
        if ea is not None and ea == eb:
            result = False
        else:
            pa, pb = self._polylines.get(a), self._polylines.get(b)
            if pa is None or pb is None:
                return True  # not cached: may become known later
            d = np.hypot(pa[:, None, 0] - pb[None, :, 0], pa[:, None, 1] - pb[None, :, 1])
            result = bool(d.min() < CONFLICT_DISTANCE)
        self._conflicts[pair] = result
        return result

    def update(self, tick: int, inside: Mapping[int, tuple[int, tuple[LaneKey, ...]]],
               requests: Mapping[int, tuple[int, tuple[LaneKey, ...]]],
               managed: Collection[int] | None = None) -> set[int]:
        """Refresh holders and answer requests; returns the ids allowed into their junction.

        ``inside``: vehicles in a junction now (they hold their lanes); ``requests``: vehicles that want to
        enter, with (junction id, lane keys). Both keyed by actor id. ``managed``: the ids this call speaks for
        (default: all); holders outside it are kept, so several drivers can share one arbiter.
        """
        mine = None if managed is None else set(managed) | set(inside) | set(requests)
        kept: dict[int, tuple[int, tuple[LaneKey, ...]]] = {}
        for vid, rec in self.holders.items():
            if vid in requests:
                if requests[vid] == rec:  # still asking for the same lanes: keeps its grant
                    kept[vid] = rec
            elif mine is not None and vid not in mine and vid not in inside:
                kept[vid] = rec  # another driver's vehicle
        kept.update(inside)
        self.holders = kept
        for vid in list(self._asked):
            if vid not in requests and (mine is None or vid in mine):
                del self._asked[vid]
        for vid in requests:
            self._asked.setdefault(vid, tick)
        granted = {vid for vid in requests if vid in self.holders}
        waiting: list[tuple[int, tuple[LaneKey, ...]]] = []
        for vid in sorted(requests, key=lambda v: (self._asked[v], v)):
            if vid in granted:
                continue
            junction, keys = requests[vid]
            blocked = any(
                other_junction == junction and any(self.conflict(k, o) for k in keys for o in other_keys)
                for other, (other_junction, other_keys) in self.holders.items() if other != vid
            )
            # first come, first served: no overtaking an earlier request that waits for a conflicting lane, or
            # a steady stream from one entry (whose lanes never conflict with each other) would starve the
            # crossing entries for good
            blocked = blocked or any(
                other_junction == junction and any(self.conflict(k, o) for k in keys for o in other_keys)
                for other_junction, other_keys in waiting
            )
            if blocked:
                waiting.append((junction, keys))
            else:
                self.holders[vid] = (junction, keys)
                granted.add(vid)
        return granted


def _whole_lane(wp: Waypoint, key: LaneKey) -> tuple[np.ndarray, LaneKey | None]:
    """Centre line (K, 2) of the lane ``key`` through ``wp``, and the non-junction lane it is entered from."""
    back = [w for w in wp.previous_until_lane_start(PATH_STEP) if (w.road_id, w.section_id, w.lane_id) == key]
    ahead = [w for w in wp.next_until_lane_end(PATH_STEP) if (w.road_id, w.section_id, w.lane_id) == key]
    lane = back[::-1] + [wp] + ahead
    pts = np.array([(w.transform.location.x, w.transform.location.y) for w in lane])
    before = lane[0].previous(PATH_STEP)
    entry = None
    if len(before) == 1 and not before[0].is_junction:
        entry = (before[0].road_id, before[0].section_id, before[0].lane_id)
    return pts, entry


@dataclass(frozen=True)
class _JunctionAhead:
    junction_id: int
    entry: int
    exit: int
    keys: tuple[LaneKey, ...]
    wants: bool  # close enough and free to go: asks the arbiter
    distance: float  # bumper to junction entry (m)


# -- the driver -------------------------------------------------------------------------------------------


@dataclass
class DrivingAgent:
    """What the driver needs to know about one vehicle it drives."""

    id: int
    path: LanePath
    target_speed: float  # m/s (after caps); 0 stops the vehicle
    ignore_signals: bool = False
    ignore_vehicles: bool = False
    stop_before_junction: bool = False  # wait at the next junction entry (scenario "stop entries")
    cleared_stops: set[int] = field(default_factory=set)
    waiting_since: int | None = None


@dataclass
class DriverOutput:
    """A control plus why the vehicle slows (for debugging and tests)."""

    control: VehicleControl
    accel: float
    reason: str
    leader_id: int | None = None  # the actor ahead on the path, if any


class TrafficDriver:
    """IDM car-following and pure-pursuit lane keeping for many vehicles; Snapshot + Map in, controls out.

    The geometric work (finding each vehicle's leader on its path, the pure-pursuit aim point) is done for all
    vehicles at once with numpy; only the few per-vehicle decisions (lights, signs, junctions) are Python.
    """

    #: Points of each path looked at for leaders, bends and steering (m ahead, at 1 m spacing): enough to
    #: stop from 90 km/h at the comfortable deceleration with the 10 m gap.
    LOOK_AHEAD_POINTS = 50

    def __init__(self, town: Map, idm: IdmParams = IdmParams(), obstacle_margin: float = 0.3,
                 arbiter: JunctionArbiter | None = None) -> None:
        self.map = town
        self.idm = idm
        self.margin = obstacle_margin
        # share one arbiter between drivers (e.g. scenario vehicles and background traffic) to coordinate them
        self.arbiter = arbiter if arbiter is not None else JunctionArbiter()
        self._stop_lines: StopLines | None = None
        self._learned: dict[int, int] = {}
        self._spoken_for: set[int] = set()  # agents and extra holders of the last call

    def stop_lines(self, snapshot: Snapshot) -> StopLines:
        """The stop-line index (built from the first snapshot: lights and signs never move)."""
        if self._stop_lines is None:
            self._stop_lines = StopLines(snapshot, self.map)
        return self._stop_lines

    def plan(self, snapshot: Snapshot, agents: Sequence[DrivingAgent],
             extra_inside: Mapping[int, tuple[int, tuple[LaneKey, ...]]] | None = None) -> dict[int, DriverOutput]:
        """Controls for every agent at this snapshot (agents missing from the snapshot are skipped)."""
        stops = self.stop_lines(snapshot)
        live = [a for a in agents if a.id in snapshot.actors]
        # this call also speaks for the agents and extra holders of the last call: a vehicle destroyed while
        # holding junction lanes, or an extra holder (the ego) that has left its junction, must lose its hold,
        # or it would block those lanes for good
        now = {a.id for a in agents} | set(extra_inside or {})
        managed = sorted(now | self._spoken_for)
        self._spoken_for = now
        if not live:
            self.arbiter.update(snapshot.frame, dict(extra_inside or {}), {}, managed=managed)
            return {}
        for agent in live:
            agent.path.extend()
            stops.mark(agent.path)
            if self._learned.get(agent.id) != agent.path.version:
                self.arbiter.learn(agent.path)
                self._learned[agent.id] = agent.path.version
        actors = [snapshot.actors[a.id] for a in live]
        batch = _Batch(actors, live, self.LOOK_AHEAD_POINTS)
        gaps, v_leads, leader_ids, lead_cos = _ObstacleTable(snapshot).leaders(batch, self.margin)
        steers = batch.pure_pursuit()
        bend_speeds = batch.curve_speed(self.idm.lateral_accel, self.idm.comfort_decel)
        inside: dict[int, tuple[int, tuple[LaneKey, ...]]] = dict(extra_inside or {})
        requests: dict[int, tuple[int, tuple[LaneKey, ...]]] = {}
        decided: list[tuple[float, str, _JunctionAhead | None]] = []
        for i, (agent, actor) in enumerate(zip(live, actors)):
            gap = None if agent.ignore_vehicles or not np.isfinite(gaps[i]) else float(gaps[i])
            accel, reason, junction = self._longitudinal(snapshot, actor, agent, stops, float(batch.s_self[i]),
                                                         gap, float(v_leads[i]), float(batch.speed[i]),
                                                         float(bend_speeds[i]), bool(lead_cos[i] > _ALONG_COS))
            decided.append((accel, reason, junction))
            if junction is not None:
                if junction.entry == 0 and agent.path.waypoints[0].is_junction:
                    inside[agent.id] = (junction.junction_id, junction.keys)
                elif junction.wants:
                    requests[agent.id] = (junction.junction_id, junction.keys)
        granted = self.arbiter.update(snapshot.frame, inside, requests, managed=managed)
        final: list[tuple[float, str]] = []
        for i, agent in enumerate(live):
            accel, reason, junction = decided[i]
            if junction is not None and agent.id in requests and agent.id not in granted:
                wait = idm_accel(max(0.0, float(batch.speed[i])), max(agent.target_speed, 0.1), junction.distance,
                                 0.0, self.idm, s0=self.idm.stop_line_gap)
                if wait < accel:
                    accel, reason = wait, "junction"
            final.append((accel, reason))
        pedals = speed_controls(actors, [a for a, _ in final], batch.speed.tolist())
        out: dict[int, DriverOutput] = {}
        for i, agent in enumerate(live):
            (accel, reason), (throttle, brake) = final[i], pedals[i]
            control = VehicleControl(throttle=round(throttle, 4), steer=round(float(steers[i]), 4),
                                     brake=round(brake, 4))
            leader = int(leader_ids[i]) if leader_ids[i] >= 0 else None
            out[agent.id] = DriverOutput(control, accel, reason, leader)
        return out

    # -- internals ------------------------------------------------------------------------------------------
    def _longitudinal(self, snapshot: Snapshot, actor: ActorState, agent: DrivingAgent, stops: StopLines,
                      s_self: float, gap: float | None, v_lead: float, speed: float,
                      bend_speed: float = math.inf,
                      lead_along: bool = True) -> tuple[float, str, _JunctionAhead | None]:
        v = max(0.0, speed)
        p = self.idm
        _, _, arc, width = agent.path.arrays()
        half_len = actor.bounding_box.extent.x
        v0 = agent.target_speed
        if 0.05 < bend_speed < v0:
            v0 = bend_speed  # slow down for bends (TM does too); a target of 0 stays an order to stop
        narrow = bool(width.size and width[0] < 2.25)
        if narrow:
            v0 = 0.0  # lanes narrower than 2.25 m: background vehicles stand still (LB2.0)
        if v0 <= 0.05:
            accel, reason = idm_accel(v, 0.0, None, 0.0, p), "stopped"
        else:
            accel, reason = idm_accel(v, v0, None, 0.0, p), "free"
        if gap is not None:
            a = idm_accel(v, max(v0, 0.1), gap, v_lead, p)
            if a < accel:
                accel, reason = a, "leader"
        record = agent.path.first_junction()
        # lights and stop signs on the path
        if not agent.ignore_signals:
            for owner, idx in sorted(agent.path.stop_marks.items(), key=lambda kv: kv[1]):
                line = float(arc[idx] + stops.ahead.get(owner, 0.0))
                if record is not None and idx < record[2]:  # it guards the next junction
                    if record[1] > 0:
                        # stop at its entry at the latest: some maps put stop lines inside the junction (e.g. the
                        # stop signs of Town07), where a waiting car would stand across the other entries' lanes
                        # and, not having asked for its own, drive in unreserved
                        line = min(line, float(arc[record[1]]))
                    elif agent.path.waypoints[0].is_junction:
                        continue  # already in it: committed, like TM once past the trigger volume
                dist = line - s_self - half_len
                if dist < -half_len:
                    continue  # already across
                must_stop = False
                info = snapshot.traffic_lights.get(owner)
                if info is not None:
                    if info.state is TrafficLightState.RED:
                        must_stop = dist > -0.5
                    elif info.state is TrafficLightState.YELLOW:
                        must_stop = dist > v * v / (2.0 * 4.0)  # stop only if it can, comfortably
                elif owner in snapshot.traffic_signs and owner not in agent.cleared_stops:
                    if v < 0.1 and dist < 3.0:
                        agent.cleared_stops.add(owner)
                    else:
                        must_stop = dist > -0.5
                if must_stop:
                    a = idm_accel(v, max(v0, 0.1), max(dist, 0.0), 0.0, p, s0=p.stop_line_gap)
                    if a < accel:
                        accel, reason = a, "light" if info is not None else "stop_sign"
                    break
        if v0 <= 0.05:
            # ordered to stand still, whatever else is in the way; on a lane that has narrowed (the taper at the end
            # of an acceleration lane) for good
            reason = "narrow_lane" if narrow else "stopped"
        # the next junction: ask for it when close and free to go, or wait at its entry
        junction = None
        if record is not None:
            jid, entry, exit_, keys = record
            dist_entry = float(arc[entry] - s_self) - half_len if entry < len(arc) else math.inf
            close = dist_entry < max(12.0, v * v / (2.0 * p.comfort_decel) + 8.0)
            blocked_by_signal = reason in ("light", "stop_sign", "stopped", "narrow_lane")
            # don't block the box: enter only if the car can stop behind a slow leader past the junction exit;
            # otherwise wait at the entry (merely not asking the arbiter would let it roll in unreserved and
            # stand across the junction, where it can close a gridlock loop through the lanes it blocks). A car
            # crossing the path is no queue on the exit: the arbiter keeps apart vehicles that cross
            room = True
            if gap is not None and exit_ < len(arc) and v_lead < 2.0 and lead_along:
                dist_exit = float(arc[exit_] - s_self) - half_len
                room = gap - p.min_gap >= dist_exit + 2.0 * half_len
            # a car that can no longer stop comfortably before the entry goes on (with its reservation)
            can_stop = dist_entry > v * v / (2.0 * p.comfort_decel)
            exit_blocked = not room and entry > 0 and can_stop
            wants = close and not exit_blocked and not blocked_by_signal and not agent.stop_before_junction
            junction = _JunctionAhead(jid, entry, exit_, keys, wants, max(dist_entry, 0.0))
            if close and exit_blocked:
                a = idm_accel(v, max(v0, 0.1), max(dist_entry, 0.0), 0.0, p, s0=p.stop_line_gap)
                if a < accel:
                    accel, reason = a, "exit_blocked"
            if agent.stop_before_junction and entry > 0:
                a = idm_accel(v, max(v0, 0.1), max(dist_entry, 0.0), 0.0, p, s0=p.stop_line_gap)
                if a < accel:
                    accel, reason = a, "junction_stopped"
        return accel, reason, junction


class _Batch:
    """The driven vehicles and the first points of their paths as padded arrays."""

    FAR = 1.0e7

    def __init__(self, actors: Sequence[ActorState], agents: Sequence[DrivingAgent], points: int) -> None:
        n = len(actors)
        h = max(2, min(points, max(len(a.path.waypoints) for a in agents)))
        self.ids = np.array([a.id for a in actors], dtype=np.int64)
        self.xy = np.full((n, h, 2), self.FAR)
        self.path_yaw = np.zeros((n, h))
        # per-vehicle scalars gathered as Python floats and turned into arrays once (a row write into an array
        # costs about as much as the arithmetic)
        pos, yaws, speeds, half, geometry, counts, s_self = [], [], [], [], [], [], []
        for i, (actor, agent) in enumerate(zip(actors, agents)):
            t = actor.transform
            x, y = t.location.x, t.location.y
            yaw = math.radians(t.rotation.yaw)
            v = actor.velocity
            pos.append((x, y))
            yaws.append(yaw)
            speeds.append(v.x * math.cos(yaw) + v.y * math.sin(yaw))  # pitch ignored: small
            half.append((actor.bounding_box.extent.x, actor.bounding_box.extent.y))
            g = _geometry(actor.type_id)
            geometry.append((g.rear_length, g.front_length, g.steer_to_wheel))
            xy, path_yaw, _, _ = agent.path.arrays()
            k = min(h, len(xy))
            counts.append(k)
            self.xy[i, :k] = xy[:k]
            self.path_yaw[i, :k] = path_yaw[:k]
            along = 0.0
            if k >= 2:
                (x0, y0), (x1, y1) = xy[:2].tolist()
                tx, ty = x1 - x0, y1 - y0
                n0 = math.hypot(tx, ty) or 1.0
                along = ((x - x0) * tx + (y - y0) * ty) / n0
            s_self.append(along)
        self.pos = np.array(pos, dtype=np.float64).reshape(n, 2)
        self.yaw = np.array(yaws, dtype=np.float64)
        self.speed = np.array(speeds, dtype=np.float64)
        self.half = np.array(half, dtype=np.float64).reshape(n, 2)
        self.geometry = np.array(geometry, dtype=np.float64).reshape(n, 3)
        self.count = np.array(counts, dtype=np.int64)
        self.s_self = np.array(s_self, dtype=np.float64)
        # arc length from the vehicle along its path: the path's own (k · PATH_STEP) less where the vehicle is
        self.s = np.where(np.arange(h)[None, :] < self.count[:, None],
                          _arc_lengths(h)[None, :] - self.s_self[:, None], self.FAR)

    def curve_speed(self, lateral_accel: float, decel: float) -> np.ndarray:
        """Speed per vehicle from which it can brake (at ``decel``) to the bend speed sqrt(a_lat / κ) of every
        bend ahead on its path (inf on straight paths)."""
        dyaw = np.diff(self.path_yaw, axis=1)
        kappa = np.abs(np.arctan2(np.sin(dyaw), np.cos(dyaw))) / PATH_STEP  # 1/m between consecutive points
        valid = (np.arange(1, self.path_yaw.shape[1])[None, :] < self.count[:, None]) & (self.s[:, 1:] > -1.0)
        kappa = np.where(valid, kappa, 0.0)
        bend = np.sqrt(lateral_accel / np.maximum(kappa, 1e-6))
        reach = np.sqrt(bend * bend + 2.0 * decel * np.maximum(self.s[:, 1:], 0.0))
        return reach.min(axis=1) if reach.shape[1] else np.full(self.pos.shape[0], np.inf)

    def pure_pursuit(self) -> np.ndarray:
        """Steer per vehicle toward the first path point at least the look-ahead distance away."""
        n = self.pos.shape[0]
        ld = np.clip(2.0 + 0.3 * np.abs(self.speed), 3.0, 8.0)  # lookahead_distance, vectorised
        d = np.hypot(self.xy[:, :, 0] - self.pos[:, None, 0], self.xy[:, :, 1] - self.pos[:, None, 1])
        valid = np.arange(self.xy.shape[1])[None, :] < self.count[:, None]
        beyond = (d >= ld[:, None]) & valid
        k = np.where(beyond.any(axis=1), np.argmax(beyond, axis=1), self.count - 1)
        rows = np.arange(n)
        dx = self.xy[rows, k, 0] - self.pos[:, 0]
        dy = self.xy[rows, k, 1] - self.pos[:, 1]
        dist = np.hypot(dx, dy)
        alpha = np.arctan2(dy, dx) - self.yaw
        alpha = np.arctan2(np.sin(alpha), np.cos(alpha))
        curvature = np.where(dist > 1e-3, 2.0 * np.sin(alpha) / np.maximum(dist, 1e-3), 0.0)
        curvature = np.where(self.speed < 0.0, -curvature, curvature)
        l_r, l_f, k_wheel = self.geometry[:, 0], self.geometry[:, 1], self.geometry[:, 2]
        beta = np.arcsin(np.clip(curvature * l_r, -0.999, 0.999))
        wheel = np.arctan(np.tan(beta) * (l_f + l_r) / l_r)
        steer = np.clip(wheel / k_wheel, -1.0, 1.0)
        return np.where(self.count >= 2, steer, 0.0)


class _ObstacleTable:
    """Boxes and velocities of every actor that can block a lane, as arrays (built once per tick)."""

    def __init__(self, snapshot: Snapshot) -> None:
        rows, ids = [], []
        for actor in snapshot.actors.values():
            if actor.kind in (ActorKind.TRAFFIC_LIGHT, ActorKind.TRAFFIC_SIGN) or actor.parent_id is not None:
                continue
            if actor.kind is ActorKind.PROP and actor.bounding_box.extent.z < 0.15:
                continue  # flat debris: drive over it
            t = actor.transform
            box = actor.bounding_box
            yaw = math.radians(t.rotation.yaw)
            c, s = math.cos(yaw), math.sin(yaw)
            cx = t.location.x + c * box.location.x - s * box.location.y
            cy = t.location.y + s * box.location.x + c * box.location.y
            rows.append((cx, cy, yaw, box.extent.x, box.extent.y, actor.velocity.x, actor.velocity.y))
            ids.append(actor.id)
        self.ids = np.asarray(ids, dtype=np.int64)
        self.a = np.asarray(rows, dtype=np.float64).reshape(-1, 7)

    def leaders(self, batch: _Batch, margin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(bumper gap, leader speed along the path, leader id or −1, cosine between the leader's heading and
        the path's there) per vehicle; gap is inf on a clear path."""
        n = batch.pos.shape[0]
        gaps = np.full(n, np.inf)
        v_lead = np.zeros(n)
        lead_id = np.full(n, -1, dtype=np.int64)
        lead_cos = np.ones(n)
        if self.a.shape[0] == 0:
            return gaps, v_lead, lead_id, lead_cos
        a = self.a
        reach = (batch.count - 1).astype(float) + 8.0
        d = np.hypot(batch.pos[:, None, 0] - a[None, :, 0], batch.pos[:, None, 1] - a[None, :, 1])
        near = (d < reach[:, None]) & (batch.ids[:, None] != self.ids[None, :]) & (batch.count[:, None] >= 2)
        ia, io = np.nonzero(near)
        if ia.size == 0:
            return gaps, v_lead, lead_id, lead_cos
        o = a[io]
        dx = o[:, None, 0] - batch.xy[ia, :, 0]
        dy = o[:, None, 1] - batch.xy[ia, :, 1]
        d2 = dx * dx + dy * dy
        # the first path point close to the obstacle (not the global nearest: a path may loop back)
        close = d2 < 16.0
        k = np.where(close.any(axis=1), np.argmax(close, axis=1), np.argmin(d2, axis=1))
        rows = np.arange(ia.size)
        pyaw = batch.path_yaw[ia, k]
        tx, ty = np.cos(pyaw), np.sin(pyaw)
        ex, ey = dx[rows, k], dy[rows, k]
        along = ex * tx + ey * ty
        lateral = np.abs(ex * ty - ey * tx)
        rel = o[:, 2] - pyaw
        cos_rel, sin_rel = np.abs(np.cos(rel)), np.abs(np.sin(rel))
        half_across = o[:, 3] * sin_rel + o[:, 4] * cos_rel
        half_along = o[:, 3] * cos_rel + o[:, 4] * sin_rel
        on_path = lateral < batch.half[ia, 1] + half_across + margin
        station = batch.s[ia, k] + along
        ahead = on_path & (station > 0.0) & (k < batch.count[ia] - 1)
        gap = np.where(ahead, station - batch.half[ia, 0] - half_along, np.inf)
        order = np.lexsort((gap, ia))
        first = np.ones(order.size, dtype=bool)
        first[1:] = ia[order][1:] != ia[order][:-1]
        best = order[first]
        best = best[np.isfinite(gap[best])]
        gaps[ia[best]] = gap[best]
        v_lead[ia[best]] = o[best, 5] * tx[best] + o[best, 6] * ty[best]
        lead_id[ia[best]] = self.ids[io[best]]
        lead_cos[ia[best]] = np.cos(rel[best])
        return gaps, v_lead, lead_id, lead_cos


def _geometry(type_id: str) -> blueprints.BicycleGeometry:
    try:
        return blueprints.find(type_id).geometry or blueprints.DEFAULT_GEOMETRY
    except blueprints.UnknownBlueprintError:
        return blueprints.DEFAULT_GEOMETRY
