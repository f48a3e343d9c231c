"""Lane changes the leaderboard route asks for (CHANGELANELEFT/RIGHT commands) when the new lane stays full.

The route planner jumps to the new lane within 5 m (CARLA's ``trace_route``). PDM-Lite follows that at once and,
near the change, stops for whatever its forecast hits in the new lane. The expert still does so first. But with the
background traffic's speed ramp around a standing ego (expert-and-scenarios.md §3.1), the new lane can become a
standing queue beside it that never opens a gap, and the ego, standing at (or half across) the change, holds up its
own lane too: a deadlock.

So once the ego has stood within a few metres of a route lane change for ``stuck_time`` seconds, the route is held
in the lane the ego is in (its points after the change are moved back onto that lane) and re-joins the route over a
cosine ramp. While the new lane has no gap beside the ego (:func:`gap_is_free`), the ramp is pushed ahead every
frame, so the ego drives on in its own lane and the traffic around it keeps moving; a slower car in the new lane
ahead is let go ahead (the ego drives a little slower than it). At the first gap the ramp is fixed just ahead of the
ego and the change is committed: cars behind in the new lane are left to brake for the ego (background cars do; a
scenario's flow cars do not, and expert.py's ``_flow_cars`` watches them), and
cars ahead are followed by IDM like any leader. The hold never reaches past the route's next lane change into a
third lane, nor to the last ``end_margin`` metres of the route.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.route_processing import DenseRoute
from b2d_data.format.road_option import RoadOption
from b2d_data.sim.api import ActorState, Snapshot

if TYPE_CHECKING:
    from b2d_data.maps import Waypoint

_CHANGES = (RoadOption.CHANGELANELEFT, RoadOption.CHANGELANERIGHT)


@dataclass(frozen=True)
class LaneChangeSettings:
    """Distances in m, times in s."""

    detect_ahead: float = 40.0  # a route lane change this close ahead is planned
    stuck_speed: float = 0.5  # m/s: the ego counts as waiting at a lane change below this speed …
    stuck_time: float = 5.0  # … and holds its lane after waiting this long within lead_min of the change
    ramp_min: float = 10.0  # the change is driven over max(ramp_min, ramp_time × speed)
    ramp_time: float = 1.2
    lead_min: float = 6.0  # while waiting, the ramp starts max(lead_min, lead_time × speed) ahead
    lead_time: float = 1.5
    front_gap: float = 3.0  # bumper gap to a car ahead in the new lane, + closing speed × front_time
    front_time: float = 1.0
    rear_gap: float = 3.0  # bumper gap to a car behind in the new lane, + closing speed × rear_time
    rear_time: float = 1.5
    commit_ahead: float = 2.0  # a gap found, the ramp starts this far ahead of the ego
    drop_back: float = 1.0  # waiting beside a slower car in the new lane, the ego drives this much slower than it
    drop_back_min_speed: float = 3.0  # … unless that car is slower than this (then the ego drives on past it)
    look: float = 40.0  # cars this far along the new lane (either way) are checked
    end_margin: float = 10.0  # the hold ends this far before the leaderboard route's end


@dataclass
class _Change:
    """One route lane change being planned."""

    start: int  # first dense index of the change (still in the old lane)
    option: RoadOption
    limit: int  # the ramp never starts later than this index
    held: np.ndarray  # (M, 3) the old lane's centre from ``start`` on, one point per dense index
    ramp_start: int
    ramp_length: int
    holding: bool = False  # the ego waited too long at the change: the route is held in the old lane
    entered: bool = False  # holding, the new lane had a gap: the ramp is fixed and the change is committed

    @property
    def ramp_end(self) -> int:
        """First dense index after the ramp."""
        return self.ramp_start + self.ramp_length


class LaneChangePlanner:
    """Per route lane change: PDM-Lite's way, or, once the ego has waited there too long, its lane held until a gap."""

    def __init__(self, settings: LaneChangeSettings | None = None) -> None:
        self.settings = settings or LaneChangeSettings()
        self._change: _Change | None = None
        self._searched_from = -1
        self._waited = 0  # frames the ego has stood at the planned change
        #: Target speed cap (m/s) while waiting beside a slower car in the new lane, to fall in behind it.
        self.speed_cap = math.inf

    @property
    def holding(self) -> bool:
        """The route is rewritten to hold the ego's lane (its original points are not the way to go)."""
        return self._change is not None and self._change.holding

    @property
    def committed(self) -> bool:
        """A lane change is committed (the ramp is fixed) and not yet done."""
        return self._change is not None and self._change.entered

    def step(self, snapshot: Snapshot, ego: ActorState, route: DenseRoute) -> None:
        """Plan, hold or release the next route lane change; rewrites ``route.points`` over its stretch."""
        s = self.settings
        cfg = route.config
        self.speed_cap = math.inf
        change = self._change
        if change is not None and route.index >= change.ramp_end:
            self._change = change = None
        if change is None:
            self._waited = 0
            change = self._change = self._next_change(route)
            if change is None:
                return
        if change.entered:
            return
        speed = ego.speed()
        lead = cfg.points(max(s.lead_min, s.lead_time * speed))
        if not change.holding:
            # PDM-Lite's way first (follow the route's change, the forecast waits for a gap); only an ego standing
            # there for stuck_time holds its lane instead (the new lane has become a queue that will not open)
            at_change = route.index + cfg.points(s.lead_min) >= change.start
            self._waited = self._waited + 1 if at_change and speed < s.stuck_speed else 0
            if self._waited < round(s.stuck_time * cfg.fps):
                return
            change.holding = True
            change.ramp_start = max(change.start, route.index + lead)
        change.ramp_length = max(change.ramp_length, cfg.points(max(s.ramp_min, s.ramp_time * speed)))
        if route.index + lead >= change.ramp_start:
            free, slower_ahead = gap_is_free(snapshot, ego, route, change, s)
            if free:
                # commit: change lane from right here (not before the route's own change point)
                change.ramp_start = max(change.start, min(change.ramp_start, route.index + cfg.points(s.commit_ahead)))
                change.entered = True
            else:
                change.ramp_start = min(change.limit, max(change.ramp_start, route.index + lead))
            if slower_ahead is not None:
                self.speed_cap = max(0.0, slower_ahead - s.drop_back)
        _write_hold(route, change)

    def yields_to_ego(self, ego: ActorState, other: ActorState) -> bool:
        """During a committed lane change: is ``other`` behind the ego (so it is left to brake for the ego)?"""
        if not self.committed:
            return False
        yaw = math.radians(ego.transform.rotation.yaw)
        dx, dy = other.location.x - ego.location.x, other.location.y - ego.location.y
        return dx * math.cos(yaw) + dy * math.sin(yaw) < -ego.bounding_box.extent.x

    def _next_change(self, route: DenseRoute) -> _Change | None:
        """The next route lane change within ``detect_ahead`` m (None: none, or one already handled)."""
        cfg = route.config
        lo = max(route.index, self._searched_from, 1)
        hi = min(len(route), route.index + cfg.points(self.settings.detect_ahead))
        cmds = route.original_commands
        for i in range(lo, hi):
            if cmds[i] in _CHANGES and cmds[i - 1] not in _CHANGES:
                self._searched_from = i + 1
                # another route rewrite (an obstacle scenario's shift) owns this stretch: leave it alone
                if np.any(route.points[i:hi] != route.original_points[i:hi]):
                    return None
                return _plan(route, i, cmds[i], self.settings)
        self._searched_from = max(self._searched_from, hi)
        return None


