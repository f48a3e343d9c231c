"""Signals: traffic lights, stop/yield signs, speed limits; the lanes they govern and their trigger boxes.

A signal governs the lanes named by the ``<validity>`` of the signal itself and of every ``<signalReference>``
to it (CARLA's ``GetAllReferencesToThisSignal``). Per governed driving lane we build CARLA's generated trigger box
(``UTrafficLightComponent`` / ``UStopSignComponent::InitializeSign``):

- traffic light (type 1000001): on a junction road with a single non-junction predecessor, the box moves to the
  end of that incoming lane; it is centred 3 m before that point (against traffic), half extents
  (1.5, max(0.01, 0.25·lane width), 1.0);
- stop (206), yield (205) and speed-limit (274) signs: a cube of half size max(0.01, 0.45·lane width), centred
  that far before the reference point.

The stop waypoint of a lane is the lane waypoint at its box centre, which is what ``TrafficLight.get_stop_waypoints``
returns for such a box. Speed-limit signs also come from RoadRunner sign objects (``Speed_30``,
``SpeedLimit60Assembly``...): CARLA's towns place them as props, not signals; they govern the driving lanes on the
side of the road they stand on.
"""

from __future__ import annotations

import heapq
import logging
import math
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, wrap_degrees
from b2d_data.maps.geometry import evaluate_cubic, evaluate_reference_line
from b2d_data.maps.lane_types import LaneType
from b2d_data.maps.lanes import EPSILON
from b2d_data.maps.opendrive_parser import ObjectRecord, RoadRecord, Validity
from b2d_data.maps.waypoint import Waypoint

if TYPE_CHECKING:
    from b2d_data.maps.map import Map

logger = logging.getLogger(__name__)

TRAFFIC_LIGHT = "1000001"
STOP = "206"
YIELD = "205"
SPEED_LIMIT = "274"
#: PDM-Lite's speed limit where nothing else is known (km/h).
DEFAULT_SPEED_LIMIT = 50.0
#: How far back along the lanes a speed-limit sign still applies (m).
SPEED_SIGN_REACH = 2000.0

_SPEED_OBJECT = re.compile(r"^sp+e+d_?(?:limit)?_?(\d+)", re.IGNORECASE)


@dataclass(frozen=True, eq=False)
class SignalLane:
    """A lane a signal governs: the referencing lane waypoint, the trigger box and its stop waypoint.

    ``trigger_box`` is in world coordinates (``location`` world centre, ``rotation`` along traffic, half extents).
    """

    road_id: int
    lane_id: int
    reference_waypoint: Waypoint
    trigger_box: BoundingBox
    stop_waypoint: Waypoint


@dataclass(frozen=True, eq=False)
class Signal:
    """An OpenDRIVE signal (or a speed-limit sign object) with the lanes it governs.

    ``transform`` is CARLA's landmark pose (reference line at ``s``, offset ``t``, z + zOffset, yaw
    −(heading + hOffset)); ``actor_transform`` is how CARLA spawns the sign/light actor (yaw + 90°, level).
    ``z_offset`` is the record's zOffset: in OpenDRIVE the height of the signal's bottom above the reference line,
    so the signal spans ``transform`` z to that plus ``height`` and the road under it is at ``transform`` z − zOffset.
    """

    id: str
    name: str
    type: str
    subtype: str
    value: float | None
    unit: str
    text: str
    road_id: int
    s: float
    t: float
    orientation: str
    dynamic: bool
    height: float
    width: float
    transform: Transform
    lanes: tuple[SignalLane, ...]
    referenced_waypoints: tuple[Waypoint, ...] = ()
    controller_ids: tuple[str, ...] = ()
    junction_id: int = -1
    from_object: bool = False
    z_offset: float = 0.0

    @property
    def is_traffic_light(self) -> bool:
        """CARLA's traffic-light type (1000001)."""
        return self.type == TRAFFIC_LIGHT

    @property
    def is_stop(self) -> bool:
        """Stop sign (206)."""
        return self.type == STOP

    @property
    def is_yield(self) -> bool:
        """Yield sign (205)."""
        return self.type == YIELD

    @property
    def is_speed_limit(self) -> bool:
        """Speed-limit sign (274) with a value."""
        return self.type == SPEED_LIMIT and self.value is not None

    @property
    def speed_limit(self) -> float | None:
        """The limit in km/h for speed-limit signs, else ``None``."""
        return self.value if self.is_speed_limit else None

    @property
    def actor_transform(self) -> Transform:
        """Pose of the CARLA actor: sign blueprints are rotated by 90° and spawned level."""
        loc, rot = self.transform.location, self.transform.rotation
        return Transform(loc, Rotation(pitch=0.0, yaw=wrap_degrees(rot.yaw + 90.0), roll=0.0))

    @property
    def stop_waypoints(self) -> tuple[Waypoint, ...]:
        """One waypoint per governed lane at its trigger box (``TrafficLight.get_stop_waypoints``)."""
        return tuple(lane.stop_waypoint for lane in self.lanes)

    @property
    def affected_lane_waypoints(self) -> tuple[Waypoint, ...]:
        """Lane waypoints at every reference (``TrafficLight.get_affected_lane_waypoints``)."""
        return self.referenced_waypoints

    def __hash__(self) -> int:
        return hash(("signal", self.id, self.from_object))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Signal) and (other.id, other.from_object) == (self.id, self.from_object)


