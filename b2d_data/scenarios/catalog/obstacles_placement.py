"""Where the obstacle scenarios (:mod:`.obstacles`) find their places: their layouts and checks."""

from __future__ import annotations

from b2d_data.maps import Map, Waypoint
from b2d_data.scenarios.catalog.layout import (
    STRAIGHTISH,
    Layout,
    multi_lane_left,
    multi_lane_right,
    register_layouts,
    two_way_single,
)
from b2d_data.scenarios.catalog.road_geometry import move_along, opposite_driving_neighbour
from collections.abc import Callable, Mapping


def opposite_flow_room(town: Map, wp: Waypoint) -> bool:
    """The opposite lane continues 1.5 × limit + 30 m both ways around the furthest obstacle position (44 m)."""
    return opposite_flow_room_at(town, wp, 44.0)


def opposite_flow_room_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """The opposite lane continues 1.5 × limit + 30 m both ways around an obstacle ``distance`` m ahead."""
    obstacle = move_along(wp, distance, step=11.0)
    if obstacle is None:
        return False
    opposite = opposite_driving_neighbour(obstacle)
    if opposite is None:
        return False
    reach = 1.5 * town.speed_limit(obstacle) + 30.0
    return bool(opposite.previous(reach)) and bool(opposite.next(reach))


#: Obstacles passed on the other side of the lane: a same-direction lane left of a right-hand obstacle and vice versa.
PASS_OTHER_SIDE: Mapping[str, Callable[[Waypoint], bool]] = {"right": multi_lane_left, "left": multi_lane_right}


register_layouts({
    "Accident": Layout("multi_lane", "two same-direction lanes, 120 m junction-free and straight-ish", multi_lane_left,
                       clear_after=120.0, max_turn=STRAIGHTISH, directions=PASS_OTHER_SIDE, reach_param="distance"),
    "ParkedObstacleTwoWays": Layout("two_way_street", "one lane each way, 100 m junction-free, opposite lane "
                                    "continuing ~105 m around the obstacle", two_way_single, clear_after=100.0,
                                    extra=opposite_flow_room, max_turn=STRAIGHTISH, reach_param="distance",
                                    reach_ok=opposite_flow_room_at),
    "ParkedObstacle": Layout("multi_lane", "two same-direction lanes, 100 m junction-free and straight-ish",
                             multi_lane_left, clear_after=100.0, max_turn=STRAIGHTISH, directions=PASS_OTHER_SIDE,
                             reach_param="distance"),
    "ConstructionObstacle": Layout("multi_lane", "two same-direction lanes, 110 m junction-free and straight-ish",
                                   multi_lane_left, clear_after=110.0, max_turn=STRAIGHTISH,
                                   directions=PASS_OTHER_SIDE, reach_param="distance"),
    "AccidentTwoWays": Layout("two_way_street", "one lane each way, 120 m junction-free, opposite lane continuing "
                              "~105 m around the obstacle", two_way_single, clear_after=120.0,
                              extra=opposite_flow_room, max_turn=STRAIGHTISH, reach_param="distance",
                              reach_ok=opposite_flow_room_at),
    "ConstructionObstacleTwoWays": Layout("two_way_street", "one lane each way, 110 m junction-free, opposite lane "
                                          "continuing ~105 m around the obstacle", two_way_single,
                                          clear_after=110.0, extra=opposite_flow_room, max_turn=STRAIGHTISH,
                                          reach_param="distance", reach_ok=opposite_flow_room_at),
})  # fmt: skip