def _plan(route: DenseRoute, start: int, option: RoadOption, s: LaneChangeSettings) -> _Change | None:
    """Hold the old lane from ``start`` up to the next change into a third lane, or up to the route's end."""
    cfg = route.config
    cmds = route.original_commands
    end = route.end_index if route.end_index >= 0 else len(route) - 1
    limit = end - cfg.points(s.end_margin)
    j = start
    while j < len(route) and cmds[j] == option:
        j += 1
    for k in range(j, len(route)):
        if cmds[k] in _CHANGES:
            if cmds[k] == option:  # on into a third lane: the ramp must be done before that change
                limit = min(limit, k - cfg.points(s.ramp_min))
            break
    if limit <= start:
        return None
    old = route.coarse_waypoints[start]
    held = _lane_centre(old, (limit - start) / cfg.points_per_meter + s.ramp_min + 60.0, cfg.points_per_meter)
    if held is None:
        return None
    return _Change(start, option, limit, held, start, cfg.points(s.ramp_min))


def _lane_centre(wp: Waypoint, length: float, per_meter: int) -> np.ndarray | None:
    """Centre points of ``wp``'s lane, 1/per_meter m apart, over ``length`` m (None when the lane ends first)."""
    pts = [wp.transform.location]
    current = wp
    for _ in range(math.ceil(length)):
        yaw = current.transform.rotation.yaw
        # at a fork, the branch that turns least
        nxt = min(
            current.next(1.0), key=lambda o: abs((o.transform.rotation.yaw - yaw + 180.0) % 360.0 - 180.0), default=None
        )
        if nxt is None or nxt.is_junction:
            break
        current = nxt
        pts.append(current.transform.location)
    if len(pts) < 2:
        return None
    coarse = np.array([[p.x, p.y, p.z] for p in pts])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(coarse[:, :2], axis=0), axis=1))])
    fine = np.arange(0.0, arc[-1], 1.0 / per_meter)
    return np.stack([np.interp(fine, arc, coarse[:, d]) for d in range(3)], axis=1)


