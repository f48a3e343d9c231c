"""GlobalRoutePlanner semantics on the tiny junction town: turn decisions, lane changes, densification."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location
from b2d_data.maps.route_planner import RouteNotFoundError

# CARLA positions (y = −OpenDRIVE y): lane -1 of road 1 at y = 1.75, lane -2 at y = 5.25.
ORIGIN_LANE_1 = Location(10.0, 1.75, 0.0)
ORIGIN_LANE_2 = Location(10.0, 5.25, 0.0)
NORTH_EXIT = Location(61.75, -30.0, 0.0)  # road 3 (north in OpenDRIVE), lane -1, 20 m in
SOUTH_EXIT = Location(58.25, 33.5, 0.0)  # road 4 (south in OpenDRIVE), lane -1, 20 m in
EAST_EXIT = Location(90.0, 1.75, 0.0)  # road 2, lane -1, 20 m in


def _options_in_junction(trace):
    # The first waypoint of the connector closes the approach edge (LANEFOLLOW, as in CARLA): look past it.
    return {option for wp, option in trace if wp.is_junction and wp.s > 0.5}


def _runs(trace) -> list[RoadOption]:
    """Options with consecutive repeats collapsed."""
    runs: list[RoadOption] = []
    for _, option in trace:
        if not runs or runs[-1] != option:
            runs.append(option)
    return runs


def test_left_turn_is_left(tiny_map):
    # Entering heading east (CARLA forward (1, 0)), leaving north (0, −1): cross z = 1·(−1) < 0 → LEFT.
    trace = tiny_map.trace_route(ORIGIN_LANE_1, NORTH_EXIT)
    assert _options_in_junction(trace) == {RoadOption.LEFT}
    assert _runs(trace) == [RoadOption.LANEFOLLOW, RoadOption.LEFT, RoadOption.LANEFOLLOW]
    assert {wp.road_id for wp, _ in trace} == {1, 11, 3}
    assert trace[0][1] == RoadOption.LANEFOLLOW and trace[-1][1] == RoadOption.LANEFOLLOW
    assert trace[-1][0].transform.location.distance(NORTH_EXIT) < 2.0


def test_right_turn_is_right(tiny_map):
    # Leaving south (0, +1): cross z = +1 > 0 → RIGHT (the straight branch's cross is 0).
    trace = tiny_map.trace_route(ORIGIN_LANE_2, SOUTH_EXIT)
    assert _options_in_junction(trace) == {RoadOption.RIGHT}
    assert _runs(trace) == [RoadOption.LANEFOLLOW, RoadOption.RIGHT, RoadOption.LANEFOLLOW]
    assert {wp.road_id for wp, _ in trace if wp.is_junction} == {12}


def test_straight_through_is_straight(tiny_map):
    trace = tiny_map.trace_route(ORIGIN_LANE_1, EAST_EXIT)
    assert _options_in_junction(trace) == {RoadOption.STRAIGHT}
    assert _runs(trace) == [RoadOption.LANEFOLLOW, RoadOption.STRAIGHT, RoadOption.LANEFOLLOW]
    spacing = [a.transform.location.distance(b.transform.location) for (a, _), (b, _) in zip(trace[:-1], trace[1:])]
    assert max(spacing) <= 1.0 + 1e-6  # 1 m hop


def test_lane_change_before_the_left_turn(tiny_map):
    # The left turn starts from lane -1 only: from lane -2 the planner changes lanes on the broken line first.
    trace = tiny_map.trace_route(ORIGIN_LANE_2, NORTH_EXIT)
    options = [option for _, option in trace]
    assert options[0] == RoadOption.CHANGELANELEFT
    assert trace[0][0].lane_id == -2 and trace[1][0].lane_id == -1
    assert RoadOption.LEFT in options and trace[-1][0].road_id == 3


def test_interpolate_trajectory_joins_keypoints(tiny_map):
    keypoints = [Location(5.0, 1.75, 0.0), Location(30.0, 1.75, 0.0), Location(30.0, 1.75, 0.0), NORTH_EXIT]
    route = tiny_map.interpolate_trajectory(keypoints)
    xy = np.array([[wp.transform.location.x, wp.transform.location.y] for wp, _ in route])
    # Passes within a hop of every keypoint, in order, and stops less than 2 hops before the last one.
    index = 0
    for k in keypoints[:-1]:
        d = np.hypot(xy[index:, 0] - k.x, xy[index:, 1] - k.y)
        assert d.min() <= 1.0 + 1e-6
        index += int(d.argmin())
    assert np.hypot(*(xy[-1] - [NORTH_EXIT.x, NORTH_EXIT.y])) < 2.0
    assert {option for _, option in route} == {RoadOption.LANEFOLLOW, RoadOption.LEFT}


def test_unreachable_destination_raises(tiny_map):
    # Road 3 leads nowhere: there is no path from it back to road 1.
    with pytest.raises(RouteNotFoundError, match="Town90"):
        tiny_map.trace_route(NORTH_EXIT, ORIGIN_LANE_1)



def test_no_lane_change_into_the_opposite_direction():
    # The generated interurban town has broken centre lines that allow overtaking, so a lane change "left"
    # reaches the opposite lane. CARLA's planner would route through it (209 of 315 routes between its spawn
    # points did before the direction check); a route must never switch to a lane of the other direction.
    from b2d_data.maps import load_opendrive
    from b2d_data.maps.towngen import generate_town

    town = load_opendrive(generate_town("interurban", 0), name="Interurban")
    spawns = town.get_spawn_points()
    routes = [town.trace_route(a.location, b.location) for a in spawns[::9] for b in spawns[4::13] if a != b]
    assert len(routes) >= 6
    for route in routes:
        for (w1, _), (w2, _) in zip(route, route[1:]):
            assert not (w1.road_id == w2.road_id and (w1.lane_id > 0) != (w2.lane_id > 0))
