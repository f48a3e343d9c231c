"""carla.Map over an OpenDRIVE file: waypoint queries, topology, junctions, signals, routes, HD-map export.

Semantics follow CARLA 0.9.15's ``carla::road::Map`` (LibCarla) and its Python ``carla.Map``/``carla.Waypoint``;
the frame is CARLA's (OpenDRIVE y flipped once when lanes are sampled).
"""

from __future__ import annotations

import copy
import logging
import math
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, wrap_degrees
from b2d_data.maps.geolocation import GeoLocation, GeoReference
from b2d_data.maps.junction import Junction
from b2d_data.maps.lane_graph import LaneKey, link_lanes
from b2d_data.maps.lane_index import LaneIndex
from b2d_data.maps.lane_types import LaneChange, LaneMarking, LaneType
from b2d_data.maps.lanes import (
    EPSILON,
    PITCH,
    WIDTH,
    YAW,
    LaneSegment,
    MarkSpan,
    centre_lane_marks,
    mark_at,
    sample_road,
)
from b2d_data.maps.opendrive_parser import OpenDriveData, parse_opendrive
from b2d_data.maps.waypoint import Waypoint

if TYPE_CHECKING:
    from b2d_data.maps.objects import Crosswalk, RoadMarkLine
    from b2d_data.maps.signals import Controller, Signal

logger = logging.getLogger(__name__)

PointLike = Location | Sequence[float] | np.ndarray


def _as_location(point: PointLike) -> Location:
    if isinstance(point, Location):
        return point
    return Location.from_array(point)


@dataclass(frozen=True)
class LaneGeometry:
    """One lane section's lane for meshing, sampled at increasing road ``s``.

    On lanes with positive ids traffic runs from the last point to the first. ``left``/``right`` are the borders
    seen along the driving direction (``right`` is always the lane's outer border). ``right_marks`` are the lane's
    own road marks, ``left_marks`` those of its inner neighbour (or the centre lane), as (start index, end index,
    marking) into the polylines.
    """

    road_id: int
    section_id: int
    lane_id: int
    lane_type: LaneType
    is_junction: bool
    junction_id: int
    s: np.ndarray
    centre: np.ndarray
    left: np.ndarray
    right: np.ndarray
    width: np.ndarray
    left_marks: tuple[tuple[int, int, LaneMarking], ...]
    right_marks: tuple[tuple[int, int, LaneMarking], ...]

    @property
    def length(self) -> float:
        """Length along road s."""
        return float(self.s[-1] - self.s[0]) if len(self.s) else 0.0