@dataclass(frozen=True)
class Controller:
    """A signal controller: the lights switched together, the junction that sequences it and its phase."""

    id: str
    name: str
    sequence: int | None
    signal_ids: tuple[str, ...]
    junction_id: int


@dataclass
class SignalIndex:
    """All signals of a map plus the per-lane speed-limit lookup."""

    map: Map
    signals: list[Signal]
    speed_signs: list[Signal]
    controllers: list[Controller]
    by_id: dict[str, Signal]
    _events: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    _entry_limit: dict[int, float | None] = field(default_factory=dict)
    _by_segment: dict[int, list[Signal]] = field(default_factory=dict)

    def governing(self, waypoint: Waypoint) -> list[Signal]:
        """Signals (speed signs included) with a trigger box on the waypoint's lane section."""
        if not self._by_segment:
            for sign in self.signals + [s for s in self.speed_signs if s.from_object]:
                for lane in sign.lanes:
                    bucket = self._by_segment.setdefault(lane.stop_waypoint.segment, [])
                    if sign not in bucket:
                        bucket.append(sign)
        return list(self._by_segment.get(waypoint.segment, []))

    def speed_limit(self, waypoint: Waypoint) -> float:
        """Last speed sign passed on the way to ``waypoint``, else lane/road speed records, else 50 km/h."""
        seg = self.map._segments[waypoint.segment]
        events = self._events.get(seg.index, [])
        if seg.forward:
            behind = [(s, v) for s, v in events if s <= waypoint.s]
            if behind:
                return max(behind)[1]
        else:
            behind = [(s, v) for s, v in events if s >= waypoint.s]
            if behind:
                return min(behind)[1]
        upstream = self._limit_entering(seg.index)
        if upstream is not None:
            return upstream
        return _record_speed(self.map, waypoint)

    def _limit_entering(self, segment: int) -> float | None:
        """Nearest speed sign upstream of a segment's start (Dijkstra backwards over predecessors)."""
        if segment in self._entry_limit:
            return self._entry_limit[segment]
        segments = self.map._segments
        queue: list[tuple[float, int]] = [(0.0, p) for p in segments[segment].predecessors]
        heapq.heapify(queue)
        seen: set[int] = set()
        found: float | None = None
        while queue:
            dist, i = heapq.heappop(queue)
            if i in seen or dist > SPEED_SIGN_REACH:
                continue
            seen.add(i)
            events = self._events.get(i)
            if events:
                pick = max(events) if segments[i].forward else min(events)
                found = pick[1]
                break
            for p in segments[i].predecessors:
                if p not in seen:
                    heapq.heappush(queue, (dist + segments[i].length, p))
        self._entry_limit[segment] = found
        return found


def _record_speed(map_: Map, waypoint: Waypoint) -> float:
    seg = map_._segments[waypoint.segment]
    lane_speeds = [v for s, v in seg.speeds if s <= waypoint.s + 1e-9]
    if lane_speeds:
        return lane_speeds[-1]
    road = map_.data.road(waypoint.road_id)
    limit = None
    for record in road.types:
        if record.s <= waypoint.s + 1e-9:
            limit = record.speed_kmh
    return limit if limit is not None else DEFAULT_SPEED_LIMIT


def _pose_on_road(road: RoadRecord, s: float, t: float, z_offset: float) -> tuple[float, float, float, float]:
    """OpenDRIVE (x, y, z, heading) of a point at (s, t) of a road's reference line (no lane offset)."""
    x, y, hdg, _ = evaluate_reference_line(road.geometries, np.array([s]))
    z, _ = evaluate_cubic(road.elevations, np.array([s]))
    h = float(hdg[0])
    return float(x[0] - t * math.sin(h)), float(y[0] + t * math.cos(h)), float(z[0]) + z_offset, h


