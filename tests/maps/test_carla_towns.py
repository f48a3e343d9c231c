"""The real CARLA towns: every file loads, lanes join up, and Bench2Drive's routes lie on and along the lanes."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location
from b2d_data.maps import LaneType

TOWNS = ["Town01", "Town04", "Town06", "Town07", "Town10HD"]


def _routes(b2d_data_dir: Path, towns: set[str]) -> list[tuple[str, str, list[Location]]]:
    root = etree.parse(str(b2d_data_dir / "bench2drive220.xml")).getroot()
    routes = []
    for route in root.iter("route"):
        if route.get("town") in towns:
            points = [
                Location(float(p.get("x")), float(p.get("y")), float(p.get("z")))
                for p in route.find("waypoints").iter("position")
            ]
            routes.append((route.get("town"), route.get("id"), points))
    return routes


def test_every_xodr_in_the_folder_loads(carla_towns):
    names = carla_towns.names()
    assert set(TOWNS) <= set(names)
    for name in names:
        m = carla_towns[name]
        assert m.lane_segments() and m.get_topology()


@pytest.mark.parametrize("town", TOWNS)
def test_town_loads_and_lanes_join(carla_towns, town):
    start = time.perf_counter()
    m = carla_towns[town]
    assert time.perf_counter() - start < 10.0
    assert m.name == town and len(m.junctions) > 0
    # Each driving lane ends where its successor starts (the files are consistent to ~1 mm).
    gaps = [
        m.lane_end(a.road_id, a.section_id, a.lane_id).transform.location.distance(b.transform.location)
        for a, b in m.get_topology()
    ]
    assert len(gaps) > 100 and max(gaps) < 0.02
    lights = m.traffic_lights()
    assert lights and all(light.lanes for light in lights)
    for light in lights:
        for lane in light.lanes:
            assert lane.stop_waypoint.lane_type == LaneType.DRIVING and not lane.stop_waypoint.is_junction


def test_town07_stop_signs_and_speed_signs(carla_towns):
    m = carla_towns["Town07"]
    stops = m.stop_signs()
    assert len(stops) == 19 and all(stop.lanes for stop in stops)
    assert {sign.speed_limit for sign in m.speed_limit_signs()} == {30.0, 40.0}


def test_route_keypoints_lie_on_driving_lanes_and_densify_in_order(carla_towns, b2d_data_dir):
    routes = _routes(b2d_data_dir, set(TOWNS))
    assert len(routes) == 31
    for town, route_id, keypoints in routes:
        m = carla_towns[town]
        for k in keypoints:
            wp = m.get_waypoint(k)
            assert wp.transform.location.distance_2d(k) < 0.3, (town, route_id, k)
        dense = m.interpolate_trajectory(keypoints)
        xy = np.array([[wp.transform.location.x, wp.transform.location.y] for wp, _ in dense])
        # The dense route passes every keypoint in order (within 1.5 m, one hop plus the XML rounding) and stops
        # within two hops of the last one, as the leaderboard's does.
        index = 0
        for k in keypoints[:-1]:
            d = np.hypot(xy[index:, 0] - k.x, xy[index:, 1] - k.y)
            assert d.min() < 1.5, (town, route_id, k, d.min())
            index += int(d.argmin())
        assert np.hypot(xy[-1, 0] - keypoints[-1].x, xy[-1, 1] - keypoints[-1].y) < 2.0 + 0.1, (town, route_id)
        # No jumps: consecutive points are at most ~2 hops apart, except where the planner changes lanes (CARLA's
        # trace_route then skips 5 waypoints ahead on the target lane).
        steps = np.hypot(*np.diff(xy, axis=0).T)
        changing = np.array([option in (RoadOption.CHANGELANELEFT, RoadOption.CHANGELANERIGHT) for _, option in dense])
        assert np.all((steps < 2.5) | changing[1:]), (town, route_id)
        assert steps.max() < 7.5, (town, route_id)


def test_get_waypoint_under_a_millisecond(carla_towns):
    m = carla_towns["Town04"]
    rng = np.random.default_rng(1)
    lo = np.array([m.junctions[j].bounding_box.location.x for j in m.junctions]).min()
    hi = np.array([m.junctions[j].bounding_box.location.x for j in m.junctions]).max()
    points = np.column_stack([rng.uniform(lo, hi, 500), rng.uniform(lo, hi, 500), np.zeros(500)])
    start = time.perf_counter()
    for p in points:
        m.get_waypoint(p)
    assert (time.perf_counter() - start) / len(points) < 1e-3