class Map:
    """A loaded OpenDRIVE town (see :func:`load_opendrive`)."""

    def __init__(self, data: OpenDriveData, name: str | None = None) -> None:
        self.data = data
        self.path: Path | None = data.path
        self.name: str = name or (data.path.stem if data.path else (data.name or "OpenDRIVE"))
        self.geo_reference = GeoReference.parse(data.geo_reference)
        segments: list[LaneSegment] = []
        self._by_road: dict[int, list[int]] = {}
        for road in data.roads:
            road_segments = sample_road(road, len(segments))
            self._by_road[road.id] = [seg.index for seg in road_segments]
            segments.extend(road_segments)
        self._segments = segments
        self._index: dict[LaneKey, int] = {seg.key: seg.index for seg in segments}
        link_lanes(data, segments, self._index)
        self._inner_marks: list[list[MarkSpan]] = []
        centre_cache: dict[tuple[int, int], list[MarkSpan]] = {}
        for seg in segments:
            inner_id = seg.lane_id - 1 if seg.lane_id > 0 else seg.lane_id + 1
            if inner_id == 0:
                key = (seg.road_id, seg.section_id)
                if key not in centre_cache:
                    road = data.road(seg.road_id)
                    centre_cache[key] = centre_lane_marks(road.sections[seg.section_id], seg.s1)
                self._inner_marks.append(centre_cache[key])
            else:
                inner = self._index.get((seg.road_id, seg.section_id, inner_id))
                self._inner_marks.append(segments[inner].marks if inner is not None else [])
        self._lane_index = LaneIndex(segments)
        self.junctions: dict[int, Junction] = self._build_junctions()
        #: Junctions given CARLA-style traffic lights the file lacks (:meth:`with_junction_lights`).
        self.generated_light_junctions: tuple[int, ...] = ()
        logger.debug("map %s: %d roads, %d lane segments", self.name, len(data.roads), len(segments))

    # ------------------------------------------------------------------ waypoints

    def _waypoint_at(self, segment: int, s: float) -> Waypoint:
        seg = self._segments[segment]
        row = seg.interpolate(s)
        transform = Transform(
            Location(float(row[0]), float(row[1]), float(row[2])),
            Rotation(pitch=float(row[PITCH]), yaw=wrap_degrees(float(row[YAW])), roll=0.0),
        )
        right = seg.mark_at(s)
        left = mark_at(self._inner_marks[segment], s)
        return Waypoint(
            seg.road_id, seg.section_id, seg.lane_id, s, transform, float(row[WIDTH]), seg.lane_type,
            seg.junction_id != -1, seg.junction_id, _lane_change(seg.lane_id, right, left), left, right, self, segment,
        )  # fmt: skip

    def _start_s(self, segment: int) -> float:
        seg = self._segments[segment]
        return seg.s0 + 10 * EPSILON if seg.forward else seg.s1 - 10 * EPSILON

    def _end_s(self, segment: int) -> float:
        seg = self._segments[segment]
        return seg.s1 - 10 * EPSILON if seg.forward else seg.s0 + 10 * EPSILON

    def get_waypoint(
        self, location: PointLike, project_to_road: bool = True, lane_type: LaneType = LaneType.DRIVING
    ) -> Waypoint | None:
        """Waypoint on the closest lane centre of a type in ``lane_type``.

        With ``project_to_road=False`` the location must lie inside that lane (within half its width in the
        horizontal plane), else ``None`` — CARLA's rule.
        """
        # The ego's lane is asked for several times a tick (route criteria, the expert), and at the same place tick
        # after tick while it waits: the last answer per argument pair is kept, keyed on the coordinates' bits.
        loc = _as_location(location)
        key = _COORDINATE_BITS(loc.x, loc.y, loc.z)
        memo = self.__dict__.setdefault("_waypoint_memo", {})
        last = memo.get((project_to_road, lane_type))
        if last is not None and last[0] == key:
            return last[1]
        waypoint = self._lookup_waypoint(loc, project_to_road, lane_type)
        memo[(project_to_road, lane_type)] = (key, waypoint)
        return waypoint

    def _lookup_waypoint(self, loc: Location, project_to_road: bool, lane_type: LaneType) -> Waypoint | None:
        """:meth:`get_waypoint` without the memo."""
        found = self._lane_index.nearest(np.array([loc.x, loc.y, loc.z]), int(lane_type))
        if found is None:
            return None
        segment, s, _ = found
        seg = self._segments[segment]
        s = min(max(s, seg.s0 + EPSILON), seg.s1 - EPSILON) if seg.s1 - seg.s0 > 2 * EPSILON else seg.s0
        waypoint = self._waypoint_at(segment, s)
        if not project_to_road and waypoint.transform.location.distance_2d(loc) >= 0.5 * waypoint.lane_width:
            return None
        return waypoint

    def lane_keys(
        self, locations: Sequence[PointLike], lane_type: LaneType = LaneType.DRIVING
    ) -> list[tuple[int, int, int] | None]:
        """``(road_id, lane_id, section_id)`` of :meth:`get_waypoint` at each location (``None`` where it is).

        One KD-tree query for all of them, and no waypoint built: what a frame's annotation needs of each box.
        """
        if not len(locations):
            return []
        points = np.array([(loc.x, loc.y, loc.z) for loc in map(_as_location, locations)], dtype=np.float64)
        out: list[tuple[int, int, int] | None] = []
        for found in self._lane_index.nearest_many(points, int(lane_type)):
            if found is None:
                out.append(None)
            else:
                seg = self._segments[found[0]]
                out.append((seg.road_id, seg.lane_id, seg.section_id))
        return out

    def get_waypoint_xodr(self, road_id: int, lane_id: int, s: float) -> Waypoint | None:
        """Waypoint at OpenDRIVE (road, lane, s), or ``None`` when outside the road or the lane is absent."""
        if not self.data.has_road(road_id):
            return None
        road = self.data.road(road_id)
        if s < 0.0 or s >= road.length:
            return None
        for section_id in range(len(road.sections)):
            segment = self._index.get((road_id, section_id, lane_id))
            if segment is None:
                continue
            seg = self._segments[segment]
            last = section_id == len(road.sections) - 1
            if seg.s0 <= s < seg.s1 or (last and s <= seg.s1):
                return self._waypoint_at(segment, s)
        return None

    def _step(self, waypoint: Waypoint, distance: float, forward: bool) -> list[Waypoint]:
        if not distance > 0.0:
            raise ValueError(f"{self.name}: waypoint step distance must be > 0, got {distance}")
        return [self._waypoint_at(i, s) for i, s in self._advance(waypoint.segment, waypoint.s, distance, forward)]

    def _advance(
        self, segment: int, s: float, distance: float, forward: bool, depth: int = 0
    ) -> list[tuple[int, float]]:
        """CARLA's GetNext / GetPrevious on (segment, s): same lane while it lasts, else every successor."""
        seg = self._segments[segment]
        along = seg.forward if forward else not seg.forward  # True: s grows
        remaining = seg.s1 - s if along else s - seg.s0
        if distance <= remaining:
            return [(segment, s + distance - EPSILON if along else s - distance + EPSILON)]
        if depth > 512:
            logger.warning("%s: lane walk stopped after 512 zero-length lanes at %s", self.name, seg.key)
            return []
        result: list[tuple[int, float]] = []
        neighbours = seg.successors if forward else seg.predecessors
        for other in neighbours:
            start = self._start_s(other) if forward else self._end_s(other)
            result = _concat(result, self._advance(other, start, distance - remaining, forward, depth + 1))
        return result

    def _until_road_end(self, waypoint: Waypoint, distance: float, forward: bool) -> list[Waypoint]:
        result: list[Waypoint] = []
        step = waypoint.next if forward else waypoint.previous
        nxt = step(distance)
        while len(nxt) == 1 and nxt[0].road_id == waypoint.road_id:
            result.append(nxt[0])
            nxt = (nxt[0].next if forward else nxt[0].previous)(distance)
        current = result[-1].s if result else waypoint.s
        length = self.data.road(waypoint.road_id).length
        # CARLA measures the rest against the road ends by lane sign, whichever way it walks.
        remaining = (length - current if waypoint.lane_id < 0 else current) - 2.220446049250313e-16
        if remaining > 0:
            last = result[-1] if result else waypoint
            tail = (last.next if forward else last.previous)(remaining)
            if tail:
                result.append(tail[0])
        return result

    def _neighbour(self, waypoint: Waypoint, lane_id: int) -> Waypoint | None:
        segment = self._index.get((waypoint.road_id, waypoint.section_id, lane_id))
        if segment is None:
            return None
        return self._waypoint_at(segment, waypoint.s)

    def generate_waypoints(self, distance: float) -> list[Waypoint]:
        """Waypoints every ``distance`` metres along every road, on each driving lane (CARLA's order)."""
        if not distance > 0.0:
            raise ValueError(f"{self.name}: generate_waypoints distance must be > 0, got {distance}")
        result = []
        for road in self.data.roads:
            sections = [
                [i for i in self._road_segments(road.id) if self._segments[i].section_id == sid]
                for sid in range(len(road.sections))
            ]
            s = EPSILON
            while s < road.length - EPSILON:
                for sid, segs in enumerate(sections):
                    if not segs:
                        continue
                    seg0 = self._segments[segs[0]]
                    last = sid == len(sections) - 1
                    if seg0.s0 <= s < seg0.s1 or (last and s <= seg0.s1):
                        for i in segs:
                            if self._segments[i].lane_type & LaneType.DRIVING:
                                result.append(self._waypoint_at(i, s))
                        break
                s += distance
        return result

    def _road_segments(self, road_id: int) -> list[int]:
        return self._by_road.get(road_id, [])

    def lane_start(self, road_id: int, section_id: int, lane_id: int) -> Waypoint | None:
        """Waypoint at the start (in driving direction) of a lane section's lane."""
        segment = self._index.get((road_id, section_id, lane_id))
        return None if segment is None else self._waypoint_at(segment, self._start_s(segment))

    def lane_end(self, road_id: int, section_id: int, lane_id: int) -> Waypoint | None:
        """Waypoint at the end (in driving direction) of a lane section's lane."""
        segment = self._index.get((road_id, section_id, lane_id))
        return None if segment is None else self._waypoint_at(segment, self._end_s(segment))

    def get_topology(self) -> list[tuple[Waypoint, Waypoint]]:
        """(lane start, successor lane start) for every driving lane of every lane section (CARLA's topology)."""
        result = []
        for seg in self._segments:
            if not seg.lane_type & LaneType.DRIVING:
                continue
            start = self._waypoint_at(seg.index, self._start_s(seg.index))
            for other in seg.successors:
                result.append((start, self._waypoint_at(other, self._start_s(other))))
        return result

    def get_spawn_points(self, spacing: float = 30.0, height: float = 0.5) -> list[Transform]:
        """Poses on driving lanes outside junctions, every ``spacing`` m from ``spacing``/2, raised by ``height``.

        Lanes shorter than that get one point at their middle (if at least 4 m long); lane ends are avoided so that
        a spawn point is never ambiguous between two lanes.
        """
        if not spacing > 0:
            raise ValueError(f"{self.name}: spawn point spacing must be > 0, got {spacing}")
        result = []
        for seg in self._segments:
            if not seg.lane_type & LaneType.DRIVING or seg.junction_id != -1 or seg.length < 4.0:
                continue
            if float(np.min(seg.data[:, WIDTH])) < 2.0:
                continue  # lanes that open or close are no place to put a car
            offsets = np.arange(spacing / 2, seg.length - 1.0, spacing)
            if len(offsets) == 0:
                offsets = np.array([seg.length / 2])
            for off in offsets:
                s = seg.s0 + off if seg.forward else seg.s1 - off
                wp = self._waypoint_at(seg.index, min(max(s, seg.s0 + EPSILON), seg.s1 - EPSILON))
                loc = wp.transform.location
                result.append(Transform(Location(loc.x, loc.y, loc.z + height), wp.transform.rotation))
        return result

    # ------------------------------------------------------------------ junctions

    def _build_junctions(self) -> dict[int, Junction]:
        junctions: dict[int, Junction] = {}
        members: dict[int, list[int]] = {}
        for road in self.data.roads:
            if road.junction != -1:
                members.setdefault(road.junction, []).append(road.id)
        for junction_id in sorted(set(members) | set(self.data.junctions)):
            record = self.data.junctions.get(junction_id)
            roads: list[int] = []
            if record is not None:
                for connection in record.connections:
                    if connection.connecting_road not in roads and self.data.has_road(connection.connecting_road):
                        roads.append(connection.connecting_road)
            for road_id in members.get(junction_id, []):
                if road_id not in roads:
                    roads.append(road_id)
            points = [self._segments[i].data[:, :3] for r in roads for i in self._road_segments(r)]
            if points:
                allp = np.concatenate(points)
                lo, hi = allp.min(axis=0), allp.max(axis=0)
            else:
                lo = hi = np.zeros(3)
            box = BoundingBox(Location.from_array((lo + hi) / 2), Location.from_array((hi - lo) / 2))
            controllers = tuple(c for c, _ in record.controllers) if record is not None else ()
            junctions[junction_id] = Junction(
                junction_id, record.name if record else "", box, tuple(roads), controllers, self
            )
        return junctions

    def _junction_waypoints(self, junction: Junction, lane_type: LaneType) -> list[tuple[Waypoint, Waypoint]]:
        result = []
        for road_id in junction.connecting_roads:
            for i in self._road_segments(road_id):
                if self._segments[i].lane_type & lane_type:
                    result.append((self._waypoint_at(i, self._start_s(i)), self._waypoint_at(i, self._end_s(i))))
        return result

    # ------------------------------------------------------------------ geometry for meshing

    def lane_geometry(self, resolution: float = 0.5, lane_type: LaneType = LaneType.ANY) -> list[LaneGeometry]:
        """Every lane section's lane resampled every ``resolution`` m along road s (ends included)."""
        result = []
        for seg in self._segments:
            if not seg.lane_type & lane_type and not (lane_type & LaneType.NONE and seg.lane_type == LaneType.NONE):
                continue
            n = max(1, int(math.ceil(seg.length / resolution))) if seg.length > 0 else 1
            s = np.linspace(seg.s0, seg.s1, n + 1)
            centre = _interp_rows(s, seg.s, seg.data[:, :3])
            inner = _interp_rows(s, seg.s, seg.inner)
            outer = _interp_rows(s, seg.s, seg.outer)
            width = np.interp(s, seg.s, seg.data[:, WIDTH])
            result.append(
                LaneGeometry(
                    seg.road_id, seg.section_id, seg.lane_id, seg.lane_type, seg.junction_id != -1, seg.junction_id,
                    s.copy(), centre, inner, outer, width,
                    _mark_ranges(self._inner_marks[seg.index], s), _mark_ranges(seg.marks, s),
                )  # fmt: skip
            )
        return result

    def road_marks(self, resolution: float = 0.5) -> list[RoadMarkLine]:
        """Every visible road-mark line once: lanes' outer borders plus each section's centre line."""
        from b2d_data.maps.objects import road_mark_lines

        return road_mark_lines(self, resolution)

    def crosswalks(self) -> list[Crosswalk]:
        """Crosswalk ``<object>`` outlines as world polygons."""
        from b2d_data.maps.objects import crosswalks

        return crosswalks(self)

    # ------------------------------------------------------------------ signals

    @cached_property
    def _signals(self):
        from b2d_data.maps.signals import build_signals

        return build_signals(self)

    def signals(self) -> list[Signal]:
        """Every OpenDRIVE ``<signal>`` with its governed lanes, stop waypoints and trigger boxes."""
        return list(self._signals.signals)

    def signal(self, signal_id: str) -> Signal | None:
        """The OpenDRIVE signal with this id, or ``None``."""
        return self._signals.by_id.get(str(signal_id))

    def traffic_lights(self) -> list[Signal]:
        """Signals of CARLA's traffic-light type (1000001)."""
        return [s for s in self._signals.signals if s.is_traffic_light]

    def stop_signs(self) -> list[Signal]:
        """Stop signs (OpenDRIVE type 206)."""
        return [s for s in self._signals.signals if s.is_stop]

    def yield_signs(self) -> list[Signal]:
        """Yield signs (OpenDRIVE type 205)."""
        return [s for s in self._signals.signals if s.is_yield]

    def speed_limit_signs(self) -> list[Signal]:
        """Speed-limit signs: type-274 signals plus speed-limit sign objects (``Speed_30``...)."""
        return list(self._signals.speed_signs)

    def controllers(self) -> list[Controller]:
        """Signal controllers (traffic-light phases) with their junction and sequence."""
        return list(self._signals.controllers)

    def traffic_light_groups(self) -> dict[str, tuple[str, ...]]:
        """Controller id → ids of the signals it switches."""
        return {c.id: c.signal_ids for c in self._signals.controllers}

    def governing_signals(self, waypoint: Waypoint) -> list[Signal]:
        """Signals whose trigger box lies on the waypoint's lane (same road, section and lane)."""
        return self._signals.governing(waypoint)

    def with_junction_lights(self, junction_ids: Iterable[int]) -> Map:
        """This town with CARLA-style traffic lights added at these junctions (``b2d_data.maps.generated_lights``).

        A copy, not a change: the town a process caches stays as its file says, so a route that needs the lights
        does not hand them to the next route that process runs. The copy shares the lane geometry and rebuilds what
        holds waypoints (junctions, signals, the route graph), since waypoints compare equal only on one map.
        """
        wanted = tuple(sorted(set(self.generated_light_junctions) | {int(j) for j in junction_ids}))
        if wanted == self.generated_light_junctions:
            return self
        unknown = [j for j in wanted if j not in self.junctions]
        if unknown:
            raise KeyError(f"{self.name} has no junction {unknown[0]}")
        clone = copy.copy(self)
        for cached in ("_signals", "_route_graph", "_waypoint_memo"):
            clone.__dict__.pop(cached, None)
        clone.generated_light_junctions = wanted
        clone.junctions = clone._build_junctions()
        logger.info("%s: traffic lights added at junction(s) %s", self.name, ", ".join(map(str, wanted)))
        return clone

    def speed_limit(self, waypoint: Waypoint) -> float:
        """Speed limit (km/h) at a waypoint: last speed sign passed, else lane/road speed, else 50."""
        return self._signals.speed_limit(waypoint)

    # ------------------------------------------------------------------ routes

    @cached_property
    def _route_graph(self):
        from b2d_data.maps.route_planner import RouteGraph

        return RouteGraph(self, 1.0)

    def route_graph(self, resolution: float = 1.0):
        """The GlobalRoutePlanner graph at ``resolution`` (built once for 1 m, the leaderboard's hop)."""
        from b2d_data.maps.route_planner import RouteGraph

        if resolution == 1.0:
            return self._route_graph
        return RouteGraph(self, resolution)

    def trace_route(self, origin: PointLike, destination: PointLike) -> list[tuple[Waypoint, RoadOption]]:
        """GlobalRoutePlanner.trace_route at 1 m: ``[(waypoint, RoadOption)]`` from origin to destination."""
        from b2d_data.maps.route_planner import RoutePlanner

        return RoutePlanner(self._route_graph).trace_route(_as_location(origin), _as_location(destination))

    def interpolate_trajectory(
        self, keypoints: Iterable[PointLike], hop_resolution: float = 1.0
    ) -> list[tuple[Waypoint, RoadOption]]:
        """The leaderboard's densification of route keypoints: trace_route between consecutive distinct points."""
        from b2d_data.maps.route_planner import interpolate_trajectory

        return interpolate_trajectory(self, [_as_location(p) for p in keypoints], hop_resolution)

    # ------------------------------------------------------------------ geolocation and export

    def transform_to_geolocation(self, location: PointLike) -> GeoLocation:
        """CARLA's ``Map.transform_to_geolocation``."""
        return self.geo_reference.transform(_as_location(location))

    def geolocation_to_location(self, latitude: float, longitude: float, altitude: float = 0.0) -> Location:
        """Inverse of :meth:`transform_to_geolocation`."""
        return self.geo_reference.inverse(latitude, longitude, altitude)

    def save_hdmap(self, path: str | Path) -> Path:
        """Write the Bench2Drive HD-map npz (format.md §6) and return its path."""
        from b2d_data.maps.hdmap import save_hdmap

        return save_hdmap(self, Path(path))

    def lane_segments(self) -> list[LaneSegment]:
        """The internal lane-section lanes (read-only use: meshing, debugging)."""
        return list(self._segments)

    def __getstate__(self) -> dict:
        # Derived caches hold waypoints that point back at this map; they are rebuilt on demand after unpickling.
        state = dict(self.__dict__)
        state.pop("_signals", None)
        state.pop("_route_graph", None)
        state.pop("_waypoint_memo", None)
        return state

    def __repr__(self) -> str:
        return f"Map({self.name!r}, roads={len(self.data.roads)}, lanes={len(self._segments)})"