def _write_hold(route: DenseRoute, change: _Change) -> None:
    """Route points: the old lane from the change's start to the ramp, the cosine ramp, then the route again."""
    n = min(len(route), change.start + len(change.held))
    idx = np.arange(change.start, n)
    x = np.clip((idx - change.ramp_start) / change.ramp_length, 0.0, 1.0)
    k = 0.5 + np.cos(x * math.pi) / 2.0  # 1 - smooth_transition(x): 1 before the ramp, 0 after it
    held = change.held[: n - change.start]
    route.points[change.start : n] = k[:, None] * held + (1.0 - k[:, None]) * route.original_points[change.start : n]
    for i in range(change.start, min(n, change.ramp_end)):
        route.commands[i] = RoadOption.LANEFOLLOW if i < change.ramp_start else change.option
    for i in range(change.ramp_end, min(n, change.ramp_end + change.ramp_length)):
        route.commands[i] = route.original_commands[i]


def gap_is_free(
    snapshot: Snapshot, ego: ActorState, route: DenseRoute, change: _Change, s: LaneChangeSettings
) -> tuple[bool, float | None]:
    """Whether no vehicle in the new lane is closer to the ego than the gaps of :class:`LaneChangeSettings` (bumper
    to bumper, along the lane, widened by the closing speed); also the speed of the nearest car that blocks the gap
    from ahead while driving slower than the ego (None: no such car)."""
    cfg = route.config
    lane = _new_lane_line(route, change, cfg.points(s.look))
    if lane is None:
        return True, None
    xy, width, headings = lane
    ego_xy = np.array([ego.location.x, ego.location.y])
    ego_station = float(np.argmin(np.linalg.norm(xy - ego_xy, axis=1)))
    v = ego.speed()
    half_ego = ego.bounding_box.extent.x
    free = True
    nearest_ahead, slower_ahead = math.inf, None
    for other in snapshot.vehicles():
        if other.id == ego.id or other.location.distance_2d(ego.location) > s.look + 10.0:
            continue
        d = np.linalg.norm(xy - np.array([other.location.x, other.location.y]), axis=1)
        k = int(np.argmin(d))
        yaw_diff = abs((other.transform.rotation.yaw - headings[k] + 180.0) % 360.0 - 180.0)
        if d[k] > 0.5 * width or yaw_diff > 45.0:
            continue
        u = other.speed()
        along = float(k) - ego_station  # metres: the line is sampled every metre
        bumper = abs(along) - half_ego - other.bounding_box.extent.x
        # a car standing ahead must also leave room for the ramp: the ego is across only past most of it
        room = s.commit_ahead + 0.6 * change.ramp_length / cfg.points_per_meter if u < s.stuck_speed else 0.0
        if along >= 0.0 and bumper < s.front_gap + max(0.0, v - u) * s.front_time + room:
            free = False
            if s.drop_back_min_speed <= u < v + s.drop_back and along < nearest_ahead:
                nearest_ahead, slower_ahead = along, u
        if along < 0.0 and bumper < s.rear_gap + max(0.0, u - v) * s.rear_time:
            free = False
    return free, slower_ahead


def _new_lane_line(route: DenseRoute, change: _Change, window: int) -> tuple[np.ndarray, float, np.ndarray] | None:
    """Centre of the new lane beside the ego, one point per metre from ``window`` points behind to ahead of it:
    the old lane (the route before the change, the held line after it) moved sideways by the new lane's width."""
    per = route.config.points_per_meter
    lo = max(0, route.index - window)
    hi = min(change.start + len(change.held), route.index + window)
    idx = np.arange(lo, hi, per)
    if idx.size < 2:
        return None
    old = np.where(
        (idx < change.start)[:, None],
        route.original_points[np.minimum(idx, len(route) - 1), :2],
        change.held[np.clip(idx - change.start, 0, len(change.held) - 1), :2],
    )
    tangent = np.gradient(old, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    # CARLA's frame: the right of heading (cos, sin) is (-sin, cos)
    right = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    old_wp = route.coarse_waypoints[change.start]
    new_wp = old_wp.get_left_lane() if change.option == RoadOption.CHANGELANELEFT else old_wp.get_right_lane()
    width = float(new_wp.lane_width) if new_wp is not None else float(old_wp.lane_width)
    offset = 0.5 * (old_wp.lane_width + width)
    side = -1.0 if change.option == RoadOption.CHANGELANELEFT else 1.0
    headings = np.degrees(np.arctan2(tangent[:, 1], tangent[:, 0]))
    return old + side * offset * right, width, headings