def signal_transform(road: RoadRecord, s: float, t: float, z_offset: float, h_offset: float, pitch: float = 0.0,
                     roll: float = 0.0) -> Transform:  # fmt: skip
    """CARLA's ``ComputeSignalTransform``: reference line pose, lateral t, z offset, yaw −(heading + hOffset)."""
    x, y, z, h = _pose_on_road(road, min(max(s, 0.0), road.length), t, z_offset)
    return Transform(
        Location(x, -y, z),
        Rotation(pitch=math.degrees(pitch), yaw=wrap_degrees(-math.degrees(h + h_offset)), roll=math.degrees(roll)),
    )


def _lane_box(map_: Map, waypoint: Waypoint, kind: str) -> SignalLane | None:
    """CARLA's generated trigger box for one governed lane (``None`` for non-driving lanes)."""
    reference = waypoint
    if kind == TRAFFIC_LIGHT and waypoint.is_junction:
        predecessors = map_._segments[waypoint.segment].predecessors
        if len(predecessors) == 1 and map_._segments[predecessors[0]].junction_id == -1:
            waypoint = map_._waypoint_at(predecessors[0], map_._end_s(predecessors[0]))
    if not waypoint.lane_type & LaneType.DRIVING:
        return None
    seg = map_._segments[waypoint.segment]
    if kind == TRAFFIC_LIGHT:
        half = Location(1.5, max(0.01, 0.25 * waypoint.lane_width), 1.0)
        shift = 1.5 + 1.5
    else:
        size = max(0.01, 0.45 * waypoint.lane_width)
        half = Location(size, size, size)
        shift = size
    eps = 1e-5
    s = waypoint.s - shift if seg.forward else waypoint.s + shift
    s = min(max(s, seg.s0 + eps), seg.s1 - eps) if seg.s1 - seg.s0 > 2 * eps else seg.s0 + EPSILON
    stop = map_._waypoint_at(seg.index, s)
    box = BoundingBox(stop.transform.location, half, stop.transform.rotation)
    return SignalLane(waypoint.road_id, waypoint.lane_id, reference, box, stop)


def _governed(
    map_: Map, references: list[tuple[int, float, list[Validity]]], kind: str
) -> tuple[tuple[SignalLane, ...], tuple[Waypoint, ...]]:
    """(one SignalLane per distinct trigger box, every referenced lane waypoint)."""
    lanes: list[SignalLane] = []
    referenced: list[Waypoint] = []
    seen: set[tuple[int, int, float]] = set()
    boxes: set[tuple[int, float]] = set()
    for road_id, s, validities in references:
        for validity in validities:
            for lane_id in validity.lanes():
                key = (road_id, lane_id, round(s, 6))
                if key in seen:
                    continue
                seen.add(key)
                # CARLA drops references placed exactly at the road end (s == length) with an error, which leaves
                # some Town01/Town07 lights governing nothing; we keep them by clamping s into the road.
                length = map_.data.road(road_id).length if map_.data.has_road(road_id) else 0.0
                waypoint = map_.get_waypoint_xodr(road_id, lane_id, min(max(s, 0.0), max(length - 1e-6, 0.0)))
                if waypoint is None:
                    logger.debug("%s: signal reference on missing lane %s/%s at s=%.2f", map_.name, road_id, lane_id, s)
                    continue
                referenced.append(waypoint)
                lane = _lane_box(map_, waypoint, kind)
                # References on the straight/left/right connecting roads lead back to the same incoming lane.
                if lane is not None and (lane.stop_waypoint.segment, round(lane.stop_waypoint.s, 6)) not in boxes:
                    boxes.add((lane.stop_waypoint.segment, round(lane.stop_waypoint.s, 6)))
                    lanes.append(lane)
    return tuple(lanes), tuple(referenced)


def _side_lanes(map_: Map, road: RoadRecord, s: float, t: float, orientation: str) -> list[Validity]:
    """Driving lanes on the side of the road a sign object stands on (t < 0: right lanes).

    A sign beside a one-way road on its other side still speaks to the lanes that exist.
    """
    side = -1 if t < 0 else 1 if t > 0 else (-1 if orientation == "-" else 1)
    lanes = _driving_lanes_at(map_, road, s, side) or _driving_lanes_at(map_, road, s, -side)
    return [Validity(lane, lane) for lane in lanes]


