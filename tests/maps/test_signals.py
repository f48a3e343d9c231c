"""Signals of the tiny town: governed lanes, CARLA-generated trigger boxes, controllers, speed limits."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.maps import LaneType


def test_traffic_light_governs_the_incoming_lanes(tiny_map):
    (light,) = tiny_map.traffic_lights()
    assert light.id == "1" and light.is_traffic_light and light.controller_ids == ("500",) and light.junction_id == 100
    # References on the straight (lanes -1, -2) and left connector (lane -1) step back to road 1's lane ends; the
    # duplicate from the second reference is dropped: one box per incoming lane.
    assert sorted((lane.road_id, lane.lane_id) for lane in light.lanes) == [(1, -2), (1, -1)]
    box = next(lane for lane in light.lanes if lane.lane_id == -1).trigger_box
    # 1.5 m box + 1.5 m margin before the lane end at s = 50: centre s = 47 → CARLA (47, 1.75); half extents
    # (1.5, 0.25 · 3.5, 1.0).
    np.testing.assert_allclose(box.location.to_list(), [47.0, 1.75, 0.0], atol=1e-6)
    np.testing.assert_allclose(box.extent.to_list(), [1.5, 0.875, 1.0], atol=1e-9)
    stops = light.stop_waypoints
    assert {(w.road_id, w.lane_id) for w in stops} == {(1, -1), (1, -2)}
    assert all(w.s == pytest.approx(47.0) for w in stops)
    assert {(w.road_id, w.lane_id) for w in light.affected_lane_waypoints} == {(10, -1), (10, -2), (11, -1)}
    # Landmark pose: road 1 at s = 48, t = −8 → OpenDRIVE (48, −8) → CARLA (48, 8); the actor turns by +90°.
    np.testing.assert_allclose(light.transform.location.to_list(), [48.0, 8.0, 0.0], atol=1e-9)
    assert light.actor_transform.rotation.yaw == pytest.approx(90.0)


def test_controllers_group_lights(tiny_map):
    (controller,) = tiny_map.controllers()
    assert (controller.id, controller.junction_id, controller.sequence) == ("500", 100, 0)
    assert controller.signal_ids == ("1",)
    assert tiny_map.traffic_light_groups() == {"500": ("1",)}
    assert tiny_map.junctions[100].controller_ids == ("500",)


def test_stop_sign_box(tiny_map):
    (stop,) = tiny_map.stop_signs()
    assert stop.is_stop and tiny_map.signal("2") is stop
    lane = next(lane for lane in stop.lanes if lane.lane_id == -1)
    # Cube of half size 0.45 · 3.5 = 1.575, centred that far before s = 20 on road 2: CARLA (70 + 18.425, 1.75).
    np.testing.assert_allclose(lane.trigger_box.location.to_list(), [88.425, 1.75, 0.0], atol=1e-6)
    np.testing.assert_allclose(lane.trigger_box.extent.to_list(), [1.575] * 3, atol=1e-9)
    assert all(lane.stop_waypoint.lane_type == LaneType.DRIVING for lane in stop.lanes)


def test_speed_limits(tiny_map):
    # Before the 60 km/h sign (s = 5) the road type says 40 km/h; after it, 60, also beyond the junction.
    assert tiny_map.speed_limit(tiny_map.get_waypoint_xodr(1, -1, 2.0)) == pytest.approx(40.0)
    assert tiny_map.speed_limit(tiny_map.get_waypoint_xodr(1, -1, 10.0)) == pytest.approx(60.0)
    assert tiny_map.speed_limit(tiny_map.get_waypoint_xodr(3, -1, 10.0)) == pytest.approx(60.0)
    assert tiny_map.speed_limit(tiny_map.get_waypoint_xodr(4, -1, 10.0)) == pytest.approx(60.0)
    # The westbound lane never passes the sign: road type speed.
    assert tiny_map.speed_limit(tiny_map.get_waypoint_xodr(1, 1, 10.0)) == pytest.approx(40.0)
    (sign,) = tiny_map.speed_limit_signs()
    assert sign.speed_limit == 60.0 and len(sign.lanes) == 2


def test_governing_signals_by_lane(tiny_map):
    # Road 1 lane -1 holds the light's box and the speed sign's box; the westbound lane holds none.
    ids = {s.id for s in tiny_map.governing_signals(tiny_map.get_waypoint_xodr(1, -1, 30.0))}
    assert ids == {"1", "3"}
    assert tiny_map.governing_signals(tiny_map.get_waypoint_xodr(1, 1, 30.0)) == []
    assert [s.id for s in tiny_map.governing_signals(tiny_map.get_waypoint_xodr(2, -2, 1.0))] == ["2"]
