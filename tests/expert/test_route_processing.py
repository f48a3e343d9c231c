"""Route processing on a real town (Town01): resampling, start index, lights, ParkingExit start."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.route_processing import build_dense_route
from b2d_data.format.road_option import RoadOption
from b2d_data.maps import load_opendrive
from b2d_data.sim.builtin.world import BuiltinSimulator


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    sim = BuiltinSimulator(load_opendrive(carla_maps_dir / "Town01.xodr"), seed=0)
    yield sim
    sim.close()


def _route(sim):
    points = sim.map.get_spawn_points()
    return sim.map.trace_route(points[0].location, points[40].location)[:90]


def _xyz(wp):
    loc = wp.transform.location
    return np.array([loc.x, loc.y, loc.z])


def test_dense_route_resolution_and_start(town01):
    route = _route(town01)
    snap = town01.snapshot()
    dense = build_dense_route(town01.map, route, _xyz(route[0][0]), snap.traffic_lights, snap.traffic_signs)
    steps = np.linalg.norm(np.diff(dense.original_points[:, :2], axis=0), axis=1)
    assert np.median(steps) == pytest.approx(0.1, abs=1e-6)
    assert steps.max() < 0.1 + 1e-6
    # 50 predecessors 1 m apart in s were prepended (longer along an outer lane of a curve): the index starts
    # at the leaderboard route's first point
    assert dense.index >= 500
    assert np.linalg.norm(dense.points[dense.index, :2] - _xyz(route[0][0])[:2]) < 0.06
    # 50 m of successors appended
    last = np.linalg.norm(dense.original_points[:, :2] - _xyz(route[-1][0])[None, :2], axis=1).argmin()
    assert len(dense) - 1 - last >= 490
    assert np.linalg.norm(dense.points[dense.end_index, :2] - _xyz(route[-1][0])[:2]) < 0.06
    assert dense.speed_limits[dense.index] == pytest.approx(30 / 3.6)  # Town01's limit signs say 30 km/h here


def test_dense_route_light_distances(town01):
    route = _route(town01)
    snap = town01.snapshot()
    dense = build_dense_route(town01.map, route, _xyz(route[0][0]), snap.traffic_lights, snap.traffic_signs)
    i = dense.index
    light_id = dense.next_light[i]
    assert light_id is not None
    # distance counts down by 0.1 m per point to 0 at the light's stop line
    assert dense.light_distance[i] - dense.light_distance[i + 10] == pytest.approx(1.0)
    stop = i + round(float(dense.light_distance[i]) * 10)
    assert dense.light_distance[stop] == 0.0
    stop_wp = snap.traffic_lights[light_id].stop_waypoints[0]
    assert np.linalg.norm(dense.original_points[stop, :2] - _xyz(stop_wp)[:2]) < 0.15
    # past the stop line the junction's light is no longer "next"
    assert dense.next_light[stop + 5] != light_id or np.isinf(dense.light_distance[stop + 5])


def test_parking_exit_start(town01):
    route = _route(town01)
    snap = town01.snapshot()
    first = route[0][0].transform
    right = first.get_right_vector()
    ego = _xyz(route[0][0]) + 3.0 * np.array([right.x, right.y, 0.0])  # 3 m to the side of the route start
    dense = build_dense_route(town01.map, route, ego, snap.traffic_lights, snap.traffic_signs, ExpertConfig())
    assert dense.index == 0
    assert np.linalg.norm(dense.points[dense.end_index, :2] - _xyz(route[-1][0])[:2]) < 0.06
    assert np.allclose(dense.points[0, :2], ego[:2])
    assert dense.commands[0] is RoadOption.CHANGELANELEFT
    # the first stretch (from the ego to the route) keeps the lane-change command
    assert all(c is RoadOption.CHANGELANELEFT for c in dense.commands[:10])
