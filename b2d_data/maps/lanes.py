"""Lane sections sampled into polylines in CARLA's frame.

A :class:`LaneSegment` is one lane of one lane section (CARLA's unit for waypoints and topology). It holds samples
at increasing road ``s``: lane centre, its two borders, the driving-direction yaw and pitch, and the width. Lateral
positions follow OpenDRIVE: ``laneOffset`` shifts the centre lane; left lanes (positive ids) stack outwards to
``+t``, right lanes to ``-t``; a lane described by ``<border>`` records takes its outer border directly. The frame
flip to CARLA (y → −y, heading → −yaw) happens here, once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from b2d_data.maps.geometry import evaluate_cubic, evaluate_reference_line, max_curvature
from b2d_data.maps.lane_types import LaneMarking, LaneType
from b2d_data.maps.opendrive_parser import LaneRecord, LaneSectionRecord, RoadRecord

#: Largest sampling step along a lane (m); tighter curves get a finer step (see :func:`sampling_step`).
MAX_STEP = 0.5
#: Chord-to-arc deviation (m) tolerated between samples.
CHORD_TOLERANCE = 0.002

#: CARLA's EPSILON in ``carla::road::Map`` (10 × DBL_EPSILON): keeps waypoints off lane-section edges.
EPSILON = 10.0 * 2.220446049250313e-16

# Columns of LaneSegment.data.
X, Y, Z, YAW, PITCH, WIDTH = range(6)


@dataclass(frozen=True, slots=True)
class MarkSpan:
    """A road mark valid on a lane border from road ``s_start`` to ``s_end``."""

    s_start: float
    s_end: float
    marking: LaneMarking


@dataclass
class LaneSegment:
    """One lane of one lane section, sampled. ``data`` columns: x, y, z, yaw (deg, unwrapped), pitch, width.

    ``inner``/``outer`` are the borders towards / away from the centre lane; seen along the driving direction the
    outer border is always on the right. ``marks`` are this lane's own road marks (its outer border).
    """

    index: int
    road_id: int
    section_id: int
    lane_id: int
    lane_type: LaneType
    s0: float
    s1: float
    junction_id: int
    s: np.ndarray
    data: np.ndarray
    inner: np.ndarray
    outer: np.ndarray
    marks: list[MarkSpan]
    speeds: list[tuple[float, float]]
    successors: list[int] = field(default_factory=list)
    predecessors: list[int] = field(default_factory=list)

    @property
    def key(self) -> tuple[int, int, int]:
        """(road_id, section_id, lane_id)."""
        return (self.road_id, self.section_id, self.lane_id)

    @property
    def length(self) -> float:
        """Length of the lane section along road s."""
        return self.s1 - self.s0

    @property
    def forward(self) -> bool:
        """True when traffic runs with increasing s (lane id ≤ 0, CARLA's rule)."""
        return self.lane_id <= 0

    def sample_index(self, s: float) -> tuple[int, float]:
        """Index ``i`` and fraction ``f`` with ``s`` between samples ``i`` and ``i + 1``."""
        arr = self.s
        n = len(arr)
        if n == 1:
            return 0, 0.0
        i = int(np.searchsorted(arr, s, side="right")) - 1
        i = min(max(i, 0), n - 2)
        ds = arr[i + 1] - arr[i]
        f = (s - arr[i]) / ds if ds > 0 else 0.0
        return i, min(max(f, 0.0), 1.0)

    def interpolate(self, s: float) -> np.ndarray:
        """The ``data`` row at road ``s`` (linear between samples)."""
        i, f = self.sample_index(s)
        row = self.data[i]
        if f == 0.0 or len(self.s) == 1:
            return row.copy()
        return row + (self.data[i + 1] - row) * f

    def mark_at(self, s: float) -> LaneMarking | None:
        """This lane's road mark (outer border) at road ``s``; ``None`` without marks."""
        return mark_at(self.marks, s)


def mark_at(marks: list[MarkSpan], s: float) -> LaneMarking | None:
    """The last mark span starting at or before ``s`` (the first one before any start)."""
    if not marks:
        return None
    chosen = marks[0]
    for span in marks:
        if span.s_start <= s + 1e-9:
            chosen = span
        else:
            break
    return chosen.marking


def sampling_step(curvature: float) -> float:
    """Step that keeps the chord within :data:`CHORD_TOLERANCE` of a curve of this curvature."""
    if curvature <= 1e-6:
        return MAX_STEP
    # Lanes run up to ~2 lane widths off the reference line, where the radius is smaller: keep a 0.7 margin.
    return float(np.clip(0.7 * math.sqrt(8.0 * CHORD_TOLERANCE / curvature), 0.05, MAX_STEP))


def section_bounds(road: RoadRecord) -> list[tuple[float, float]]:
    """[s0, s1] of every lane section (the last ends at the road length)."""
    bounds = []
    for i, sec in enumerate(road.sections):
        s0 = min(max(sec.s, 0.0), road.length)
        s1 = road.sections[i + 1].s if i + 1 < len(road.sections) else road.length
        bounds.append((s0, max(min(s1, road.length), s0)))
    return bounds


def _section_grid(road: RoadRecord, s0: float, s1: float) -> np.ndarray:
    step = sampling_step(max_curvature(road.geometries, s0, s1))
    n = max(1, int(math.ceil((s1 - s0) / step))) if s1 > s0 else 1
    grid = np.linspace(s0, s1, n + 1)
    # Keep geometry joints as samples so that kinks (line → arc) are reproduced exactly.
    joints = [g.s for g in road.geometries if s0 < g.s < s1]
    if joints:
        grid = np.unique(np.concatenate([grid, joints]))
    return grid


def _lane_extent(lane: LaneRecord, s_local: np.ndarray, inner_abs: np.ndarray, inner_slope: np.ndarray):
    """Width (≥ 0 side distance) and its slope; border records give the outer distance directly."""
    if lane.widths or not lane.borders:
        return evaluate_cubic(lane.widths, s_local)
    outer, outer_slope = evaluate_cubic(lane.borders, s_local)
    return outer - inner_abs, outer_slope - inner_slope


def sample_road(road: RoadRecord, first_index: int) -> list[LaneSegment]:
    """Sample every lane (centre lane excluded) of every section of ``road``."""
    segments: list[LaneSegment] = []
    for section_id, (s0, s1) in enumerate(section_bounds(road)):
        section = road.sections[section_id]
        grid = _section_grid(road, s0, s1)
        x, y, hdg, k = evaluate_reference_line(road.geometries, grid)
        # Road-level cubics may restart exactly at a section end: take the value from the left there, as CARLA
        # does by evaluating lane ends a hair inside the section.
        s_eval = grid.copy()
        if len(s_eval) > 1:
            s_eval[-1] -= min(1e-9, 0.5 * (s_eval[-1] - s_eval[-2]))
        z, dz = evaluate_cubic(road.elevations, s_eval)
        superelevation, _ = evaluate_cubic(road.superelevations, s_eval)
        offset, doffset = evaluate_cubic(road.lane_offsets, s_eval)
        s_local = grid - section.s
        for side in (1, -1):
            ids = sorted((i for i in section.lanes if i * side > 0), key=abs)
            inner_abs = np.zeros_like(grid)  # distance from the centre lane, ≥ 0 for normal widths
            inner_slope = np.zeros_like(grid)
            for lane_id in ids:
                lane = section.lanes[lane_id]
                width, dwidth = _lane_extent(lane, s_local, inner_abs, inner_slope)
                outer_abs, outer_slope = inner_abs + width, inner_slope + dwidth
                segments.append(
                    _make_segment(
                        road, section, section_id, lane, s0, s1, grid, (x, y, hdg, k), (z, dz), superelevation,
                        offset + side * inner_abs, offset + side * outer_abs,
                        doffset + side * 0.5 * (inner_slope + outer_slope), first_index + len(segments),
                    )  # fmt: skip
                )
                inner_abs, inner_slope = outer_abs, outer_slope
    segments.sort(key=lambda seg: (seg.section_id, seg.lane_id))
    for i, seg in enumerate(segments):
        seg.index = first_index + i
    return segments


def _points(x, y, hdg, z, superelevation, t) -> np.ndarray:
    """OpenDRIVE (s, t) samples → CARLA (x, y, z) points."""
    px = x - t * np.sin(hdg)
    py = y + t * np.cos(hdg)
    pz = z + t * np.tan(superelevation)
    return np.stack([px, -py, pz], axis=1)


def _make_segment(
    road, section, section_id, lane, s0, s1, grid, ref, elevation, superelevation, t_inner, t_outer, dt_centre, index
) -> LaneSegment:
    x, y, hdg, k = ref
    z, dz = elevation
    t_centre = 0.5 * (t_inner + t_outer)
    centre = _points(x, y, hdg, z, superelevation, t_centre)
    along = 1.0 - k * t_centre
    heading = hdg + np.arctan2(dt_centre, along)
    forward = lane.id <= 0
    # CARLA yaw is the negated OpenDRIVE heading; left lanes drive the other way.
    yaw = -np.degrees(heading) if forward else 180.0 - np.degrees(heading)
    yaw = np.degrees(np.unwrap(np.radians(yaw)))
    pitch = np.degrees(np.arctan2(dz, np.maximum(np.hypot(along, dt_centre), 1e-9)))
    if not forward:
        pitch = -pitch
    width = np.abs(t_outer - t_inner)
    data = np.column_stack([centre, yaw, pitch, width])
    marks = []
    for i, m in enumerate(lane.road_marks):
        start = section.s + m.s_offset
        end = section.s + lane.road_marks[i + 1].s_offset if i + 1 < len(lane.road_marks) else s1
        marks.append(MarkSpan(start, end, LaneMarking(m.type, m.color, m.width, m.lane_change)))
    speeds = [(section.s + off, kmh) for off, kmh in lane.speeds]
    return LaneSegment(
        index, road.id, section_id, lane.id, lane.type, s0, s1, road.junction, grid.copy(), data,
        _points(x, y, hdg, z, superelevation, t_inner), _points(x, y, hdg, z, superelevation, t_outer), marks, speeds,
    )  # fmt: skip


def centre_lane_marks(section: LaneSectionRecord, s1: float) -> list[MarkSpan]:
    """Road marks of the centre lane (lane 0) of a section: the left marking of lanes ±1."""
    lane = section.lanes.get(0)
    if lane is None:
        return []
    spans = []
    for i, m in enumerate(lane.road_marks):
        start = section.s + m.s_offset
        end = section.s + lane.road_marks[i + 1].s_offset if i + 1 < len(lane.road_marks) else s1
        spans.append(MarkSpan(start, end, LaneMarking(m.type, m.color, m.width, m.lane_change)))
    return spans
