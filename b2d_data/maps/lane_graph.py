"""Lane connectivity in the driving direction (CARLA's ``Lane::GetNextLanes`` / ``GetPreviousLanes``).

Traffic on a lane with id ≤ 0 runs with increasing s, on a lane with id > 0 against it. A lane's successors are:
the linked lane of the next lane section of the same road; at the road's end, the linked lane of the successor
road (in its first or last section, by contact point) or, when the road ends at a junction, the connecting-road
lanes that the junction's connections list for this incoming road and lane. Predecessors are the inverse relation.
"""

from __future__ import annotations

import logging
import math

from b2d_data.maps.geometry import evaluate_reference_line
from b2d_data.maps.lanes import LaneSegment
from b2d_data.maps.opendrive_parser import OpenDriveData, RoadLink, RoadRecord

logger = logging.getLogger(__name__)

LaneKey = tuple[int, int, int]


def link_lanes(odr: OpenDriveData, segments: list[LaneSegment], index: dict[LaneKey, int]) -> None:
    """Fill ``successors`` and ``predecessors`` of every segment (in place)."""
    incoming: dict[tuple[int, int], list] = {}
    for junction in odr.junctions.values():
        for connection in junction.connections:
            incoming.setdefault((junction.id, connection.incoming_road), []).append(connection)
    for seg in segments:
        road = odr.road(seg.road_id)
        targets = _next_keys(odr, road, seg, incoming)
        for key in targets:
            target = index.get(key)
            if target is None:
                logger.debug("lane %s links to missing lane %s", seg.key, key)
                continue
            if target not in seg.successors:
                seg.successors.append(target)
    for seg in segments:
        for target in seg.successors:
            segments[target].predecessors.append(seg.index)


def _section_at_contact(road: RoadRecord, contact: str | None) -> int:
    return 0 if contact == "start" else len(road.sections) - 1


def _next_keys(odr: OpenDriveData, road: RoadRecord, seg: LaneSegment, incoming) -> list[LaneKey]:
    section = road.sections[seg.section_id]
    lane = section.lanes[seg.lane_id]
    if seg.forward:
        linked, neighbour_section, road_link, at_end = lane.successor, seg.section_id + 1, road.successor, "end"
    else:
        linked, neighbour_section, road_link, at_end = lane.predecessor, seg.section_id - 1, road.predecessor, "start"
    if 0 <= neighbour_section < len(road.sections):
        return [(road.id, neighbour_section, linked)] if linked not in (None, 0) else []
    if road_link is None:
        return []
    if road_link.element_type == "junction":
        return _junction_keys(odr, road, seg, road_link, at_end, incoming)
    if not odr.has_road(road_link.element_id) or linked in (None, 0):
        return []
    target = odr.road(road_link.element_id)
    contact = road_link.contact_point or _guess_contact(road, at_end, target)
    return [(target.id, _section_at_contact(target, contact), linked)]


def _junction_keys(odr, road: RoadRecord, seg: LaneSegment, link: RoadLink, at_end: str, incoming) -> list[LaneKey]:
    keys: list[LaneKey] = []
    other = road.predecessor if at_end == "end" else road.successor
    # A road that starts and ends at the same junction: keep connections that touch this end only.
    check_end = other is not None and other.element_type == "junction" and other.element_id == link.element_id
    for connection in incoming.get((link.element_id, road.id), []):
        if not odr.has_road(connection.connecting_road):
            continue
        target = odr.road(connection.connecting_road)
        if check_end and _guess_contact(road, at_end, target) != connection.contact_point:
            continue
        for from_lane, to_lane in connection.lane_links:
            if from_lane == seg.lane_id and to_lane != 0:
                keys.append((target.id, _section_at_contact(target, connection.contact_point), to_lane))
    return keys


def _guess_contact(road: RoadRecord, at_end: str, target: RoadRecord) -> str:
    """Which end of ``target`` touches ``road`` at ``at_end`` (by reference-line distance)."""
    here = evaluate_reference_line(road.geometries, [0.0 if at_end == "start" else road.length])
    ends = evaluate_reference_line(target.geometries, [0.0, target.length])
    d_start = math.hypot(ends[0][0] - here[0][0], ends[1][0] - here[1][0])
    d_end = math.hypot(ends[0][1] - here[0][0], ends[1][1] - here[1][0])
    return "start" if d_start <= d_end else "end"
