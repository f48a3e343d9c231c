"""DenseRoute: the leaderboard's 1 m route of a route XML, on CARLA's Town01."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location
from b2d_data.maps import load_opendrive
from b2d_data.scenarios.route import DenseRoute, EmptyRouteError
from b2d_data.scenarios.route_xml import Route


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town01.xodr")


@pytest.fixture(scope="module")
def straight(town01):
    """15 m along the first spawn point's lane (Town01 road 0, lane -1: straight, heading −x; a junction 21 m on)."""
    start = town01.get_waypoint(town01.get_spawn_points()[0].location)
    end = start.next(15.0)[0]
    route = Route(id="3", town="Town01", waypoints=(start.transform.location, end.transform.location))
    return DenseRoute.from_route(town01, route), start, end


def test_dense_route_of_a_straight_lane(straight, town01):
    dense, start, end = straight
    # 1 m hops along a straight lane, all on the same lane, all LANEFOLLOW (the planner stops within one hop of
    # the destination, so 15 m give 15 or 16 points).
    assert len(dense) in (15, 16)
    assert {(wp.road_id, wp.lane_id) for wp in dense.waypoints} == {(start.road_id, start.lane_id)}
    assert set(dense.commands) == {RoadOption.LANEFOLLOW}
    assert dense.locations.shape == (len(dense), 3) and dense.forward_vectors.shape == (len(dense), 3)
    assert dense.locations[0] == pytest.approx([start.location.x, start.location.y, start.location.z])
    assert dense.cumulative_length[0] == 0.0
    np.testing.assert_allclose(np.diff(dense.cumulative_length), 1.0, atol=1e-6)
    assert dense.total_length == pytest.approx(len(dense) - 1, abs=1e-6)
    # The lane heads −x: forward vectors are unit and point that way.
    np.testing.assert_allclose(np.linalg.norm(dense.forward_vectors, axis=1), 1.0)
    assert dense.forward_vectors[5][0] == pytest.approx(-1.0, abs=1e-3)
    assert dense.speed_limits[0] == town01.speed_limit(start)
    assert dense.speed_limit_ms(0) == pytest.approx(town01.speed_limit(start) / 3.6)
    assert dense.percentage(6) == pytest.approx(6 / (len(dense) - 1) * 100)


def test_dense_route_is_a_sequence_of_pairs(straight):
    dense, start, _ = straight
    first_wp, first_option = dense[0]
    assert first_wp.location.distance(start.location) < 1e-6 and first_option is RoadOption.LANEFOLLOW
    assert len(list(dense)) == len(dense)
    assert [wp for wp, _ in dense[2:4]] == list(dense.waypoints[2:4])
    assert dense.transforms[3] == dense.waypoints[3].transform


def test_closest_index_window_and_ties(straight):
    dense, _, _ = straight
    p10 = dense.location(10)
    # 0.3 m beside point 10: nearest is 10 when the window reaches it.
    beside = Location(p10.x, p10.y + 0.3, p10.z)
    assert dense.closest_index(beside) == 10
    assert dense.closest_index(beside, start=8, window=5) == 10
    # A window 0..3 cannot reach point 10: its last point is the nearest it has.
    assert dense.closest_index(beside, start=0, window=3) == 3
    # Exactly half-way between 10 and 11: the later point wins, as in the leaderboard's scans.
    mid = (dense.locations[10] + dense.locations[11]) / 2
    assert dense.closest_index(mid) == 11
    # 3-D distances only differ from horizontal ones by height.
    above = Location(p10.x, p10.y, p10.z + 5.0)
    assert dense.closest_index(above, planar=False) == 10


def test_passed_index_uses_the_forward_vector_test(straight):
    dense, _, _ = straight
    # The lane heads −x, so "past point i" means x < x_i. 0.5 m past point 4:
    past4 = dense.locations[4] + 0.5 * dense.forward_vectors[4]
    assert dense.passed_index(past4, start=0, window=10) == 4
    # The window limits how far one update may jump (window 2 from 0 → at most 2).
    assert dense.passed_index(past4, start=0, window=2) == 2
    # Standing before point 0 passes nothing: the start index is kept.
    before = dense.locations[0] - 0.5 * dense.forward_vectors[0]
    assert dense.passed_index(before, start=0, window=2) == 0


def test_route_through_a_junction_has_turn_commands(town01):
    start = town01.get_waypoint(town01.get_spawn_points()[0].location)
    route = Route(id="9", town="Town01", waypoints=(start.transform.location, start.next(60.0)[0].transform.location))
    dense = DenseRoute.from_route(town01, route)
    junction = [i for i, wp in enumerate(dense.waypoints) if wp.is_junction]
    assert junction, "the route from spawn point 0 crosses a junction"
    # Straight across: the junction's points say STRAIGHT, the roads before and after LANEFOLLOW.
    assert RoadOption.STRAIGHT in {dense.commands[i] for i in junction}
    assert dense.commands[0] is RoadOption.LANEFOLLOW and dense.commands[-1] is RoadOption.LANEFOLLOW
    steps = np.linalg.norm(np.diff(dense.locations, axis=0), axis=1)
    assert dense.total_length == pytest.approx(float(steps.sum()))
    assert math.isclose(dense.total_length, float(dense.cumulative_length[-1]))


def test_identical_keypoints_give_no_route(town01):
    p = town01.get_spawn_points()[0].location
    with pytest.raises(EmptyRouteError):
        DenseRoute.from_route(town01, Route(id="1", town="Town01", waypoints=(p, p)))