def _driving_lanes_at(map_: Map, road: RoadRecord, s: float, side: int) -> list[int]:
    found: list[int] = []
    for section_id in range(len(road.sections)):
        for lane_id in sorted(road.sections[section_id].lanes, key=abs):
            if lane_id * side <= 0:
                continue
            seg_index = map_._index.get((road.id, section_id, lane_id))
            if seg_index is None:
                continue
            seg = map_._segments[seg_index]
            if seg.s0 <= s <= seg.s1 and seg.lane_type & LaneType.DRIVING and lane_id not in found:
                found.append(lane_id)
    return found


def _speed_object_signal(map_: Map, road: RoadRecord, obj: ObjectRecord) -> Signal | None:
    match = _SPEED_OBJECT.match(obj.name)
    if match is None:
        return None
    s = min(max(obj.s, 0.0), road.length - 1e-6)
    validities = _side_lanes(map_, road, s, obj.t, obj.orientation)
    lanes, referenced = _governed(map_, [(road.id, s, validities)], SPEED_LIMIT)
    transform = signal_transform(road, s, obj.t, obj.z_offset, obj.hdg, obj.pitch, obj.roll)
    return Signal(
        obj.id, obj.name, SPEED_LIMIT, "", float(match.group(1)), "km/h", "", road.id, obj.s, obj.t, obj.orientation,
        False, obj.height, obj.width, transform, lanes, referenced, (), road.junction, True, obj.z_offset,
    )  # fmt: skip


def build_signals(map_: Map) -> SignalIndex:
    """Collect every signal of ``map_`` with its lanes, controllers and junction."""
    data = map_.data
    references: dict[str, list[tuple[int, float, list[Validity]]]] = {}
    reference_roads: dict[str, list[int]] = {}
    for road in data.roads:
        for ref in road.signal_references:
            references.setdefault(ref.id, []).append((road.id, ref.s, ref.validities))
            reference_roads.setdefault(ref.id, []).append(road.id)
    controller_junction: dict[str, int] = {}
    for junction in data.junctions.values():
        for controller_id, _ in junction.controllers:
            controller_junction.setdefault(controller_id, junction.id)
    controls: dict[str, list[str]] = {}
    for controller in data.controllers:
        for signal_id in controller.signal_ids:
            controls.setdefault(signal_id, []).append(controller.id)

    signals: list[Signal] = []
    for road in data.roads:
        for rec in road.signals:
            refs = [(road.id, rec.s, rec.validities)] + references.get(rec.id, [])
            lanes, referenced = _governed(map_, refs, rec.type)
            controller_ids = tuple(controls.get(rec.id, []))
            junction_id = next((controller_junction[c] for c in controller_ids if c in controller_junction), -1)
            if junction_id == -1:
                for road_id in reference_roads.get(rec.id, []):
                    if data.road(road_id).junction != -1:
                        junction_id = data.road(road_id).junction
                        break
            transform = signal_transform(road, rec.s, rec.t, rec.z_offset, rec.h_offset, rec.pitch, rec.roll)
            signals.append(
                Signal(
                    rec.id, rec.name, rec.type, rec.subtype, rec.value, rec.unit, rec.text, road.id, rec.s, rec.t,
                    rec.orientation, rec.dynamic, rec.height, rec.width, transform, lanes, referenced, controller_ids,
                    junction_id, z_offset=rec.z_offset,
                )  # fmt: skip
            )
    by_id = {sig.id: sig for sig in signals}
    speed_signs = [sig for sig in signals if sig.is_speed_limit]
    for road in data.roads:
        for obj in road.objects:
            sign = _speed_object_signal(map_, road, obj)
            if sign is not None:
                speed_signs.append(sign)
    controllers = [
        Controller(c.id, c.name, c.sequence, tuple(c.signal_ids), controller_junction.get(c.id, -1))
        for c in data.controllers
    ]
    if getattr(map_, "generated_light_junctions", ()):
        from b2d_data.maps.generated_lights import junction_lights

        for junction_id in map_.generated_light_junctions:
            extra, extra_controllers = junction_lights(map_, junction_id)
            signals.extend(extra)
            controllers.extend(extra_controllers)
            by_id.update((sig.id, sig) for sig in extra)
    index = SignalIndex(map_, signals, speed_signs, controllers, by_id)
    for sign in speed_signs:
        for lane in sign.lanes:
            index._events.setdefault(lane.reference_waypoint.segment, []).append(
                (lane.reference_waypoint.s, float(sign.value))
            )
    for events in index._events.values():
        events.sort()
    return index
