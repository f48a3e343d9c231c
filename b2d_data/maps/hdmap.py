"""Bench2Drive HD-map export (``<Town>_HD_map.npz``, format.md §6; tools/gen_hdmap.py's layout and algorithm).

For every topology start lane (sorted by road id) the walk steps 0.05 m along the lane (``next(0.05)[0]``) while
the road stays the same. Centre points are ``((x, y, z), (roll, pitch, yaw), is_junction)``; the left and right
boundary points are ``((x, y, z), (roll, pitch, yaw))`` shifted by ∓0.5·lane width along the right vector. A new
element starts when the lane id or a side's marking type/colour changes; a side's list is only flushed (and
emptied) when it holds more than one point, so a single leftover point opens the next element, as in the original
script. ``Topology`` lists the driving (road, lane) pairs 0.05 m after the point where an element is flushed.

Two deliberate differences from the released v0 maps: a lane that appears several times in CARLA's topology (once
per successor) is walked once, and a lane section already covered by an earlier walk of the same road is not walked
again — the duplication that Bench2Drive issue #149 reports. The npz is the one ``np.savez_compressed`` writes, only
deflated at zlib level 1 (numpy's default level takes 5× longer for the same size).
"""

from __future__ import annotations

import contextlib
import gc
import logging
import math
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from b2d_data.format.transform import Transform
from b2d_data.maps.lane_types import LaneMarking, LaneMarkingColor, LaneMarkingType, LaneType
from b2d_data.maps.lanes import PITCH, WIDTH, YAW

if TYPE_CHECKING:
    from b2d_data.maps.map import Map
    from b2d_data.maps.waypoint import Waypoint

logger = logging.getLogger(__name__)

#: Step of the walk along each lane (m), as gen_hdmap.py's ``precision``.
PRECISION = 0.05


def _walk(map_: Map, start: int, step: float, covered: set[int]) -> list[tuple[int, np.ndarray]]:
    """(segment, s values) visited by repeated ``next(step)[0]`` from a lane start while the road is the same.

    The walk also stops on entering a lane section already in ``covered`` (it was exported by an earlier walk).
    """
    segments = map_._segments
    seg = segments[start]
    road_id = seg.road_id
    chunks: list[tuple[int, np.ndarray]] = []
    s = map_._start_s(start)
    while True:
        covered.add(seg.index)
        remaining = seg.s1 - s if seg.forward else s - seg.s0
        count = int(math.floor(remaining / step + 1e-9)) if remaining >= 0 else 0
        offsets = np.arange(count + 1) * step
        values = s + offsets if seg.forward else s - offsets
        chunks.append((seg.index, np.clip(values, seg.s0, seg.s1)))
        overshoot = (count + 1) * step - remaining
        # Cross lane ends (possibly several short ones) with the rest of the step, on the first successor.
        while True:
            if not seg.successors:
                return chunks
            seg = segments[seg.successors[0]]
            if seg.road_id != road_id or seg.index in covered:
                return chunks
            if overshoot <= seg.length:
                s = seg.s0 + overshoot if seg.forward else seg.s1 - overshoot
                break
            overshoot -= seg.length
            covered.add(seg.index)


def _walk_starts(map_: Map) -> list[int]:
    """Topology start lanes in gen_hdmap.py's order (sorted by road id), each lane once.

    Lanes that no lane of the same road leads into come first, so that one walk covers a road's chain of lane
    sections; the others follow for whatever the first walks did not reach.
    """
    starts = [seg for seg in map_._segments if seg.lane_type & LaneType.DRIVING and seg.successors]
    starts.sort(key=lambda seg: seg.road_id)
    segments = map_._segments

    def fed_from_same_road(seg) -> bool:
        return any(segments[p].road_id == seg.road_id for p in seg.predecessors)

    heads = [seg.index for seg in starts if not fed_from_same_road(seg)]
    rest = [seg.index for seg in starts if fed_from_same_road(seg)]
    order = {seg.index: k for k, seg in enumerate(starts)}
    return sorted(heads, key=order.__getitem__) + sorted(rest, key=order.__getitem__)


def _marking_key(marking: LaneMarking | None) -> tuple[LaneMarkingType, LaneMarkingColor]:
    if marking is None:
        return (LaneMarkingType.NONE, LaneMarkingColor.WHITE)
    return (marking.type, marking.color)


def _marking_keys(spans, s_values: np.ndarray) -> list[tuple[LaneMarkingType, LaneMarkingColor]]:
    """The (type, colour) of the mark span in force at each s (as :func:`mark_at`), vectorised."""
    if not spans:
        return [_marking_key(None)] * len(s_values)
    starts = np.array([span.s_start for span in spans])
    index = np.clip(np.searchsorted(starts, s_values + 1e-9, side="right") - 1, 0, len(spans) - 1)
    keys = [_marking_key(span.marking) for span in spans]
    return [keys[i] for i in index.tolist()]


