"""Traffic lights for a junction whose OpenDRIVE file has none, laid out as CARLA's towns have them.

CARLA's older towns (Town01–Town07) place some of their lights as actors of the Unreal level rather than as OpenDRIVE
signals: Town04's junction 1452, where bench2drive220 route 26944 runs OppositeVehicleRunningRedLight, has lights in
CARLA but none in ``Town04.xodr``. We give such a junction what those level lights are:

- one light head per incoming road (all driving lanes of that road entering the junction share it), standing on the
  road's right edge at the junction entry;
- per governed lane CARLA's generated trigger box (``b2d_data.maps.signals``: 3 m before the entry, half extents
  1.5 × 0.25·width × 1);
- one controller per head, all in one group per junction, so the heads take turns (CARLA's ``TrafficLightGroup``:
  green, yellow, red of one controller, then the next), with CARLA's default stage times (``UTrafficLightController``:
  green 10 s, yellow 3 s, red 2 s), which the builtin simulator's light controller already uses for every group.

Heads take turns in the order of their roads around the junction (clockwise seen from above, starting north), a
fixed order of our own: CARLA's level lights carry their order in the level, which we do not have.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps.lane_types import LaneType
from b2d_data.maps.signals import TRAFFIC_LIGHT, Controller, Signal, SignalLane, _lane_box

if TYPE_CHECKING:
    from b2d_data.maps.map import Map
    from b2d_data.maps.waypoint import Waypoint

#: Prefix of the ids of generated signals and controllers (OpenDRIVE ids of CARLA's towns are numbers).
GENERATED_PREFIX = "b2d_generated_"
#: How far right of the rightmost lane's centre a generated pole stands, beyond half that lane's width (m).
POLE_MARGIN = 1.0


def has_traffic_lights(map_: Map, junction_id: int) -> bool:
    """True when an OpenDRIVE traffic light belongs to the junction or stops a lane that enters it."""
    feeding = {seg for seg, _ in _incoming_lanes(map_, junction_id)}
    for light in map_.traffic_lights():
        if light.junction_id == junction_id:
            return True
        if any(lane.stop_waypoint.segment in feeding for lane in light.lanes):
            return True
    return False


def _incoming_lanes(map_: Map, junction_id: int) -> list[tuple[int, int]]:
    """(incoming lane segment, connecting lane segment) for every driving lane that enters the junction."""
    junction = map_.junctions.get(junction_id)
    if junction is None:
        raise KeyError(f"{map_.name} has no junction {junction_id}")
    pairs: list[tuple[int, int]] = []
    for road_id in junction.connecting_roads:
        for seg_index in map_._road_segments(road_id):
            seg = map_._segments[seg_index]
            if not seg.lane_type & LaneType.DRIVING:
                continue
            for pred in seg.predecessors:
                if map_._segments[pred].junction_id == -1 and (pred, seg_index) not in pairs:
                    pairs.append((pred, seg_index))
    return pairs


def _bearing(centre: Location, point: Location) -> float:
    """Clockwise angle (degrees, 0 = north) of ``point`` seen from ``centre`` in CARLA's frame (y points south)."""
    return math.degrees(math.atan2(point.x - centre.x, -(point.y - centre.y))) % 360.0


def _pole_transform(rightmost: Waypoint) -> Transform:
    """The head's landmark pose: right of the rightmost entering lane at the entry, facing along the lane as an
    OpenDRIVE light with no heading offset does (its actor then turns 90° as CARLA's do)."""
    loc, yaw = rightmost.transform.location, rightmost.transform.rotation.yaw
    side = 0.5 * rightmost.lane_width + POLE_MARGIN
    right = math.radians(yaw + 90.0)  # CARLA's right vector: yaw + 90° in its left-handed frame
    return Transform(Location(loc.x + side * math.cos(right), loc.y + side * math.sin(right), loc.z), Rotation(yaw=yaw))


def junction_lights(map_: Map, junction_id: int) -> tuple[list[Signal], list[Controller]]:
    """One traffic light per road entering the junction and one controller per light, in turn order."""
    pairs = _incoming_lanes(map_, junction_id)
    by_road: dict[tuple[int, int], list[Waypoint]] = {}
    # an incoming lane feeds several connecting lanes (left, straight, right): one trigger box each lane
    for pred in dict.fromkeys(pred for pred, _ in pairs):
        seg = map_._segments[pred]
        end = map_._waypoint_at(pred, map_._end_s(pred))
        # A road enters the junction with the lanes of one side; key by road and side.
        by_road.setdefault((seg.road_id, 1 if seg.lane_id > 0 else -1), []).append(end)
    centre = map_.junctions[junction_id].bounding_box.location
    heads: list[tuple[float, tuple[int, int], list[Waypoint]]] = []
    for key, ends in by_road.items():
        ends.sort(key=lambda wp: abs(wp.lane_id))
        heads.append((_bearing(centre, ends[0].transform.location), key, ends))
    heads.sort(key=lambda h: (h[0], h[1]))
    signals: list[Signal] = []
    controllers: list[Controller] = []
    for order, (_, (road_id, side), ends) in enumerate(heads):
        lanes: list[SignalLane] = []
        for end in ends:
            lane = _lane_box(map_, end, TRAFFIC_LIGHT)
            if lane is not None:
                lanes.append(lane)
        if not lanes:
            continue
        rightmost = ends[-1]
        signal_id = f"{GENERATED_PREFIX}{junction_id}_{road_id}_{'left' if side > 0 else 'right'}"
        controller_id = f"{GENERATED_PREFIX}controller_{junction_id}_{order}"
        signal = Signal(
            signal_id, "generated traffic light", TRAFFIC_LIGHT, "", None, "", "", road_id, rightmost.s, 0.0,
            "-" if side > 0 else "+", True, 0.0, 0.0, _pole_transform(rightmost), tuple(lanes), tuple(ends),
            (controller_id,), junction_id,
        )  # fmt: skip
        signals.append(signal)
        controllers.append(Controller(controller_id, "generated", order, (signal_id,), junction_id))
    return signals, controllers
