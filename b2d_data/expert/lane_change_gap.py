"""Gap acceptance for the route's planned lane changes (a deviation from PDM-Lite, which steers into a planned
change wherever the route puts it and brakes to a stop when its forecast meets a car of the target lane).

Until a gap is accepted the dense route is held on the current lane past the planned change (the route points are
moved to the current lane's centre, commands LANEFOLLOW), and the speed is set to drift the ego beside a gap of
the target lane: faster than the gap to catch one ahead, slower to let one come back to it, stopping only at the
last point where the change can still be made. A gap is accepted when the ego fits between its leader and follower
with a clearance that grows with their speeds and the speed differences; then the route gets a smooth ramp into the
target lane from just ahead of the ego and, until the ramp is driven, the ego follows the gap's leader by IDM.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.idm import idm_target_speed
from b2d_data.expert.route_processing import DenseRoute
from b2d_data.expert.route_shifting import smooth_transition
from b2d_data.format.road_option import RoadOption
from b2d_data.sim.api import ActorState

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint

log = logging.getLogger(__name__)

_CHANGES = (RoadOption.CHANGELANELEFT, RoadOption.CHANGELANERIGHT)


@dataclass(frozen=True)
class GapConfig:
    """Distances in metres, times in seconds, speeds in m/s."""

    lookahead: float = 60.0  # gaps are sought from this far before the planned change
    search_back: float = 70.0  # target-lane vehicles this far behind the ego count
    search_ahead: float = 90.0
    # Bumper gaps. At a matched 15 m/s they need 3 + 3.75 + 3 + 3 = 12.75 m besides the cars' lengths (~9.4 m), so
    # a slot opens between flow cars 25 m apart, the densest HighwayExit flow of the training ranges; headways of
    # 0.4 s and 0.3 s needed 25.9 m for any slot and 27.9 m to aim at one (route 149130001, seed 149: a flow 15-27 m
    # apart at 15 m/s, in which the ego stopped for good).
    front_margin: float = 3.0  # bumper gap to the gap's leader: margin + headway × own speed + closing braking
    front_headway: float = 0.2
    rear_margin: float = 3.0  # bumper gap to the follower: margin + headway × its speed + Δv² / (2 × its braking)
    rear_headway: float = 0.25
    follower_brake: float = 3.0  # the follower closes in at most at its speed difference, braking this hard
    ego_acceleration: float = 2.0  # what the ego gains while it moves over, when slower than the follower
    comfortable_brake: float = 2.5
    # the braking curve toward the last point where a held change may begin; at 2 m/s² it held the ego below a
    # 15 m/s flow from 58 m before that point on, so a gap ahead drifted away (route 149130002, seed 149)
    stop_deceleration: float = 3.0
    stop_margin: float = 2.0
    # drifting beside a gap: the speed offset from the gap's speed is sqrt(2 × this × distance) (m/s²), so it
    # fades as the ego arrives and the gap still fits; no more than the desired speed ahead or this share of the
    # gap's speed behind (a standing ego never finds a gap in a flow that does not brake: route 149130003)
    align_acceleration: float = 1.5
    drop_back_share: float = 0.3
    ramp_time: float = 3.0  # the lane change ramp is speed × this long, within the bounds below
    ramp_min: float = 12.0
    ramp_max: float = 30.0
    ramp_lead: float = 2.0  # the ramp starts this far ahead of the ego
    end_margin: float = 5.0  # a held change must start this far before the next change or junction
    early_commit: float = 8.0  # a gap may be taken this far before the planned change (the ramp starts there)


@dataclass
class _Change:
    """One planned lane change of the route: dense indices and its state."""

    start: int  # first point of the planned change
    end: int  # first point on the target lane after it
    to_right: bool
    last_start: int  # the latest point where a held change may begin
    hold_end: int = 0  # the held points reach this far (the next change or junction), past ``last_start``
    target_keys: frozenset[tuple[int, int]] = frozenset()
    committed: bool = False
    ramp_end: int = -1
    held: bool = False


@dataclass
class _Car:
    s: float  # along the route (m)
    half: float  # half length (m)
    speed: float
    actor: ActorState | None  # None: an end of the search window


def _actor_id(car: _Car) -> int | None:
    """The car's actor id (None for an end of the search window)."""
    return car.actor.id if car.actor is not None else None