#: The exact bits of a location (−0.0 and 0.0 differ), the key of :meth:`Map.get_waypoint`'s memo.
_COORDINATE_BITS = struct.Struct("<3d").pack


def _concat(dst: list, src: list) -> list:
    # CARLA's ConcatVectors appends the shorter list to the longer one; the order of branches follows from it.
    if len(src) > len(dst):
        dst, src = src, dst
    return dst + src


def _lane_change(lane_id: int, right: LaneMarking | None, left: LaneMarking | None) -> LaneChange:
    """carla.Waypoint.lane_change from the two markings (missing marking → both)."""
    c_right = right.lane_change if right is not None else LaneChange.BOTH
    c_left = left.lane_change if left is not None else LaneChange.BOTH
    swap = {LaneChange.RIGHT: LaneChange.LEFT, LaneChange.LEFT: LaneChange.RIGHT}
    if lane_id > 0:
        c_right = swap.get(c_right, c_right)
    if (lane_id - 1 if lane_id > 0 else lane_id + 1) > 0:
        c_left = swap.get(c_left, c_left)
    return LaneChange((c_right & LaneChange.RIGHT) | (c_left & LaneChange.LEFT))


def _interp_rows(x: np.ndarray, xp: np.ndarray, rows: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(x, xp, rows[:, j]) for j in range(rows.shape[1])])


def _mark_ranges(marks: list[MarkSpan], s: np.ndarray) -> tuple[tuple[int, int, LaneMarking], ...]:
    """Index ranges of the ascending ``s`` covered by each mark span."""
    ranges = []
    for span in marks:
        inside = np.nonzero((s >= span.s_start - 1e-9) & (s <= span.s_end + 1e-9))[0]
        if len(inside):
            ranges.append((int(inside[0]), int(inside[-1]), span.marking))
    return tuple(ranges)


def load_opendrive(path: str | Path, name: str | None = None) -> Map:
    """Load an OpenDRIVE file (or XML text) into a :class:`Map`; ``name`` defaults to the file stem."""
    return Map(parse_opendrive(path), name)
