"""Where the highway merge scenarios (:mod:`.highway`) find their places: on-ramps joining a highway."""

from __future__ import annotations

from b2d_data.maps import Map
from b2d_data.scenarios.catalog.junctions import walk_back_to_source
from b2d_data.scenarios.catalog.layout import CHECK_STEP, LAYOUTS, Layout, register_layouts, xml_location
from b2d_data.scenarios.catalog.road_geometry import JunctionLane, move_along, same_direction_driving_neighbour


#: Highways are at least this fast (km/h); CARLA's Town04/06 highways are 90, generated ones 90–100.
HIGHWAY_MIN_LIMIT = 80.0
#: Largest heading change (deg) from an on-ramp's entry to the lane it merges into (Town04's curved ramps: ~50).
MERGE_MAX_ANGLE = 60.0
#: How far up the on-ramp HighwayCutIn's car waits (m before the merge junction).
CUT_IN_RAMP_DISTANCE = 60.0


def _merge_lane(conn: JunctionLane, lanes: list[JunctionLane]) -> JunctionLane | None:
    """The connection from another road into the lane right of ``conn``'s exit at a shallow angle (an on-ramp
    merging beside it, not a side street turning in)."""
    right = same_direction_driving_neighbour(conn.exit, "right")
    if right is None:
        return None
    for other in lanes:
        into_right = (other.exit.road_id, other.exit.lane_id) == (right.road_id, right.lane_id)
        if into_right and abs(other.angle) < MERGE_MAX_ANGLE and other.entry.road_id != conn.entry.road_id:
            return other
    return None


def _highway_merge(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The ego drives straight on a highway through a junction where an on-ramp joins the lane on its right."""
    fast = min(town.speed_limit(conn.entry), town.speed_limit(conn.exit)) >= HIGHWAY_MIN_LIMIT
    return fast and _merge_lane(conn, lanes) is not None


def _cut_in_car(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The cut-in car 60 m up the ramp (less where the ramp is shorter); end_location 10 m past the merge."""
    merge = _merge_lane(conn, lanes)
    if merge is None:
        return []
    car = walk_back_to_source(merge.entry, CUT_IN_RAMP_DISTANCE, step=2.0)
    end = move_along(merge.exit, 10.0)
    if end is None or car.transform.location.distance_2d(merge.entry.transform.location) < 15.0:
        return []
    return [{"other_actor_location": xml_location(car), "end_location": xml_location(end)}]


#: MergerIntoSlowTraffic: the flow starts this far up the highway before the merge junction and ends this far
#: after it, on the highway lane the acceleration lane runs beside (m; B2D's routes: ~25 m behind the trigger,
#: 120-230 m ahead of it).
SLOW_FLOW_BACK, SLOW_FLOW_AFTER = 60.0, 75.0


def _ramp_into_acceleration_lane(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The route comes down an on-ramp and through its merge junction onto the acceleration lane of a highway."""
    for other in lanes:
        if other.turn == "straight" and _highway_merge(town, other, lanes) and _merge_lane(other, lanes) is conn:
            return True
    return False


def _slow_flow_beside(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The slow flow on the highway lane left of the acceleration lane: from before the merge to after it."""
    for other in lanes:
        if other.turn != "straight" or _merge_lane(other, lanes) is not conn:
            continue
        source = walk_back_to_source(other.entry, SLOW_FLOW_BACK)
        sink = move_along(other.exit, SLOW_FLOW_AFTER, step=CHECK_STEP)
        if sink is None or sink.is_junction:
            continue
        return [{"start_actor_flow": xml_location(source), "end_actor_flow": xml_location(sink)}]
    return []


register_layouts({
    "HighwayCutIn": Layout(
        "highway_ramps", "a highway (>= 80 km/h) crossed straight through a junction where an on-ramp joins the lane "
        "right of the route", turns=("straight",), junction_ok=_highway_merge, junction_extra=_cut_in_car,
        approach=(50.0, 70.0), departure=(60.0, 80.0), trigger_offset=(0.0, 4.0)),
    "MergerIntoSlowTraffic": Layout(
        "highway_ramps", "an on-ramp merging into a highway (>= 80 km/h) through a junction onto an acceleration "
        "lane beside the highway's right lane", turns=("straight", "left", "right"),
        junction_ok=_ramp_into_acceleration_lane, junction_extra=_slow_flow_beside, approach=(40.0, 50.0),
        departure=(95.0, 105.0), trigger_offset=(2.0, 6.0), merge_left_after=(16.0, 30.0)),
})  # fmt: skip
# V2 (Town06's entries with their own lanes) merges the same way on generated towns; only the background differs.
register_layouts({"MergerIntoSlowTrafficV2": LAYOUTS["MergerIntoSlowTraffic"]})