@dataclass
class GapDecision:
    """What the gate wants this frame: a speed cap (inf: none) and the vehicle it is aligned to."""

    target_speed: float = math.inf
    leader_id: int | None = None
    holding: bool = False


def planned_changes(route: DenseRoute, town: Map | None, cfg: ExpertConfig, gap: GapConfig) -> list[_Change]:
    """The route's planned lane changes (CHANGELANE blocks of the original commands outside junctions)."""
    cmds = route.original_commands
    n = len(route)
    out: list[_Change] = []
    i = 0
    while i < n:
        if cmds[i] not in _CHANGES:
            i += 1
            continue
        j = i
        while j < n and cmds[j] == cmds[i]:
            j += 1
        out.append(_Change(start=i, end=min(j, n - 1), to_right=cmds[i] == RoadOption.CHANGELANERIGHT, last_start=n))
        i = j
    # a held change must begin before the next change or junction, leaving room for its ramp
    for k, change in enumerate(out):
        limit = out[k + 1].start if k + 1 < len(out) else n - 1
        junction = np.flatnonzero(route.is_junction[change.end : limit])
        if junction.size:
            limit = change.end + int(junction[0])
        change.last_start = max(change.start, limit - cfg.points(gap.ramp_min + gap.end_margin))
        change.hold_end = max(change.last_start, limit)
        if town is not None:
            keys = set()
            for idx in range(change.end, min(limit, n), cfg.points_per_meter):
                wp = route.waypoint(idx)
                keys.add((wp.road_id, wp.lane_id))
            for idx in range(
                max(0, change.start - cfg.points(gap.lookahead + gap.search_back)), change.start, cfg.points_per_meter
            ):
                wp = route.waypoint(idx)
                other = wp.get_right_lane() if change.to_right else wp.get_left_lane()
                if other is not None:
                    keys.add((other.road_id, other.lane_id))
            change.target_keys = frozenset(keys)
    return out


def _source_centre(wp: Waypoint, to_right: bool, previous: np.ndarray) -> np.ndarray:
    """The current-lane centre beside ``wp``: ``wp`` itself or its neighbour on the side the change comes from,
    whichever continues the held path."""
    here = np.array([wp.transform.location.x, wp.transform.location.y, wp.transform.location.z])
    other = wp.get_left_lane() if to_right else wp.get_right_lane()
    if other is None:
        return here
    there = np.array([other.transform.location.x, other.transform.location.y, other.transform.location.z])
    return there if np.linalg.norm(there[:2] - previous[:2]) < np.linalg.norm(here[:2] - previous[:2]) else here


def hold_lane(route: DenseRoute, change: _Change) -> None:
    """Move the route points of the planned change and after it (up to ``last_start``) onto the current lane."""
    if change.held:
        return
    previous = route.original_points[max(0, change.start - 1)]
    for idx in range(change.start, change.hold_end):
        previous = _source_centre(route.waypoint(idx), change.to_right, previous)
        route.points[idx] = previous
        route.commands[idx] = RoadOption.LANEFOLLOW
    change.held = True


def commit_change(route: DenseRoute, change: _Change, begin: int, length: int) -> None:
    """A smooth ramp from the held points to the original (target-lane) points over [begin, begin + length)."""
    begin = max(begin, change.start)
    end = min(len(route), begin + max(1, length))
    command = RoadOption.CHANGELANERIGHT if change.to_right else RoadOption.CHANGELANELEFT
    for idx in range(begin, end):
        k = smooth_transition((idx - begin) / max(1, length))
        route.points[idx] = k * route.original_points[idx] + (1.0 - k) * route.points[idx]
        route.commands[idx] = command
    for idx in range(end, max(end, change.hold_end)):
        route.points[idx] = route.original_points[idx]
        route.commands[idx] = route.original_commands[idx]
    change.committed = True
    change.ramp_end = end


