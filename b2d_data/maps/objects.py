"""Road objects and mark lines for meshing: crosswalk polygons and road-mark polylines in CARLA's frame."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.maps.geometry import evaluate_cubic, evaluate_reference_line
from b2d_data.maps.lane_types import LaneMarking, LaneMarkingType
from b2d_data.maps.lanes import MarkSpan, centre_lane_marks
from b2d_data.maps.opendrive_parser import ObjectRecord, RoadRecord

if TYPE_CHECKING:
    from b2d_data.maps.map import Map


@dataclass(frozen=True)
class Crosswalk:
    """A crosswalk outline: ``polygon`` (N, 3) world points, not repeating the first point at the end."""

    id: str
    road_id: int
    name: str
    polygon: np.ndarray


@dataclass(frozen=True)
class RoadMarkLine:
    """A painted (or curb/grass) line: one mark span of one lane border, as an (N, 3) polyline.

    ``lane_id`` is the lane whose outer border carries the mark, or 0 for a section's centre line.
    """

    road_id: int
    section_id: int
    lane_id: int
    marking: LaneMarking
    points: np.ndarray


def object_outline(road: RoadRecord, obj: ObjectRecord) -> np.ndarray:
    """World (CARLA) polygon of an object's outline (cornerLocal around the object pose, or cornerRoad)."""
    if obj.outline_road:
        s = np.array([c[0] for c in obj.outline_road])
        t = np.array([c[1] for c in obj.outline_road])
        dz = np.array([c[2] for c in obj.outline_road])
        x, y, hdg, _ = evaluate_reference_line(road.geometries, s)
        z, _ = evaluate_cubic(road.elevations, s)
        return np.column_stack([x - t * np.sin(hdg), -(y + t * np.cos(hdg)), z + dz])
    s = min(max(obj.s, 0.0), road.length)
    x, y, hdg, _ = evaluate_reference_line(road.geometries, np.array([s]))
    z, _ = evaluate_cubic(road.elevations, np.array([s]))
    h = float(hdg[0])
    ox, oy = float(x[0]) - obj.t * math.sin(h), float(y[0]) + obj.t * math.cos(h)
    oz = float(z[0]) + obj.z_offset
    heading = h + obj.hdg
    c, sn = math.cos(heading), math.sin(heading)
    pts = np.array(obj.outline, dtype=np.float64)
    wx = ox + pts[:, 0] * c - pts[:, 1] * sn
    wy = oy + pts[:, 0] * sn + pts[:, 1] * c
    return np.column_stack([wx, -wy, oz + pts[:, 2]])


def crosswalks(map_: Map) -> list[Crosswalk]:
    """Every object of type ``crosswalk`` that has an outline."""
    result = []
    for road in map_.data.roads:
        for obj in road.objects:
            if obj.type.lower() != "crosswalk" or not (obj.outline or obj.outline_road):
                continue
            polygon = object_outline(road, obj)
            if len(polygon) > 1 and np.allclose(polygon[0], polygon[-1]):
                polygon = polygon[:-1]
            result.append(Crosswalk(obj.id, road.id, obj.name, polygon))
    return result


def _span_points(s_grid: np.ndarray, border: np.ndarray, span: MarkSpan, resolution: float) -> np.ndarray | None:
    lo, hi = max(span.s_start, s_grid[0]), min(span.s_end, s_grid[-1])
    if hi - lo <= 1e-6:
        return None
    n = max(1, int(math.ceil((hi - lo) / resolution)))
    s = np.linspace(lo, hi, n + 1)
    return np.column_stack([np.interp(s, s_grid, border[:, j]) for j in range(3)])


def road_mark_lines(map_: Map, resolution: float = 0.5) -> list[RoadMarkLine]:
    """Each lane's outer-border marks and each section's centre-line marks, skipping type NONE."""
    result = []
    centre_done: set[tuple[int, int]] = set()
    for seg in map_.lane_segments():
        for span in seg.marks:
            if span.marking.type == LaneMarkingType.NONE:
                continue
            pts = _span_points(seg.s, seg.outer, span, resolution)
            if pts is not None:
                result.append(RoadMarkLine(seg.road_id, seg.section_id, seg.lane_id, span.marking, pts))
        if abs(seg.lane_id) != 1 or (seg.road_id, seg.section_id) in centre_done:
            continue
        centre_done.add((seg.road_id, seg.section_id))
        section = map_.data.road(seg.road_id).sections[seg.section_id]
        for span in centre_lane_marks(section, seg.s1):
            if span.marking.type == LaneMarkingType.NONE:
                continue
            pts = _span_points(seg.s, seg.inner, span, resolution)
            if pts is not None:
                result.append(RoadMarkLine(seg.road_id, seg.section_id, 0, span.marking, pts))
    return result
