"""Merging into a slow flow (MergerIntoSlowTraffic, MergerIntoSlowTrafficV2): gap acceptance for the expert.

PDM-Lite follows no leader near a lane change (only the short box forecast runs there), so it drives at its own
target speed up to a flow of cars at 9–10 m/s and into the side of the first one it meets. While a merge scenario
publishes its hint (with the flow's sink), this module orders every vehicle in the flow's lane by its distance to
that sink along the lane (all branches that lead there: the highway lane and, Town06-style, the flow's own entry)
and compares it with the ego's distance to the sink along its route. The ego then follows the nearest such
vehicle that is ahead of it, or beside it, or too little behind it to merge in front of it: it slows down, lets
that car pass and slots in behind it. Cars far enough behind are not waited for here: the flow's cars never brake
for the ego (LB2.0's ActorFlow ignores vehicles until its first collision), and the expert's long forecast of
such cars (expert.py, ``_flow_cars``) keeps it out of their way and drives it at their speed once it is in.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.idm import idm_target_speed
from b2d_data.expert.route_processing import DenseRoute
from b2d_data.format.transform import Location
from b2d_data.sim.api import ActorState, ScenarioHint

if TYPE_CHECKING:
    from b2d_data.maps import Map

log = logging.getLogger(__name__)

#: The hint types handled here.
#: EnterActorFlow publishes its sink only on an on-ramp, where the ego changes from its own lane into the flow's.
MERGE_TYPES = ("MergerIntoSlowTraffic", "MergerIntoSlowTrafficV2", "EnterActorFlowV2", "EnterActorFlow")
#: The flow's lane is followed back from the sink this far (m), and on past it this far.
LANE_BACK, LANE_AHEAD = 250.0, 30.0
#: A vehicle is in the flow's lane within this distance of its centre line (m) and this heading difference (deg).
IN_LANE_DISTANCE, IN_LANE_YAW = 1.8, 45.0
#: The ego counts as merged within this distance of the flow lane's centre line (m).
EGO_MERGED_DISTANCE = 1.0
#: Free road (m) wanted behind the ego to merge in front of a flow car, on top of the half lengths of both cars.
REAR_MARGIN = 4.0
#: A car beside or behind the ego slower than this (m/s) stands and is not waited for.
WAITING_SPEED = 2.0
#: Share of a flow car's speed the ego slows to while that car is beside it, so that the car draws ahead.
BESIDE_SPEED_SHARE = 0.5


@dataclass(frozen=True)
class _Lane:
    """Centre points (N, 2) of the lanes leading to a sink, their headings (deg) and distances to the sink (m)."""

    points: np.ndarray
    headings: np.ndarray
    to_sink: np.ndarray


def merge_hint(hints: Sequence[ScenarioHint]) -> ScenarioHint | None:
    """The first published merge hint that carries its sink, if any."""
    for hint in hints:
        if hint.scenario_type in MERGE_TYPES and {"sink_x", "sink_y"} <= set(hint.extra):
            return hint
    return None


def _flow_lane(town: Map, sink: Location) -> _Lane | None:
    """Every lane point within ``LANE_BACK`` m before the sink (all branches) and ``LANE_AHEAD`` m after it."""
    start = town.get_waypoint(sink)
    if start is None:
        return None
    points: list[tuple[float, float]] = []
    headings: list[float] = []
    dist: list[float] = []
    seen: set[tuple[int, int, int, float]] = set()
    frontier = [(start, 0.0)]
    while frontier and len(points) < 5000:
        wp, d = frontier.pop()
        key = (wp.road_id, wp.section_id, wp.lane_id, round(wp.s))
        if key in seen:
            continue
        seen.add(key)
        loc = wp.transform.location
        points.append((loc.x, loc.y))
        headings.append(wp.transform.rotation.yaw)
        dist.append(d)
        if d + 1.0 <= LANE_BACK:
            frontier += [(p, d + 1.0) for p in wp.previous(1.0)]
    wp, d = start, 0.0
    while d < LANE_AHEAD:
        nxt = wp.next(1.0)
        if not nxt:
            break
        wp, d = nxt[0], d + 1.0
        points.append((wp.transform.location.x, wp.transform.location.y))
        headings.append(wp.transform.rotation.yaw)
        dist.append(-d)
    return _Lane(np.array(points), np.array(headings), np.array(dist))


def _nearest(lane: _Lane, x: float, y: float, yaw: float) -> tuple[float, float]:
    """(distance to the nearest lane point with a heading within ``IN_LANE_YAW``, that point's distance to sink)."""
    d = np.hypot(lane.points[:, 0] - x, lane.points[:, 1] - y)
    diff = np.abs((lane.headings - yaw + 180.0) % 360.0 - 180.0)
    d = np.where(diff < IN_LANE_YAW, d, np.inf)
    k = int(np.argmin(d))
    return float(d[k]), float(lane.to_sink[k])


class SlowFlowMerge:
    """The expert's merge into a slow flow: a target speed that waits for a gap (see the module docstring)."""

    def __init__(self, config: ExpertConfig, town: Map) -> None:
        self.config = config
        self.town = town
        self._lanes: dict[tuple[float, float], _Lane | None] = {}
        self._sink_index: dict[tuple[float, float], int] = {}

    def target_speed(
        self,
        hint: ScenarioHint,
        ego: ActorState,
        route: DenseRoute,
        vehicles: Sequence[ActorState],
        target_speed: float,
    ) -> tuple[float, ActorState | None]:
        """The speed that keeps the ego behind the flow car it must let pass (and that car), or ``target_speed``."""
        sink = Location(float(hint.extra["sink_x"]), float(hint.extra["sink_y"]), float(hint.extra.get("sink_z", 0.0)))
        key = (round(sink.x, 1), round(sink.y, 1))
        if key not in self._lanes:
            self._lanes[key] = _flow_lane(self.town, sink)
            pts = route.original_points[:, :2]
            self._sink_index[key] = int(np.argmin(np.hypot(pts[:, 0] - sink.x, pts[:, 1] - sink.y)))
        lane = self._lanes[key]
        if lane is None:
            return target_speed, None
        cfg = self.config
        ego_to_sink = (self._sink_index[key] - route.index) / cfg.points_per_meter
        ego_yaw = ego.transform.rotation.yaw
        ego_off, _ = _nearest(lane, ego.location.x, ego.location.y, ego_yaw)
        merged = ego_off < EGO_MERGED_DISTANCE
        ego_half = ego.bounding_box.extent.x
        best: tuple[float, ActorState] | None = None
        for v in vehicles:
            off, v_to_sink = _nearest(lane, v.location.x, v.location.y, v.transform.rotation.yaw)
            if off > IN_LANE_DISTANCE:
                continue
            ahead = ego_to_sink - v_to_sink  # > 0: the vehicle is ahead of the ego once merged
            needed_behind = 0.0 if merged else ego_half + v.bounding_box.extent.x + REAR_MARGIN
            if ahead <= -needed_behind or ahead > cfg.leading_detection_length:
                continue
            if ahead <= 0.0 and v.speed() < WAITING_SPEED:
                continue  # it stands (a flow only stops after a collision): go first
            if best is None or ahead < best[0]:
                best = (ahead, v)
        if best is None:
            return target_speed, None
        ahead, leader = best
        if ahead < ego_half + leader.bounding_box.extent.x + 1.0:
            # beside (or just ahead, not yet in our lane): fall back and let it draw ahead
            speed = min(target_speed, BESIDE_SPEED_SHARE * leader.speed())
        else:
            speed = idm_target_speed(
                cfg,
                target_speed,
                ego.speed(),
                2.0 * leader.bounding_box.extent.x,
                leader.speed(),
                ahead,
                cfg.idm_leading_vehicle_s0,
                cfg.idm_leading_vehicle_T,
            )
        log.debug("merge: following %d (%.1f m ahead along the flow lane) at %.1f m/s", leader.id, ahead, speed)
        return min(speed, target_speed), leader