class _Points:
    """Per-point arrays and HD-map point tuples of one walk."""

    def __init__(self, map_: Map, chunks: list[tuple[int, np.ndarray]]) -> None:
        self.segment = np.concatenate([np.full(len(s), i) for i, s in chunks])
        self.s = np.concatenate([s for _, s in chunks])
        rows = []
        self.left_keys: list[tuple] = []
        self.right_keys: list[tuple] = []
        for i, s_values in chunks:
            seg = map_._segments[i]
            rows.append(np.column_stack([np.interp(s_values, seg.s, seg.data[:, j]) for j in range(seg.data.shape[1])]))
            self.right_keys += _marking_keys(seg.marks, s_values)
            self.left_keys += _marking_keys(map_._inner_marks[i], s_values)
        data = np.concatenate(rows)
        self.lane = [map_._segments[i].lane_id for i in self.segment.tolist()]
        self.junction = [map_._segments[i].junction_id != -1 for i in self.segment.tolist()]
        xyz = data[:, :3]
        yaw = (data[:, YAW] + 180.0) % 360.0 - 180.0
        half = 0.5 * data[:, WIDTH]
        # CARLA's right vector at roll 0 is (-sin yaw, cos yaw, 0) whatever the pitch.
        right = np.column_stack([-np.sin(np.radians(yaw)), np.cos(np.radians(yaw)), np.zeros_like(yaw)])
        rot = [(0.0, p, y) for p, y in zip(data[:, PITCH].tolist(), yaw.tolist())]
        self.centre = [(tuple(p), r, j) for p, r, j in zip(xyz.tolist(), rot, self.junction)]
        self.left = [(tuple(p), r) for p, r in zip((xyz - right * half[:, None]).tolist(), rot)]
        self.right = [(tuple(p), r) for p, r in zip((xyz + right * half[:, None]).tolist(), rot)]

    def __len__(self) -> int:
        return len(self.s)


def _topology(map_: Map, waypoint: Waypoint) -> list[tuple[int, int]]:
    return [(w.road_id, w.lane_id) for w in waypoint.next(PRECISION) if w.lane_type == LaneType.DRIVING]


def _neighbour(waypoint: Waypoint | None) -> tuple[int | None, int | None]:
    if waypoint is None:
        return (None, None)
    return (waypoint.road_id, waypoint.lane_id)


def _append(road_dict: dict[Any, Any], lane_id: int, element: dict[str, Any]) -> None:
    road_dict.setdefault(lane_id, []).append(element)


def _emit_walk(map_: Map, pts: _Points, hd: dict[int, dict[Any, Any]]) -> None:
    n = len(pts)
    road_id = map_._segments[int(pts.segment[0])].road_id

    def waypoint(k: int) -> Waypoint:
        return map_._waypoint_at(int(pts.segment[k]), float(pts.s[k]))

    events = [0] + [
        k for k in range(1, n)
        if pts.lane[k] != pts.lane[k - 1] or pts.left_keys[k] != pts.left_keys[k - 1]
        or pts.right_keys[k] != pts.right_keys[k - 1]
    ]  # fmt: skip
    centre_start = left_start = right_start = 0

    def centre_element(lo: int, hi: int, flush_at: int) -> dict[str, Any]:
        wps = [bool(j) for j in pts.junction[lo:hi]]
        last = waypoint(hi - 1)
        return {
            "Points": pts.centre[lo:hi], "Type": "Center", "Color": "White",
            "Topology": _topology(map_, waypoint(flush_at)), "TopologyType": _topology_type(wps),
            "Left": _neighbour(last.get_left_lane()), "Right": _neighbour(last.get_right_lane()),
        }  # fmt: skip

    def side_element(points, key, flush_at: int) -> dict[str, Any]:
        return {
            "Points": points, "Type": key[0].carla_name, "Color": key[1].carla_name,
            "Topology": _topology(map_, waypoint(flush_at)),
        }  # fmt: skip

    road_dict = hd.setdefault(road_id, {})
    for k in events:
        lane_changed = k > 0 and pts.lane[k] != pts.lane[k - 1]
        if lane_changed:
            if k - centre_start > 1:
                _append(road_dict, int(pts.lane[k - 1]), centre_element(centre_start, k, k))
            centre_start = k
        if k == 0:
            continue  # the first point always differs from the script's sentinel, but nothing is collected yet
        previous_lane = int(pts.lane[k - 1])
        if lane_changed or pts.left_keys[k] != pts.left_keys[k - 1]:
            if k - left_start > 1:
                _append(road_dict, previous_lane, side_element(pts.left[left_start:k], pts.left_keys[k - 1], k))
                left_start = k
        if lane_changed or pts.right_keys[k] != pts.right_keys[k - 1]:
            if k - right_start > 1:
                _append(road_dict, previous_lane, side_element(pts.right[right_start:k], pts.right_keys[k - 1], k))
                right_start = k
    last_lane = int(pts.lane[n - 1])
    if n - left_start > 1:
        _append(road_dict, last_lane, side_element(pts.left[left_start:n], pts.left_keys[n - 1], n - 1))
    if n - right_start > 1:
        _append(road_dict, last_lane, side_element(pts.right[right_start:n], pts.right_keys[n - 1], n - 1))
    if n - centre_start > 0:
        _append(road_dict, last_lane, centre_element(centre_start, n, n - 1))