@dataclass
class LaneChangeGate:
    """Holds each planned lane change of the route until a gap of the target lane is accepted."""

    config: ExpertConfig
    town: Map | None
    gap: GapConfig = field(default_factory=GapConfig)
    changes: list[_Change] | None = None
    #: the target-lane gap being approached (its cars' ids; None for an end of the search window)
    _aim: tuple[int | None, int | None] | None = field(default=None, init=False, repr=False)

    def step(
        self, snapshot_vehicles: Sequence[ActorState], ego: ActorState, route: DenseRoute, desired_speed: float
    ) -> GapDecision:
        """The gate's decision for this frame (may rewrite the route's working points)."""
        cfg, gap = self.config, self.gap
        if self.changes is None:
            self.changes = planned_changes(route, self.town, cfg, gap)
        index = route.index
        change = next((c for c in self.changes if not c.committed or c.ramp_end > index), None)
        if change is None or index < change.start - cfg.points(gap.lookahead):
            return GapDecision()
        cars = self._target_lane_cars(snapshot_vehicles, ego, route, change)
        ego_s = index / cfg.points_per_meter
        speed = ego.speed()
        half = ego.bounding_box.extent.x
        if change.committed:
            leader = min((c for c in cars if c.s > ego_s), key=lambda c: c.s, default=None)
            if leader is None:
                return GapDecision()
            return GapDecision(self._follow(desired_speed, speed, half, leader, ego_s), leader.actor.id)
        hold_lane(route, change)
        slots = self._slots(cars, speed, half)
        here = next((s for s in slots if s[0] <= ego_s <= s[1]), None)
        if here is not None and index >= change.start - cfg.points(gap.early_commit):
            length = cfg.points(float(np.clip(speed * gap.ramp_time, gap.ramp_min, gap.ramp_max)))
            commit_change(route, change, index + cfg.points(gap.ramp_lead), length)
            log.debug("lane change into gap %s at route point %d", here, index)
            leader = min((c for c in cars if c.s > ego_s), key=lambda c: c.s, default=None)
            target = self._follow(desired_speed, speed, half, leader, ego_s) if leader is not None else math.inf
            return GapDecision(target, leader.actor.id if leader is not None else None)
        room = (change.last_start - index) / cfg.points_per_meter
        target = self._align(cars, ego_s, half, desired_speed, room)
        # never past the last point where the change can begin: a gentle braking curve down to it
        stop = math.sqrt(2.0 * gap.stop_deceleration * max(0.0, room - gap.stop_margin))
        return GapDecision(min(target, stop), None, holding=True)

    # -- helpers ---------------------------------------------------------------------------------------------
    def _target_lane_cars(
        self, vehicles: Sequence[ActorState], ego: ActorState, route: DenseRoute, change: _Change
    ) -> list[_Car]:
        """Vehicles on the change's target lane near the ego, with their position along the route."""
        cfg, gap = self.config, self.gap
        lo = max(0, route.index - cfg.points(gap.search_back))
        hi = min(len(route), route.index + cfg.points(gap.search_ahead))
        pts = route.original_points[lo : hi : cfg.points_per_meter, :2]
        out = []
        if pts.shape[0] == 0 or self.town is None:
            return out
        for v in vehicles:
            if v.id == ego.id:
                continue
            loc = np.array([v.location.x, v.location.y])
            d = np.linalg.norm(pts - loc[None, :], axis=1)
            k = int(np.argmin(d))
            if d[k] > 8.0:
                continue
            wp = self.town.get_waypoint(v.location)
            if wp is None or (wp.road_id, wp.lane_id) not in change.target_keys:
                continue
            out.append(
                _Car((lo + k * cfg.points_per_meter) / cfg.points_per_meter, v.bounding_box.extent.x, v.speed(), v)
            )
        out.sort(key=lambda c: c.s)
        return out

    def _front_need(self, speed: float, leader: _Car) -> float:
        gap = self.gap
        closing = max(0.0, speed - leader.speed)
        return gap.front_margin + gap.front_headway * speed + closing * closing / (2.0 * gap.comfortable_brake)

    def _rear_need(self, speed: float, follower: _Car) -> float:
        gap = self.gap
        closing = max(0.0, follower.speed - speed)
        # the follower brakes while the ego speeds up: they close in by Δv² / (2 (b + a))
        return gap.rear_margin + gap.rear_headway * follower.speed + closing * closing / (
            2.0 * (gap.follower_brake + gap.ego_acceleration)
        )

    def _slots(self, cars: list[_Car], speed: float, half: float) -> list[tuple[float, float, float]]:
        """Where the ego's centre may be for each gap at its current speed: (from, to, the gap's speed)."""
        out = []
        bounds: list[tuple[_Car | None, _Car | None]] = list(zip([None, *cars], [*cars, None]))
        for follower, leader in bounds:
            lo = -math.inf if follower is None else follower.s + follower.half + half + self._rear_need(speed, follower)
            hi = math.inf if leader is None else leader.s - leader.half - half - self._front_need(speed, leader)
            if lo <= hi:
                speeds = [c.speed for c in (follower, leader) if c is not None]
                out.append((lo, hi, float(np.mean(speeds)) if speeds else math.inf))
        return out

    def _align(self, cars: list[_Car], ego_s: float, half: float, desired: float, room: float) -> float:
        """A speed that brings the ego beside the gap it can reach soonest at the gap's own speed, among those it
        reaches before the braking curve toward the last point takes it below that speed; the soonest of all when
        none does."""
        if not cars:
            return desired
        gap = self.gap
        # the ends of the search window count as cars: the flow may go on unseen beyond them, and a gap open
        # toward them kept the ego dropping back after one that receded as new cars came into view (149130020)
        bounded = [
            _Car(ego_s - gap.search_back, half, cars[0].speed, None),
            *cars,
            _Car(ego_s + gap.search_ahead, half, cars[-1].speed, None),
        ]
        best, best_rank = None, (False, False, -math.inf)
        for follower, leader in zip(bounded[:-1], bounded[1:]):
            gap_speed = (follower.speed + leader.speed) / 2.0
            # where the ego's centre may be beside this gap at the gap's speed (1 m inside either end)
            lo = follower.s + follower.half + half + self._rear_need(gap_speed, follower)
            hi = leader.s - leader.half - half - self._front_need(gap_speed, leader)
            key = (_actor_id(follower), _actor_id(leader))
            # the gap aimed at so far is kept while it is one at all: positions come in 1 m steps, and a gap a
            # metre short of the 2 m the choice asks for flickered in and out (route 149130020, seed 149)
            kept = key == self._aim and hi >= lo
            if hi - lo < 2.0 and not kept:
                continue
            middle = (lo + hi) / 2.0
            r = ego_s - float(np.clip(ego_s, min(lo + 1.0, middle), max(hi - 1.0, middle)))  # > 0: ahead of it
            limit = gap.drop_back_share * gap_speed if r > 0 else max(desired - gap_speed, 0.5)
            time = abs(r) / max(limit, 0.5)
            travel = gap_speed * time - r
            fits = travel <= room - gap.stop_margin - gap_speed * gap_speed / (2.0 * gap.stop_deceleration)
            rank = (fits, fits and kept, -time)
            if rank > best_rank:
                best, best_rank = (r, gap_speed, limit, key), rank
        if best is None:
            self._aim = None
            return desired
        r, gap_speed, limit, self._aim = best
        offset = min(math.sqrt(2.0 * gap.align_acceleration * abs(r)), limit)
        return float(np.clip(gap_speed - math.copysign(offset, r), 0.0, desired))

    def _follow(self, desired: float, speed: float, half: float, leader: _Car, ego_s: float) -> float:
        """IDM behind the gap's leader (its distance along the route)."""
        cfg = self.config
        distance = leader.s - ego_s
        return idm_target_speed(
            cfg,
            desired,
            speed,
            leader.half + half,
            leader.speed,
            distance,
            cfg.idm_leading_vehicle_s0,
            cfg.idm_leading_vehicle_T,
        )
