"""The expert's dense route (expert-and-scenarios.md §1.2): built once per route, then tracked every frame.

From the leaderboard's 1 m route: optional ParkingExit start or 50 m of predecessors, 50 m of successors,
linear resampling to 10 points/m (each point keeps the command of the nearest original point), per-point
heading, next traffic light / stop sign and their distances, speed limits, and the narrow-lane fix. The working
copy of the points is what obstacle scenarios shift; ``original_points`` never changes.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.lights_and_signs import stop_sign_affects, stop_sign_centre
from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location
from b2d_data.sim.api import TrafficLightInfo, TrafficSignInfo

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint

log = logging.getLogger(__name__)

_LANE_CHANGES = (RoadOption.CHANGELANELEFT, RoadOption.CHANGELANERIGHT)


def _xyz(wp: Waypoint) -> np.ndarray:
    loc = wp.transform.location
    return np.array([loc.x, loc.y, loc.z], dtype=np.float64)


def resample(points: np.ndarray, commands: Sequence[RoadOption], points_per_meter: int
             ) -> tuple[np.ndarray, list[RoadOption], np.ndarray]:
    """Linear resampling of a polyline to ``1/points_per_meter`` spacing along its length.

    Returns the new points, their commands (that of the nearest original point along the line) and, per new
    point, the index of that original point.
    """
    seg = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(arc[-1])
    n = math.floor(total * points_per_meter + 1e-9) + 1
    s = np.arange(n) / points_per_meter
    out = np.stack([np.interp(s, arc, points[:, k]) for k in range(3)], axis=1)
    # nearest original point along the line: the closer of the two segment ends
    hi = np.clip(np.searchsorted(arc, s, side="right"), 1, len(arc) - 1)
    lo = hi - 1
    nearest = np.where(s - arc[lo] <= arc[hi] - s, lo, hi)
    return out, [commands[int(i)] for i in nearest], nearest


def route_headings(points: np.ndarray) -> np.ndarray:
    """Heading (degrees) per point from its two neighbours; the ends copy their neighbour."""
    if points.shape[0] < 3:
        d = points[-1] - points[0] if points.shape[0] > 1 else np.array([1.0, 0.0, 0.0])
        return np.full(points.shape[0], math.degrees(math.atan2(d[1], d[0])))
    d = points[2:] - points[:-2]
    yaw = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    return np.concatenate([[yaw[0]], yaw, [yaw[-1]]])


def light_governs_mask(config: ExpertConfig, points: np.ndarray, headings: np.ndarray,
                       light: TrafficLightInfo) -> np.ndarray:
    """Route points that see one of the light's stop lines on their own lane within the look-ahead (§1.2).

    A stop waypoint counts for a point when it lies 0…5 m ahead along the route heading, within half a lane
    width sideways and with a heading within 45° (CARLA's landmark search along the lane, done geometrically).
    """
    mask = np.zeros(points.shape[0], dtype=bool)
    rad = np.radians(headings)
    fwd = np.stack([np.cos(rad), np.sin(rad)], axis=1)
    for sw in light.stop_waypoints:
        d = _xyz(sw)[None, :2] - points[:, :2]
        along = np.einsum("ij,ij->i", d, fwd)
        across = np.abs(d[:, 0] * fwd[:, 1] - d[:, 1] * fwd[:, 0])
        dyaw = np.abs((headings - sw.transform.rotation.yaw + 180.0) % 360.0 - 180.0)
        mask |= (along >= 0.0) & (along <= config.traffic_light_lookahead) & (across < 0.5 * sw.lane_width) & (
            dyaw < 45.0
        )
    return mask


@dataclass
class DenseRoute:
    """The dense route and everything precomputed along it (all arrays indexed by route point).

    Map waypoints of the dense points are looked up lazily (:meth:`waypoint`): most frames only need the
    junction flags, which come from the nearest original (1 m) waypoint.
    """

    points: np.ndarray  # (N, 3) working copy, shifted by obstacle scenarios
    original_points: np.ndarray  # (N, 3) never shifted
    coarse_waypoints: list[Waypoint]  # per dense point: the nearest waypoint of the (extended) 1 m route
    commands: list[RoadOption]
    original_commands: list[RoadOption]
    headings: np.ndarray  # degrees, from the original points
    next_light: list[int | None]
    light_distance: np.ndarray  # metres along the route to the stop line of ``next_light``
    next_stop: list[int | None]
    stop_distance: np.ndarray
    speed_limits: np.ndarray  # m/s
    is_junction: np.ndarray  # per-point junction flags
    town: Map | None = None
    index: int = 0
    end_index: int = -1  # the leaderboard route's last point (−1: the last point)
    config: ExpertConfig = field(default_factory=ExpertConfig)
    _saved_index: int = 0
    _waypoints: dict[int, Waypoint] = field(default_factory=dict)

    def waypoint(self, i: int) -> Waypoint:
        """The map waypoint (driving lane) at original route point ``i``, looked up once and cached."""
        i = int(np.clip(i, 0, len(self) - 1))
        wp = self._waypoints.get(i)
        if wp is None:
            found = self.town.get_waypoint(Location(*self.original_points[i])) if self.town is not None else None
            wp = found if found is not None else self.coarse_waypoints[i]
            self._waypoints[i] = wp
        return wp

    def set_waypoint(self, i: int, wp: Waypoint) -> None:
        """Force the waypoint of point ``i`` (ParkingExit start, narrow-lane fix)."""
        self._waypoints[int(i)] = wp

    def __len__(self) -> int:
        return self.points.shape[0]

    def update_index(self, position: np.ndarray | tuple[float, float]) -> int:
        """Move the index to the nearest route point among the next ``route_search_distance`` metres."""
        end = min(self.index + self.config.points(self.config.route_search_distance), len(self))
        window = self.points[self.index : end]
        d2 = (window[:, 0] - position[0]) ** 2 + (window[:, 1] - position[1]) ** 2
        self.index += int(np.argmin(d2))
        return self.index

    def save(self) -> None:
        """Remember the index (before forecasting the ego along the route)."""
        self._saved_index = self.index

    def load(self) -> None:
        """Restore the remembered index."""
        self.index = self._saved_index

    def closest_index(self, begin: int, location: np.ndarray) -> int:
        """Nearest original route point to ``location`` by descending the distance from ``begin`` (§1.9)."""
        pts = self.original_points[:, :2]
        target = np.asarray(location, dtype=np.float64)[:2]
        index = int(np.clip(begin, 0, len(self) - 1))
        if len(self) < 2:
            return index
        nxt = min(index + 1, len(self) - 1)
        direction = -1 if np.linalg.norm(target - pts[index]) < np.linalg.norm(target - pts[nxt]) else 1
        while 0 <= index + direction < len(self):
            if np.linalg.norm(target - pts[index]) < np.linalg.norm(target - pts[index + direction]):
                break
            index += direction
        return index

    def near_lane_change(self, speed: float) -> bool:
        """A CHANGELANE command from 15 m behind to max(20 m, braking distance) ahead of the index (§1.6)."""
        cfg = self.config
        braking = ((speed * 3.6) / 10.0) ** 2 / 2.0 + cfg.braking_distance_safety
        ahead = max(cfg.points(cfg.lane_change_min_lookahead), min(len(self), cfg.points_per_meter * int(braking)))
        lo = max(0, self.index - cfg.points(cfg.lane_change_lookbehind))
        hi = min(len(self) - 1, self.index + ahead)
        return any(c in _LANE_CHANGES for c in self.commands[lo:hi])

    def lane_changed_recently(self) -> bool:
        """A CHANGELANE command within the last 15 m (widens the trailing-vehicle corridor, §1.6)."""
        lo = max(0, self.index - self.config.points(self.config.trailing_lane_change_lookbehind))
        return any(c in _LANE_CHANGES for c in self.commands[lo : self.index])

    def samples(self, points: np.ndarray, first: float, count: int) -> np.ndarray:
        """``count`` points 1 m apart starting ``first`` metres ahead of the index (padded with the last)."""
        start = self.index + self.config.points(first)
        idx = np.minimum(start + np.arange(count) * self.config.points_per_meter, len(self) - 1)
        return points[idx].copy()


def _extend(route: Sequence[tuple[Waypoint, RoadOption]], config: ExpertConfig, parking_exit_wp: Waypoint | None,
            ego_location: np.ndarray) -> tuple[np.ndarray, list[RoadOption], list[Waypoint], int]:
    """Route points with the ParkingExit start or predecessors, plus successors; returns the start index (m)."""
    wps: list[Waypoint] = [wp for wp, _ in route]
    cmds = [RoadOption(int(c)) for _, c in route]
    pts = [_xyz(wp) for wp, _ in route]
    start = 0
    if parking_exit_wp is not None:
        # the ego starts off the route (ParkingExit): drive from where it stands, as a lane change
        wps.insert(0, parking_exit_wp)
        cmds.insert(0, RoadOption.CHANGELANELEFT)
        pts.insert(0, np.asarray(ego_location, dtype=np.float64))
    else:
        first = route[0][0]
        for _ in range(config.extra_route_length):
            prev = first.previous(1.0)
            if not prev:
                break
            first = prev[0]
            wps.insert(0, first)
            cmds.insert(0, RoadOption.LANEFOLLOW)
            pts.insert(0, _xyz(first))
            start += 1
    last = route[-1][0]
    for _ in range(config.extra_route_length):
        nxt = last.next(1.0)
        if not nxt:
            break
        last = nxt[0]
        wps.append(last)
        cmds.append(RoadOption.LANEFOLLOW)
        pts.append(_xyz(last))
    return np.array(pts), cmds, wps, start


def build_dense_route(town: Map, route: Sequence[tuple[Waypoint, RoadOption]], ego_location: np.ndarray,
                      lights: Mapping[int, TrafficLightInfo], signs: Mapping[int, TrafficSignInfo],
                      config: ExpertConfig | None = None) -> DenseRoute:
    """Process the leaderboard's dense route for the expert (§1.2)."""
    config = config or ExpertConfig()
    if len(route) < 2:
        raise ValueError(f"the expert needs a route of at least 2 points, got {len(route)}")
    ego_location = np.asarray(ego_location, dtype=np.float64)
    first = _xyz(route[0][0])
    parking_wp = None
    if np.linalg.norm(first[:2] - ego_location[:2]) > config.parking_exit_start_distance:
        from b2d_data.maps import LaneType

        parking_wp = town.get_waypoint(Location(*ego_location), lane_type=LaneType.ANY) or route[0][0]
        log.info("ego starts %.1f m from the route: ParkingExit start", np.linalg.norm(first[:2] - ego_location[:2]))
    raw_points, raw_cmds, raw_wps, start_m = _extend(route, config, parking_wp, ego_location)
    # drop repeated points (zero-length segments) so the arc length is strictly increasing
    keep = np.concatenate([[True], np.linalg.norm(np.diff(raw_points[:, :2], axis=0), axis=1) > 1e-6])
    kept_index = np.cumsum(keep) - 1
    start_original = int(kept_index[start_m])
    raw_points = raw_points[keep]
    raw_cmds = [c for c, k in zip(raw_cmds, keep) if k]
    raw_wps = [w for w, k in zip(raw_wps, keep) if k]
    points, commands, nearest = resample(raw_points, raw_cmds, config.points_per_meter)
    # the dense point at the leaderboard route's first point (after the prepended predecessors)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(raw_points[:, :2], axis=0), axis=1))])
    start_index = min(round(float(arc[start_original]) * config.points_per_meter), len(points) - 1)
    end_original = int(kept_index[start_m + len(route) - 1 + (1 if parking_wp is not None else 0)])
    end_index = min(round(float(arc[end_original]) * config.points_per_meter), len(points) - 1)
    coarse = [raw_wps[int(j)] for j in nearest]
    dense = DenseRoute(
        points=points.copy(), original_points=points.copy(), coarse_waypoints=coarse, commands=list(commands),
        original_commands=list(commands), headings=route_headings(points),
        next_light=[None] * len(points), light_distance=np.full(len(points), np.inf),
        next_stop=[None] * len(points), stop_distance=np.full(len(points), np.inf),
        speed_limits=np.zeros(len(points)), is_junction=np.array([wp.is_junction for wp in coarse], dtype=bool),
        town=town, index=start_index, end_index=end_index, config=config, _saved_index=start_index,
    )  # fmt: skip
    if parking_wp is not None:
        # the ego's own lane (parking/shoulder) at the start, whatever the nearest driving lane is
        dense.set_waypoint(0, parking_wp)
    _compute_lights(dense, lights, config)
    _compute_stop_signs(dense, town, signs, config)
    _compute_speed_limits(dense, town, config)
    _prevent_too_early_lane_changes(dense, config)
    log.debug("dense route: %d points, start index %d", len(dense), start_index)
    return dense


def _compute_lights(dense: DenseRoute, lights: Mapping[int, TrafficLightInfo], config: ExpertConfig) -> None:
    """Next light and the route distance to its stop line per point (scan backwards, §1.2 step 4)."""
    n = len(dense)
    sees: list[tuple[int, np.ndarray]] = []
    for light_id in sorted(lights):
        mask = light_governs_mask(config, dense.original_points, dense.headings, lights[light_id])
        if mask.any():
            sees.append((light_id, mask))
    next_light: int | None = None
    distance = math.inf
    recorded = False
    for i in range(n - 1, -1, -1):
        found = [light_id for light_id, mask in sees if mask[i]]
        if found:
            if not recorded:
                distance = 0.0
                next_light = found[0]
            else:
                distance += 1.0
            recorded = True
        else:
            distance += 1.0
            recorded = False
        dense.next_light[i] = next_light
        dense.light_distance[i] = distance / config.points_per_meter
    # the route's last metres never report a light (there is nothing to stop for after the end)
    tail = config.points(config.traffic_light_route_end_margin)
    if tail:
        dense.light_distance[-tail:] = np.inf
        dense.next_light[-tail:] = [None] * min(tail, n)


def _compute_stop_signs(dense: DenseRoute, town: Map, signs: Mapping[int, TrafficSignInfo],
                        config: ExpertConfig) -> None:
    """Stop sign governing each point (RunningStopTest's membership test), then distances by a backward scan."""
    stops = [(i, signs[i]) for i in sorted(signs) if signs[i].type_id.startswith("traffic.stop")]
    if not stops:
        return
    centres = np.array([stop_sign_centre(sign) for _, sign in stops])
    n = len(dense)
    belongs: list[int | None] = [None] * n
    for i in range(n):
        p = dense.original_points[i]
        if np.min(np.linalg.norm(centres - p[None, :], axis=1)) >= config.stop_sign_max_distance:
            continue
        for sign_id, sign in stops:
            if stop_sign_affects(town, p, sign):
                belongs[i] = sign_id
                break
    next_stop: int | None = None
    distance = math.inf
    for i in range(n - 1, -1, -1):
        if belongs[i] is not None:
            next_stop = belongs[i]
            distance = 0.0
        else:
            distance += 1.0
        dense.next_stop[i] = next_stop
        dense.stop_distance[i] = distance / config.points_per_meter


def _compute_speed_limits(dense: DenseRoute, town: Map, config: ExpertConfig) -> None:
    """Map speed limit (m/s), looked up every 5 m along the route and held in between."""
    every = max(1, config.points(config.speed_limit_spacing))
    limit = 50.0 / 3.6
    for i in range(len(dense)):
        if i % every == 0:
            limit = float(town.speed_limit(dense.coarse_waypoints[i])) / 3.6
        dense.speed_limits[i] = limit


def _prevent_too_early_lane_changes(dense: DenseRoute, config: ExpertConfig) -> None:
    """Keep the route on the previous lane while the lane it enters is still narrower than 2.5 m (§1.2 step 5).

    Widths come from the 1 m route; only where the rule fires are the dense points' own waypoints looked up.
    """
    threshold = config.minimum_lane_width
    width = np.array([wp.lane_width for wp in dense.coarse_waypoints])
    n = len(dense)
    i = 0
    while i < n - 2:
        if not (width[i + 1] < threshold and width[i + 2] < threshold and width[i + 1] < width[i + 2]):
            i += 1
            continue
        to_left = dense.commands[i] == RoadOption.CHANGELANELEFT
        j = i + 1
        while j < n and dense.waypoint(j).lane_width < threshold:
            own = dense.waypoint(j)
            other = own.get_right_lane() if to_left else own.get_left_lane()
            wp = other if other is not None else own
            dense.set_waypoint(j, wp)
            dense.points[j] = _xyz(wp)
            dense.original_points[j] = _xyz(wp)
            j += 1
        i = max(i + 1, j - 1)