def _topology_type(is_junction: list[bool]) -> str:
    """gen_hdmap.py's ``check_waypoints_status``: junction/normal by the number of status changes."""
    changes = sum(1 for a, b in zip(is_junction[:-1], is_junction[1:]) if a != b)
    start = is_junction[0]
    if changes == 0:
        return "Junction" if start else "Normal"
    if changes == 1:
        return "EnterNormal" if start else "EnterJunction"
    if changes == 2:
        return "PassNormal" if start else "PassJunction"
    return "StartJunctionMultiChange" if start else "StartNormalMultiChange"


def _insert_volume(hd: dict[int, dict[Any, Any]], road_id: int, points: list, kind: str, parent) -> None:
    entry = {"Points": points, "Type": kind, "ParentActor_Location": [parent.x, parent.y, parent.z]}
    hd.setdefault(road_id, {}).setdefault("Trigger_Volumes", []).append(entry)


def _stop_sign_volumes(map_: Map, hd: dict[int, dict[Any, Any]]) -> None:
    for sign in map_.stop_signs():
        for lane in sign.lanes:
            box = lane.trigger_box
            e = max(box.extent.x, box.extent.y)
            local = np.array([[-e, -e, 0.0], [e, -e, 0.0], [e, 0.0, 0.0], [e, e, 0.0], [-e, e, 0.0]])
            corners = Transform(box.location, box.rotation).transform_points(local).tolist()
            at = map_.get_waypoint(box.location)
            if at is not None:
                _insert_volume(hd, at.road_id, corners, "StopSign", sign.transform.location)


def _traffic_light_volumes(map_: Map, hd: dict[int, dict[Any, Any]]) -> None:
    for light in map_.traffic_lights():
        if not light.lanes:
            continue
        close: list[list[float]] = []
        far: list[list[float]] = []
        for wpx in light.stop_waypoints:
            while not wpx.is_junction:
                nxt = wpx.next(0.5)
                if not nxt or nxt[0].is_junction:
                    break
                wpx = nxt[0]
            yaw = math.radians(wpx.transform.rotation.yaw)
            # gen_hdmap.py's "right" vector is (-forward.y, forward.x, 0).
            vx, vy = -math.sin(yaw), math.cos(yaw)
            loc = wpx.transform.location
            off = 0.4 * wpx.lane_width
            close.append([loc.x - off * vx, loc.y - off * vy, loc.z])
            close.append([loc.x + off * vx, loc.y + off * vy, loc.z])
            before = wpx.previous(0.5)
            if not before:
                continue
            b = before[0].transform.location
            far.append([b.x - off * vx, b.y - off * vy, b.z])
            far.append([b.x + off * vx, b.y + off * vy, b.z])
        at = map_.get_waypoint(light.lanes[0].trigger_box.location)
        if at is not None:
            _insert_volume(hd, at.road_id, close + far[::-1], "TrafficLight", light.transform.location)


@contextlib.contextmanager
def _no_cyclic_gc():
    """Pause the cyclic collector: the export allocates millions of acyclic tuples, which would trigger it
    over and over (it halves the run time on Town04)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def build_hdmap(map_: Map) -> dict[int, dict[Any, Any]]:
    """The HD-map dict: road id → {lane id → [elements], 'Trigger_Volumes' → [volumes]}."""
    with _no_cyclic_gc():
        return _build(map_)


def _build(map_: Map) -> dict[int, dict[Any, Any]]:
    hd: dict[int, dict[Any, Any]] = {}
    covered: set[int] = set()
    for head in _walk_starts(map_):
        if head in covered:
            continue
        chunks = [(i, s) for i, s in _walk(map_, head, PRECISION, covered) if len(s)]
        if chunks:
            _emit_walk(map_, _Points(map_, chunks), hd)
    _stop_sign_volumes(map_, hd)
    _traffic_light_volumes(map_, hd)
    return hd


def save_hdmap(map_: Map, path: Path) -> Path:
    """Write the npz that ``np.savez_compressed(path, arr=rows)`` writes, rows = (road_id, road_dict) objects.

    The archive is the same (one deflated ``arr.npy`` member holding a pickled object array of shape (roads, 2));
    it is written with zlib level 1 instead of numpy's default level, which is 5× faster for the same size.
    """
    hd = build_hdmap(map_)
    arr = np.empty((len(hd), 2), dtype=object)
    for row, (road_id, road_dict) in enumerate(hd.items()):
        arr[row, 0] = road_id
        arr[row, 1] = road_dict
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    with _no_cyclic_gc(), zipfile.ZipFile(
        tmp, mode="w", compression=zipfile.ZIP_DEFLATED, allowZip64=True, compresslevel=1
    ) as zf, zf.open("arr.npy", "w", force_zip64=True) as member:
        np.lib.format.write_array(member, arr, allow_pickle=True)
    tmp.replace(path)
    logger.info("wrote HD map of %s (%d roads) to %s", map_.name, len(hd), path)
    return path
