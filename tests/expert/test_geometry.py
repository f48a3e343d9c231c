"""Box overlap, route resampling and shifting, stop-sign logic, forecasts and the path-clear test."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.forecasting import (
    BoxTrack,
    colliding,
    forecast_vehicles,
    forecast_walkers,
    leading_vehicle_ids,
    num_future_frames,
    trailing_vehicle_ids,
)
from b2d_data.expert.hazard_heuristic import segments_cross, vehicle_hazard, walker_hazard
from b2d_data.expert.lights_and_signs import StopSignTracker, stop_sign_centre
from b2d_data.expert.obb import OrientedBox, boxes_overlap
from b2d_data.expert.obstacle_scenarios import is_overtaking_path_clear, min_time_for_distance
from b2d_data.expert.route_processing import light_governs_mask, resample, route_headings
from b2d_data.expert.route_shifting import extend_shift, shift_route_smoothly, smooth_transition, still_before_shift
from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform
from b2d_data.sim.api import TrafficLightInfo, TrafficLightState, TrafficSignInfo, VehicleControl
from b2d_data.sim.traffic_rules import inside_stop_box

CFG = ExpertConfig()


# ------------------------------------------------------------------------------------------------ SAT / OBB
def _box(x: float, y: float = 0.0, z: float = 0.0, yaw: float = 0.0, ext=(1.0, 1.0, 1.0)) -> OrientedBox:
    return OrientedBox.from_yaw((x, y, z), ext, yaw)


def test_axis_aligned_boxes():
    assert boxes_overlap(_box(0.0), _box(1.9))  # extents 1 + 1 > 1.9
    assert not boxes_overlap(_box(0.0), _box(2.1))
    assert not boxes_overlap(_box(0.0), _box(0.0, z=2.5))  # stacked: separated along z


def test_rotated_box_overlap():
    # B turned 45°: its half width along A's x axis is √2 ≈ 1.414, so the limit is 1 + 1.414 = 2.414
    assert boxes_overlap(_box(0.0), _box(2.3, yaw=45.0))
    assert not boxes_overlap(_box(0.0), _box(2.5, yaw=45.0))


def test_cross_axis_separation():
    # long thin boxes crossing diagonally in plan but at different heights overlap only if z overlaps
    a = _box(0.0, ext=(5.0, 0.2, 0.5))
    b = _box(0.0, yaw=90.0, ext=(5.0, 0.2, 0.5))
    assert boxes_overlap(a, b)
    assert not boxes_overlap(a, _box(0.0, z=1.2, yaw=90.0, ext=(5.0, 0.2, 0.5)))


def test_corners_2d():
    corners = _box(1.0, 2.0, yaw=90.0, ext=(2.0, 1.0, 1.0)).corners_2d()
    # yaw 90° in CARLA's frame: the box's x axis points +y
    assert np.allclose(sorted(corners[:, 0]), [0.0, 0.0, 2.0, 2.0])
    assert np.allclose(sorted(corners[:, 1]), [0.0, 0.0, 4.0, 4.0])


# ------------------------------------------------------------------------------------------- resampling
def test_resample_spacing_and_commands():
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0]])
    cmds = [RoadOption.LANEFOLLOW, RoadOption.LANEFOLLOW, RoadOption.RIGHT, RoadOption.RIGHT]
    out, out_cmds, nearest = resample(pts, cmds, 10)
    assert out.shape == (31, 3)  # 3 m of polyline at 0.1 m, both ends included
    assert np.allclose(np.linalg.norm(np.diff(out[:, :2], axis=0), axis=1), 0.1)
    assert np.allclose(out[25], [2.0, 0.5, 0.0])
    # nearest original point: 1.4 m → point 1, 1.6 m → point 2
    assert nearest[14] == 1 and nearest[16] == 2
    assert out_cmds[14] is RoadOption.LANEFOLLOW and out_cmds[16] is RoadOption.RIGHT


def test_route_headings():
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    # middle point: from (0,0) to (1,1) → 45°; ends copy their neighbour
    assert np.allclose(route_headings(pts), [45.0, 45.0, 45.0])


def _light(stop_x: float, yaw: float = 0.0, state=TrafficLightState.RED) -> TrafficLightInfo:
    class _StopWp:
        transform = Transform(Location(stop_x, 0.0, 0.0), Rotation(yaw=yaw))
        lane_width = 3.5

    return TrafficLightInfo(
        id=7, transform=Transform(Location(stop_x, 4.0, 0.0), Rotation(yaw=yaw + 90.0)), state=state,
        trigger_volume=BoundingBox(Location(), Location(1.75, 1.5, 1.0)), stop_waypoints=(_StopWp(),),
        affected_lane_waypoints=(), group_id=0, opendrive_id="7", level_bbox=BoundingBox(Location(), Location()),
        level_bbox_transform=Transform(),
    )  # fmt: skip


def test_light_governs_points_up_to_5m_before_the_stop_line(make_route):
    route = make_route(50.0)
    mask = light_governs_mask(CFG, route.original_points, route.headings, _light(30.0))
    governed = np.flatnonzero(mask)
    assert governed.min() == 250 and governed.max() == 300  # 25 m … 30 m
    # a light for the opposite direction on the same spot governs nothing
    assert not light_governs_mask(CFG, route.original_points, route.headings, _light(30.0, yaw=180.0)).any()


# ----------------------------------------------------------------------------------------- route shifting
def test_smooth_transition():
    assert smooth_transition(0.0) == 0.0
    assert smooth_transition(0.5) == pytest.approx(0.5)
    assert smooth_transition(0.25) == pytest.approx((1 - math.cos(math.pi / 4)) / 2)
    assert smooth_transition(1.0) == pytest.approx(1.0)


def test_shift_route_smoothly_cosine_ramps(make_route):
    route = make_route(40.0)
    # shift left (−y, lanes 3.5 m apart) over points [100, 300) with 8 m (80 point) ramps
    shift_route_smoothly(route, 100, 300, True, 80)
    y = route.points[:, 1]
    assert y[99] == 0.0 and y[100] == pytest.approx(0.0)
    assert y[120] == pytest.approx(-3.5 * (1 - math.cos(math.pi * 0.25)) / 2)  # k = 0.146
    assert y[140] == pytest.approx(-1.75)  # k = 0.5 halfway up the ramp
    assert y[180] == pytest.approx(-3.5) and y[200] == pytest.approx(-3.5)
    assert y[260] == pytest.approx(-1.75)  # halfway down: (300 − 260) / 80
    assert y[300] == 0.0
    assert route.commands[120] is RoadOption.CHANGELANELEFT
    assert route.commands[200] is RoadOption.LANEFOLLOW
    assert route.commands[250] is RoadOption.CHANGELANERIGHT
    assert np.all(route.original_points[:, 1] == 0.0)  # the original copy is never shifted


def test_shift_route_partial_factor(make_route):
    route = make_route(40.0)
    shift_route_smoothly(route, 100, 300, False, 40, factor=0.6)  # right (+y), 60 % of the way
    assert route.points[200, 1] == pytest.approx(0.6 * 3.5)
    assert route.points[120, 1] == pytest.approx(0.6 * 3.5 * 0.5)  # (120 − 100) / 40 = 0.5


def test_extend_shift_moves_the_return_ramp(make_route):
    route = make_route(60.0)
    shift_route_smoothly(route, 100, 300, True, 80)
    end = extend_shift(route, 300 - 80, 450, True, 80)
    assert end == 450 - 80
    assert route.points[300, 1] == pytest.approx(-3.5)  # formerly the end of the shift, now fully shifted
    assert route.points[410, 1] == pytest.approx(-1.75)  # halfway down the new ramp
    assert route.points[450, 1] == 0.0
    assert route.commands[420] is RoadOption.CHANGELANERIGHT


def test_still_before_shift(make_route):
    route = make_route(60.0)
    shift_route_smoothly(route, 200, 500, True, 80)  # left (−y) over x = 20 … 50 m; lanes 3.5 m wide
    beside = np.array([17.0, -3.5, 0.0])  # a car in the target lane, 3.5 m > half a lane from the ego's lane
    ahead = np.array([35.0, 0.0, 0.0])  # the obstacle the shift goes around, in the ego's lane
    route.index = 150  # x = 15: the shift starts 5 m ahead, inside a 10.5 m look-ahead
    assert still_before_shift(route, np.array([15.0, 0.0, 0.0]), beside, 0.5, 10.5)
    assert not still_before_shift(route, np.array([15.0, 0.0, 0.0]), ahead, 0.5, 10.5)
    assert not still_before_shift(route, np.array([15.0, -0.6, 0.0]), beside, 0.5, 10.5)  # 0.6 m toward the shift
    assert not still_before_shift(route, np.array([15.0, 0.0, 0.0]), beside, 0.5, 4.0)  # the shift is beyond 4 m
    route.index = 250  # x = 25, inside the ramp (route at y = −1.75) while the ego is still on its lane
    assert still_before_shift(route, np.array([25.0, 0.2, 0.0]), beside, 0.5, 10.5)
    route.index = 50  # x = 5: nothing shifted within 10.5 m
    assert not still_before_shift(route, np.array([5.0, 0.0, 0.0]), beside, 0.5, 10.5)


def test_closest_index(make_route):
    route = make_route(50.0)
    assert route.closest_index(0, np.array([12.34, 1.0])) == 123
    assert route.closest_index(400, np.array([12.34, -1.0])) == 123


def test_route_index_moves_at_most_4m(make_route):
    route = make_route(50.0)
    assert route.update_index(np.array([2.0, 0.3])) == 20
    assert route.update_index(np.array([30.0, 0.0])) == 20 + 39  # only the next 40 points are searched


# ----------------------------------------------------------------------------------------------- stop signs
def _stop_sign(x: float) -> TrafficSignInfo:
    # pole beside an east-bound lane, actor x axis across the lane (yaw 90°); trigger centre on the lane at x
    return TrafficSignInfo(
        id=3, type_id="traffic.stop", transform=Transform(Location(x, 3.0, 0.0), Rotation(yaw=90.0)),
        trigger_volume=BoundingBox(Location(-3.0, 0.0, 1.0), Location(1.75, 1.5, 1.0)),
        level_bbox=BoundingBox(Location(), Location()), level_bbox_transform=Transform(),
    )  # fmt: skip


def test_stop_sign_trigger_box():
    sign = _stop_sign(20.0)
    assert np.allclose(stop_sign_centre(sign), [20.0, 0.0, 1.0])
    # The shared rule is CARLA's axis-aligned test: extent x (1.75) along world x, y (1.5) along world y, ×1.2,
    # even though this trigger volume's actor is turned 90°: half sizes 2.1 m in x and 1.8 m in y.
    centre, extent = Location(20.0, 0.0, 1.0), sign.trigger_volume.extent
    assert inside_stop_box(Location(22.0, 0.0, 0.0), centre, extent)
    assert not inside_stop_box(Location(22.2, 0.0, 0.0), centre, extent)
    assert inside_stop_box(Location(20.0, 1.7, 0.0), centre, extent)
    assert not inside_stop_box(Location(20.0, 1.9, 0.0), centre, extent)


def test_stop_sign_clearing_logic():
    sign = _stop_sign(20.0)
    tracker = StopSignTracker(CFG)
    # 5 m/s, 3 m away: s* = 2 + 0.5 + 25 / (2·√(24·8.7)) = 3.365 m > 3 m, so IDM brakes
    target, distance = tracker.target_speed(8.0, 5.0, np.array([17.0, 0.0, 1.0]), sign)
    assert distance == pytest.approx(3.0) and target < 5.0 and not tracker.cleared
    # slow (0.2 m/s) and close: not cleared yet
    tracker.target_speed(8.0, 0.2, np.array([17.5, 0.0, 1.0]), sign)
    assert not tracker.cleared
    # below 0.1 m/s and within 3 m: cleared, no constraint any more
    target, _ = tracker.target_speed(8.0, 0.05, np.array([17.5, 0.0, 1.0]), sign)
    assert tracker.cleared and target == 8.0
    # driving on through the junction it stays cleared …
    target, _ = tracker.target_speed(8.0, 4.0, np.array([27.0, 0.0, 1.0]), sign)
    assert tracker.cleared and target == 8.0
    # … until it is more than 10 m away
    tracker.target_speed(8.0, 6.0, np.array([30.5, 0.0, 1.0]), sign)
    assert not tracker.cleared
    assert tracker.target_speed(8.0, 6.0, np.array([0.0, 0.0, 1.0]), None) == (8.0, math.inf)


# ---------------------------------------------------------------------------------------------- forecasts
def test_horizon():
    assert num_future_frames(CFG, False) == 40
    assert num_future_frames(CFG, True) == 22


def test_vehicle_forecast_boxes_grow(make_vehicle):
    car = make_vehicle(5, 0.0, 0.0, speed=10.0, control=VehicleControl(throttle=0.0))
    (track,) = forecast_vehicles(CFG, [car], 40, near_lane_change=False)
    assert np.allclose(track.centres[:, 0], 0.5 * np.arange(1, 41))  # constant 10 m/s
    assert np.allclose(track.extents[:, 0], 2.4 * 1.2)  # ×1.2 along (max(1.2, 1.2·i/N))
    assert track.extents[0, 1] == pytest.approx(1.0)  # ×max(1, 1.3·0/40)
    assert track.extents[39, 1] == pytest.approx(1.0 * 1.3 * 39 / 40)
    (slow,) = forecast_vehicles(CFG, [make_vehicle(6, 0.0, 0.0, speed=0.5)], 40, near_lane_change=True)
    assert np.allclose(slow.extents[:, :2], [2.4, 1.0])  # below 1 m/s: real size
    (lc,) = forecast_vehicles(CFG, [car], 22, near_lane_change=True)
    assert np.allclose(lc.extents[:, 0], 2.4 * 2.0)


def test_a_flow_car_is_forecast_along_its_hinted_path(make_vehicle):
    from b2d_data.expert.forecasting import along_path

    # 10 m/s east from the origin; the path turns south-bound (+y) 10 m ahead: an L of 10 m then 30 m
    car = make_vehicle(5, 0.0, 0.0, speed=10.0)
    (straight,) = forecast_vehicles(CFG, [car], 40, near_lane_change=False)
    track = along_path(CFG, straight, car, np.array([[-5.0, 0.0], [10.0, 0.0], [10.0, 30.0]]))
    # frame i is (i + 1) × 0.05 s ahead: 0.5 m per frame; frame 9 (5 m) still on the first leg, heading 0
    assert track.centres[9, :2] == pytest.approx([5.0, 0.0]) and track.yaws[9] == pytest.approx(0.0)
    # frame 39 (2 s, 20 m): 10 m along the second leg, heading +90° (the kinematic forecast: 20 m straight on)
    assert track.centres[39, :2] == pytest.approx([10.0, 10.0]) and track.yaws[39] == pytest.approx(np.pi / 2)
    assert straight.centres[39, :2] == pytest.approx([20.0, 0.0])
    assert np.array_equal(track.extents, straight.extents)
    # a car pushed 4 m off its path keeps the kinematic forecast
    assert along_path(CFG, straight, car, np.array([[-5.0, 4.0], [10.0, 4.0]])) is straight


def test_walker_forecast(make_walker):
    (track,) = forecast_walkers(CFG, [make_walker(9, 5.0, -3.0, direction=(0.0, 1.0), speed=0.2)], 40)
    # speed raised to 0.5 m/s; 40 steps of 0.05 s → 1 m
    assert track.centres[-1, 1] == pytest.approx(-2.0)
    assert np.allclose(track.extents[:, :2], 1.5)


def test_colliding_uses_same_frame(make_vehicle):
    frames = 10
    ego = BoxTrack(1, np.stack([np.arange(frames) * 1.0, np.zeros(frames), np.zeros(frames)], axis=1),
                   np.zeros(frames), np.tile([2.0, 1.0, 1.0], (frames, 1)))
    # the other box is where the ego will be at frame 9, but only at frame 0 → no hit
    other = BoxTrack(2, np.tile([9.0, 0.0, 0.0], (frames, 1)) + np.array([[0.0, 10.0 * (i > 0), 0.0]
                                                                          for i in range(frames)]),
                     np.zeros(frames), np.tile([2.0, 1.0, 1.0], (frames, 1)))
    assert colliding(ego, [other]) == []
    still = BoxTrack(3, np.tile([9.0, 0.0, 0.0], (frames, 1)), np.zeros(frames), np.tile([2.0, 1.0, 1.0], (frames, 1)))
    assert colliding(ego, [still]) == [3]


def test_colliding_finds_boxes_that_touch_only_at_a_corner():
    # the footprint-circle prefilter must keep a pair whose boxes meet corner to corner: centres 4.41 m apart,
    # circumradii 2 × hypot(2, 1) = 4.47 m (a prefilter on the longer half extent, 2 + 2 m, would drop it)
    frames = 5
    ego = BoxTrack(1, np.zeros((frames, 3)), np.zeros(frames), np.tile([2.0, 1.0, 1.0], (frames, 1)))

    def other(actor_id: int, x: float, y: float) -> BoxTrack:
        return BoxTrack(actor_id, np.tile([x, y, 0.0], (frames, 1)), np.zeros(frames), np.tile([2.0, 1.0, 1.0],
                                                                                                (frames, 1)))

    corner = other(7, 3.95, 1.95)  # a 5 cm square of overlap at the corners
    gap = other(8, 4.05, 1.95)  # 5 cm apart along x
    far = other(9, 40.0, 0.0)
    assert colliding(ego, [far, corner, gap, far]) == [7]
    assert colliding(ego, [gap, far]) == []


def test_colliding_agrees_with_the_full_separating_axis_test():
    # random boxes around the ego, many of them touching or nearly: the answer of the separating-axis test over
    # every actor, in the given order
    from b2d_data.expert.obb import overlap_many, yaw_axes

    rng = np.random.default_rng(3)
    frames = 40
    ego = BoxTrack(0, np.column_stack([np.linspace(0.0, 20.0, frames), np.zeros(frames), np.zeros(frames)]),
                   rng.uniform(-0.2, 0.2, frames), np.tile([2.9, 1.3, 0.8], (frames, 1)))
    others = [BoxTrack(k, np.column_stack([rng.uniform(-5.0, 25.0) + rng.uniform(-1.0, 1.0, frames),
                                           rng.uniform(-8.0, 8.0) + rng.uniform(-1.0, 1.0, frames),
                                           np.zeros(frames)]),
                       rng.uniform(-np.pi, np.pi, frames), np.tile([2.4, 1.0, 0.8], (frames, 1))) for k in range(60)]
    centres = np.stack([t.centres for t in others])
    hit = overlap_many(np.broadcast_to(ego.centres, centres.shape), np.broadcast_to(yaw_axes(ego.yaws),
                                                                                    centres.shape + (3,)),
                       np.broadcast_to(ego.extents, centres.shape), centres,
                       yaw_axes(np.stack([t.yaws for t in others])), np.stack([t.extents for t in others]))
    expected = [t.actor_id for t, h in zip(others, hit.any(axis=1)) if h]
    assert 0 < len(expected) < len(others)
    assert colliding(ego, others) == expected


def test_vehicle_forecast_of_many_is_each_alone_to_the_bit(make_vehicle):
    # vehicles of different boxes, speeds and controls forecast together: each track is its forecast alone
    from b2d_data.format.transform import BoundingBox, Location

    cars = [make_vehicle(1, 3.0, -2.0, yaw=30.0, speed=9.0, control=VehicleControl(throttle=0.6, steer=0.2)),
            make_vehicle(2, -8.0, 4.0, yaw=-120.0, speed=0.4, half=(1.1, 0.4, 0.8)),
            make_vehicle(3, 20.0, 1.0, yaw=178.0, speed=14.0, half=(6.0, 1.4, 1.9),
                         control=VehicleControl(brake=1.0, steer=-0.4))]
    cars[2] = replace(cars[2], bounding_box=BoundingBox(Location(0.8, -0.3, 1.9), Location(6.0, 1.4, 1.9)))
    for near_lc, frames in ((False, 40), (True, 22)):
        together = forecast_vehicles(CFG, cars, frames, near_lc)
        for car, track in zip(cars, together):
            (alone,) = forecast_vehicles(CFG, [car], frames, near_lc)
            assert track.actor_id == car.id
            for a, b in ((track.centres, alone.centres), (track.yaws, alone.yaws), (track.extents, alone.extents)):
                assert a.shape == b.shape and np.array_equal(a, b)


def test_vehicle_forecast_box_centre_turns_with_the_car(make_vehicle):
    # a standing car heading +90° (south in CARLA's frame) whose box sits 1 m ahead, 0.5 m right and 0.7 m up of
    # its origin: the box centre is 1 m along +y and 0.5 m along −x of it; a standing car keeps its real size
    from b2d_data.format.transform import BoundingBox, Location

    box = BoundingBox(Location(1.0, 0.5, 0.7), Location(2.0, 0.9, 0.7))
    south = replace(make_vehicle(4, 10.0, 5.0, yaw=90.0), bounding_box=box)
    east = replace(make_vehicle(5, 10.0, 5.0), bounding_box=box)  # heading +x: 1 m along +x, 0.5 m along +y
    south_track, east_track = forecast_vehicles(CFG, [south, east], 10, near_lane_change=False)
    assert south_track.centres == pytest.approx(np.tile([9.5, 6.0, 0.7], (10, 1)))
    assert south_track.yaws == pytest.approx(np.full(10, np.pi / 2))
    assert east_track.centres == pytest.approx(np.tile([11.0, 5.5, 0.7], (10, 1)))
    for track in (south_track, east_track):
        assert np.array_equal(track.extents, np.tile([2.0, 0.9, 0.7], (10, 1)))


def test_leading_and_trailing_vehicles(make_route, make_vehicle):
    route = make_route(200.0)
    route.index = 500  # ego at x = 50
    cars = [
        make_vehicle(1, 70.0, 1.0),  # ahead, in lane → leading
        make_vehicle(2, 70.0, 3.5),  # ahead, next lane → neither
        make_vehicle(3, 70.0, 0.0, yaw=90.0),  # ahead but crossing → neither
        make_vehicle(4, 35.0, 0.5),  # behind in lane → trailing
        make_vehicle(5, 140.0, 0.0),  # 90 m ahead: beyond 80 m of route… but within 2.5 m of its last sample
    ]
    assert leading_vehicle_ids(CFG, route, cars) == {1}
    assert trailing_vehicle_ids(CFG, route, cars) == {4}


# ------------------------------------------------------------------------------------------ TCP heuristic
def test_segments_cross():
    assert segments_cross(np.zeros(2), np.array([10.0, 0.0]), np.array([5.0, -3.0]), np.array([0.0, 8.0]))
    assert not segments_cross(np.zeros(2), np.array([10.0, 0.0]), np.array([12.0, -3.0]), np.array([0.0, 8.0]))


def test_tcp_vehicle_and_walker_hazards(make_vehicle, make_walker):
    ego = make_vehicle(1, 0.0, 0.0, speed=2.0, role="hero")
    assert vehicle_hazard(CFG, ego, [ego, make_vehicle(2, 6.0, 0.5)]) == 2  # 6 m ahead, same heading
    assert vehicle_hazard(CFG, ego, [make_vehicle(2, 9.0, 0.0)]) is None  # beyond max(7.5, 2·2)
    assert vehicle_hazard(CFG, ego, [make_vehicle(2, -5.0, 0.0)]) is None  # behind
    assert vehicle_hazard(CFG, ego, [make_vehicle(2, 6.0, 0.0, yaw=180.0)]) == 2  # head-on, straight ahead
    assert vehicle_hazard(CFG, ego, [make_vehicle(2, 6.0, 2.5, yaw=180.0)]) is None  # oncoming, next lane
    assert walker_hazard(CFG, ego, [make_walker(3, 6.0, -2.0, direction=(0.0, 1.0))]) == 3
    assert walker_hazard(CFG, ego, [make_walker(3, 6.0, 4.0, direction=(0.0, 1.0))]) is None
    # the first vehicle in the cone, in the given order, past cars far off in x or in y; reach max(7.5, 2·10) = 20 m
    fast = make_vehicle(1, 0.0, 0.0, speed=10.0, role="hero")
    cars = [make_vehicle(4, 60.0, 0.5), make_vehicle(5, 3.0, 45.0), make_vehicle(6, 19.5, 0.5),
            make_vehicle(7, 8.0, 0.0)]
    assert vehicle_hazard(CFG, fast, cars) == 6
    assert vehicle_hazard(CFG, fast, cars[:2]) is None


# ------------------------------------------------------------------------------------- path-clear (§1.9)
def test_min_time_for_distance():
    # capped at the current speed: 5.25 m at 10 m/s = 0.525 s
    assert min_time_for_distance(CFG, 5.25, 10.0, 10.0) == pytest.approx(0.525)
    # from standstill: first tick covers 0 m, then the polynomial adds 120·0.00904221 = 1.085 m/s per tick
    t = min_time_for_distance(CFG, 20.0, 50 / 3.6, 0.0)
    assert 1.5 < t < 2.5


class _LaneMap:
    """get_waypoint → a fake waypoint whose lane is −1 for y > 0 (ego lane) and 1 for y < 0 (opposite)."""

    def get_waypoint(self, location):
        class _Wp:
            road_id = 1
            lane_id = -1 if location.y > 0 else 1

        return _Wp()


def test_path_clear(make_route, make_vehicle):
    route = make_route(100.0)
    ego = make_vehicle(1, 0.0, 1.75, speed=5.0, role="hero")
    lanes = {(1, 1)}
    to_index = 300  # shift end 30 m ahead
    clear = is_overtaking_path_clear(CFG, _LaneMap(), route, ego, [ego], to_index, 8.0, lanes, 50 / 3.6)
    assert clear
    # oncoming car 100 m ahead at 10 m/s reaches the shift end in (70 − 2.4)/10 = 6.8 s > ego's time: clear
    far = make_vehicle(2, 100.0, -1.75, yaw=180.0, speed=10.0)
    assert is_overtaking_path_clear(CFG, _LaneMap(), route, ego, [ego, far], to_index, 8.0, lanes, 50 / 3.6)
    # 40 m ahead at 10 m/s: (10 − 2.4)/10 = 0.76 s → blocked
    near = make_vehicle(3, 40.0, -1.75, yaw=180.0, speed=10.0)
    assert not is_overtaking_path_clear(CFG, _LaneMap(), route, ego, [ego, near], to_index, 8.0, lanes, 50 / 3.6)
    # already inside the overtaking zone (shift end behind it)
    inside = make_vehicle(4, 20.0, -1.75, yaw=180.0, speed=0.0)
    assert not is_overtaking_path_clear(CFG, _LaneMap(), route, ego, [ego, inside], to_index, 8.0, lanes, 50 / 3.6)
    # behind the ego: ignored
    behind = make_vehicle(5, -20.0, -1.75, yaw=180.0, speed=10.0)
    assert is_overtaking_path_clear(CFG, _LaneMap(), route, ego, [ego, behind], to_index, 8.0, lanes, 50 / 3.6)


def test_vehicle_forecast_matches_the_one_step_model(make_vehicle):
    from b2d_data.expert.kinematic_bicycle import forecast_other_vehicles

    control = VehicleControl(throttle=0.7, steer=-0.3)
    (track,) = forecast_vehicles(CFG, [make_vehicle(5, 1.0, 2.0, yaw=30.0, speed=7.0, control=control)], 40, False)
    x, y, yaw, v = np.array([1.0]), np.array([2.0]), np.radians([30.0]), np.array([7.0])
    for _ in range(40):
        x, y, yaw, v = forecast_other_vehicles(CFG, x, y, yaw, v, np.array([-0.3]), np.array([0.7]), np.zeros(1))
    assert track.centres[-1, :2] == pytest.approx([x[0], y[0]])
    assert track.yaws[-1] == pytest.approx(yaw[0])


def test_vehicle_forecast_is_the_step_by_step_euler_forecast_to_the_bit(make_vehicle):
    # the running sums of forecast_vehicles against the Euler steps one frame at a time; a braking car comes to a
    # stand within the horizon (the speed's clamp at 0), a faster one does not
    cars = [make_vehicle(1, 1.0, 2.0, yaw=30.0, speed=7.0, control=VehicleControl(throttle=0.7, steer=-0.3)),
            make_vehicle(2, -4.0, 9.5, yaw=-170.0, speed=3.9, control=VehicleControl(brake=1.0, steer=0.5)),
            make_vehicle(3, 0.3, -7.0, yaw=95.0, speed=12.5, control=VehicleControl(brake=1.0)),
            make_vehicle(4, 6.0, 6.0, yaw=-45.0, speed=0.0, control=VehicleControl(throttle=0.4, steer=1.0))]
    frames = 40
    tracks = forecast_vehicles(CFG, cars, frames, False)
    from b2d_data.expert.kinematic_bicycle import slip_angle

    x = np.array([c.location.x for c in cars])
    y = np.array([c.location.y for c in cars])
    yaw = np.radians([c.transform.rotation.yaw for c in cars])
    speed = np.array([c.speed() for c in cars])
    steer = np.array([c.control.steer for c in cars])
    accel = np.where(np.array([c.control.brake for c in cars]) >= CFG.other_vehicle_brake_threshold,
                     CFG.other_brake_acceleration, np.array([c.control.throttle for c in cars])
                     * CFG.other_throttle_acceleration)
    beta = slip_angle(CFG, steer)
    turn = np.sin(beta) / CFG.rear_wheel_base * CFG.dt
    for i in range(frames):
        heading = yaw + beta
        x = x + speed * np.cos(heading) * CFG.dt
        y = y + speed * np.sin(heading) * CFG.dt
        yaw = yaw + speed * turn
        speed = np.maximum(0.0, speed + CFG.dt * accel)
        for k, track in enumerate(tracks):
            assert track.centres[i, 0] == x[k] and track.centres[i, 1] == y[k] and track.yaws[i] == yaw[k]
    assert speed[1] == 0.0 and speed[2] > 0.0  # one braking car reached the clamp, the other did not
    assert tracks[1].centres[-1, 0] == tracks[1].centres[30, 0] != tracks[1].centres[0, 0]


# ------------------------------------------------------------------------------------ scenario handling
def test_invading_turn_offsets_route_to_the_right(make_route):
    from b2d_data.expert.route_shifting import shift_route_for_invading_turn

    route = make_route(100.0)
    route.config = replace(route.config, invading_turn_shift_from_trigger=False)  # PDM-Lite's region
    start, end = shift_route_for_invading_turn(route, np.array([40.0, 0.0]), np.array([60.0, 0.0]), 1.2)
    assert (start, end) == (400 - 150, 600 + 100)  # 15 m before the first cone, 10 m after the last
    assert np.allclose(route.points[start:end, 1], 1.2)  # +y is right of an east-bound route
    assert route.points[start - 1, 1] == 0.0 and route.points[end, 1] == 0.0
    # ours (the default): from the ego's route point (index 0 here, the route's start) to 10 m after the last cone
    route = make_route(100.0)
    assert route.index == 0
    assert shift_route_for_invading_turn(route, np.array([40.0, 0.0]), np.array([60.0, 0.0]), 1.2) == (0, 700)
    assert np.allclose(route.points[0:700, 1], 1.2) and route.points[700, 1] == 0.0
    # next to a shoulder the offset keeps 0.3 m from the fence
    shoulder = make_route(100.0, right_type=__import__("b2d_data.maps", fromlist=["LaneType"]).LaneType.SHOULDER)
    shift_route_for_invading_turn(shoulder, np.array([40.0, 0.0]), np.array([60.0, 0.0]), 1.2)
    assert shoulder.points[500, 1] == pytest.approx(0.9)


def _snapshot(actors):
    from b2d_data.format.weather import ROUTE_DEFAULT
    from b2d_data.sim.api import Snapshot

    return Snapshot(frame=1, timestamp=0.05, actors={a.id: a for a in actors}, traffic_lights={}, traffic_signs={},
                    collisions=(), weather=ROUTE_DEFAULT)


def test_obstacle_manager_handles_the_nearest_live_scenario(make_route, make_vehicle):
    from b2d_data.expert.obstacle_scenarios import ObstacleScenarioManager
    from b2d_data.sim.api import ScenarioHint

    route = make_route(200.0)
    ego = make_vehicle(1, 0.0, 0.0, role="hero")
    near, far = make_vehicle(2, 40.0, 1.2), make_vehicle(3, 120.0, 1.2)
    snap = _snapshot([ego, near, far])
    manager = ObstacleScenarioManager(CFG, town=None)
    hints = [ScenarioHint("ParkedObstacle", 3, 3, "right"), ScenarioHint("ParkedObstacle", 2, 2, "right"),
             ScenarioHint("ParkedObstacle", 99, 99, "right")]  # actor 99 is gone: dropped
    result = manager.step(snap, ego, route, hints, 8.0)
    assert result.scenario == "ParkedObstacle" and not result.keep_driving and result.target_speed == 8.0
    # the near car (40 m) was handled: shift from 40 − 2.4 − 8 m to 40 + 2.4 + 8 m, to the left (−y)
    assert manager.records[("ParkedObstacle", 2)].done
    assert (manager.records[("ParkedObstacle", 2)].from_index, manager.records[("ParkedObstacle", 2)].to_index) == (
        296, 504)  # fmt: skip
    assert route.points[400, 1] == pytest.approx(-3.5)
    # the far one (120 m) is beyond 50 m: next frame it is the nearest but still too far to shift
    manager.step(snap, ego, route, hints, 8.0)
    assert not manager.records[("ParkedObstacle", 3)].changed_route
    assert route.points[1200, 1] == 0.0


def test_two_way_obstacle_waits_then_commits(make_route, make_vehicle):
    from b2d_data.expert.obstacle_scenarios import ObstacleScenarioManager
    from b2d_data.sim.api import ScenarioHint

    route = make_route(200.0)
    route.index = 300  # ego at x = 30
    ego = make_vehicle(1, 30.0, 0.0, speed=3.0, role="hero")
    parked = make_vehicle(2, 60.0, 1.2)
    oncoming = make_vehicle(3, 90.0, -3.5, yaw=180.0, speed=8.0)
    hint = ScenarioHint("ParkedObstacleTwoWays", 2, 2, "right")
    manager = ObstacleScenarioManager(CFG, town=_LaneMap())
    result = manager.step(_snapshot([ego, parked, oncoming]), ego, route, [hint], 8.0)
    record = manager.records[("ParkedObstacleTwoWays", 2)]
    # shift [60 − 2.4 − 4 + 0.5, 60 + 2.4 + 4 − 0.5] m, 60 % of the way into the opposite lane
    assert (record.from_index, record.to_index) == (541, 659)
    assert route.points[600, 1] == pytest.approx(-0.6 * 3.5)
    # the shift starts 24 m ahead (> 8 m): wait with IDM toward 1.5 m past the shift start
    assert not result.keep_driving and result.reduced_by is not None
    assert result.reduced_by.distance == pytest.approx((541 + 15 - 300) / 10)
    # closer than 8 m to the shift start with an oncoming car 30 m away: still waiting
    route.index = 480
    ego = make_vehicle(1, 48.0, 0.0, speed=0.0, role="hero")
    oncoming = make_vehicle(3, 80.0, -3.5, yaw=180.0, speed=8.0)
    result = manager.step(_snapshot([ego, parked, oncoming]), ego, route, [hint], 8.0)
    assert not result.keep_driving and not record.path_clear
    # once the oncoming car has passed (behind the ego), commit at 50 km/h without forecasting
    oncoming = make_vehicle(3, 30.0, -3.5, yaw=180.0, speed=8.0)
    result = manager.step(_snapshot([ego, parked, oncoming]), ego, route, [hint], 8.0)
    assert result.keep_driving and result.target_speed == pytest.approx(50 / 3.6)
    # the commitment ends 2 m before the shift end
    route.index = 640
    manager.step(_snapshot([ego, parked]), ego, route, [hint], 8.0)
    assert record.done


def test_braking_forecast_stops_short_and_real_extents(make_route, make_vehicle):
    # the flow checks (expert.py ``_flow_cars``): where a full brake from now on leaves the ego, and real boxes
    from b2d_data.expert.forecasting import forecast_ego_boxes, with_extents
    from b2d_data.expert.lateral_controller import LateralPIDController
    from b2d_data.expert.longitudinal_controller import make_longitudinal_controller

    cfg = ExpertConfig.for_builtin()
    route = make_route(100.0, cfg)
    ego = make_vehicle(1, 0.0, 0.0, speed=8.0, half=(2.45, 1.06, 0.75))
    lateral, longitudinal = LateralPIDController(cfg), make_longitudinal_controller(cfg)
    stop = forecast_ego_boxes(cfg, ego, route, lateral, longitudinal, 8.0, 80, braking=True)
    go = forecast_ego_boxes(cfg, ego, route, lateral, longitudinal, 8.0, 80)
    # PDM-Lite's full-brake polynomial of the Lincoln: 28.8 → 27.0 km/h in the first 0.05 s (10 m/s²), harder
    # below, so the ego stands within 8² / (2 · 10) = 3.2 m (and surely beyond 8² / (2 · 20) = 1.6 m)
    assert 1.6 < stop.centres[-1, 0] < 3.2
    assert stop.centres[-1, 0] == pytest.approx(stop.centres[-20, 0], abs=1e-6)
    assert go.centres[-1, 0] == pytest.approx(8.0 * 4.0, abs=1.0)  # holding 8 m/s for 4 s
    assert route.index == 0  # the route cursor is restored
    real = with_extents(go, ego, margin=0.1)
    assert np.allclose(real.extents, [2.55, 1.16, 0.75]) and real.centres is go.centres


def test_a_flow_car_behind_in_the_ego_lane_sets_a_speed_floor(make_vehicle):
    from types import SimpleNamespace

    from b2d_data.expert.expert import Expert

    ego = make_vehicle(1, 0.0, 0.0, speed=5.0, role="hero")

    def floor(*others) -> float:
        snapshot = SimpleNamespace(vehicles=lambda: [ego, *others])
        return Expert._flow_follower_floor(SimpleNamespace(config=CFG), snapshot, ego)

    # 15 m behind at 15 m/s: bumper gap 15 - 2.4 - 2.4 = 10.2 m; closing to 3 m in 2.5 s allows 7.2 / 2.5 = 2.88 m/s
    # of speed difference: floor 12.12 m/s
    assert floor(make_vehicle(7, -15.0, 0.0, speed=15.0, role="scenario")) == pytest.approx(15.0 - 7.2 / 2.5)
    # within 3 m of bumper gap: the follower's own speed
    assert floor(make_vehicle(7, -7.0, 0.0, speed=15.0, role="scenario")) == pytest.approx(15.0)
    assert floor(make_vehicle(7, -45.0, 0.0, speed=15.0, role="scenario")) == 0.0  # beyond the 40 m range
    assert floor(make_vehicle(7, -15.0, 3.5, speed=15.0, role="scenario")) == 0.0  # the next lane
    assert floor(make_vehicle(7, -15.0, 0.0, speed=15.0, role="background")) == 0.0  # brakes for the ego
    assert floor(make_vehicle(7, 15.0, 0.0, speed=15.0, role="scenario")) == 0.0  # ahead


def test_a_flow_path_joins_the_route_where_it_runs_along_it():
    from b2d_data.expert.expert import _path_joins

    route = np.stack([np.arange(0.0, 40.0), np.full(40, 0.5)], axis=1)
    headings = np.zeros(40)
    along = np.stack([np.arange(-30.0, 30.0), np.zeros(60)], axis=1)
    crossing = np.stack([np.full(40, 10.0), np.arange(-20.0, 20.0)], axis=1)
    beside = np.stack([np.arange(-30.0, 30.0), np.full(60, 4.0)], axis=1)
    assert _path_joins(along, route, headings, CFG)  # 0.5 m off the route, same heading
    assert not _path_joins(crossing, route, headings, CFG)  # meets it at 90°
    assert not _path_joins(beside, route, headings, CFG)  # 3.5 m away: the next lane


def test_a_flow_joining_the_route_holds_the_ego_short_of_its_path(make_route, make_vehicle):
    from types import SimpleNamespace

    from b2d_data.expert.expert import Expert

    cfg = ExpertConfig()
    route = make_route(60.0, cfg)
    ego = make_vehicle(0, 0.0, 0.0)  # half extents 2.4 x 1.0
    crossing = np.stack([np.full(41, 12.0), np.linspace(-20.0, 0.0, 41)], axis=1)  # reaches the route at x = 12
    me = SimpleNamespace(config=cfg)
    # clearance 1.0 (ego half width) + 1.0 (flow car) + 1.0 (margin) = 3.0: the first route point nearer than that
    # to the path is x = 9.1 (10 points/m); the ego's front (2.4 m ahead of its centre) may drive 9.1 - 2.4 = 6.7 m
    assert Expert._conflict_hold(me, ego, route, [crossing]) == pytest.approx(6.7)
    # a path 3.5 m beside the route never comes within 3.0 m: no hold
    beside = np.stack([np.linspace(0.0, 60.0, 61), np.full(61, -3.5)], axis=1)
    assert Expert._conflict_hold(me, ego, route, [beside]) is None
    # a path reaching the route 40 m on is beyond the 25 m look-ahead
    far = crossing + np.array([28.0, 0.0])
    assert Expert._conflict_hold(me, ego, route, [far]) is None
    # from x = 7 the ego's front is already within reach of the car: 2.1 - 2.4 < 0, no hold (it brakes as before)
    route.index = 70
    assert Expert._conflict_hold(me, ego, route, [crossing]) is None
    # cars at the ends of their paths (nothing ahead of them): no hold, and no error
    route.index = 0
    assert Expert._conflict_hold(me, ego, route, [np.zeros((0, 2))]) is None


def test_a_shorter_ego_forecast_is_the_start_of_a_longer_one(make_route, make_vehicle):
    # what Expert._ego_boxes relies on to serve several horizons from one forecast
    from b2d_data.expert.forecasting import forecast_ego_boxes
    from b2d_data.expert.lateral_controller import LateralPIDController
    from b2d_data.expert.longitudinal_controller import make_longitudinal_controller

    cfg = ExpertConfig.for_builtin()
    route = make_route(100.0, cfg)
    route.points[:, 1] = 0.02 * route.points[:, 0]  # a slight slant, so that the ego steers
    ego = make_vehicle(1, 0.0, 0.5, yaw=4.0, speed=6.0, half=(2.45, 1.06, 0.75))
    for braking in (False, True):
        lateral, longitudinal = LateralPIDController(cfg), make_longitudinal_controller(cfg)
        long = forecast_ego_boxes(cfg, ego, route, lateral, longitudinal, 9.0, 80, braking=braking)
        short = forecast_ego_boxes(cfg, ego, route, lateral, longitudinal, 9.0, 40, braking=braking)
        for a, b in ((short.centres, long.centres[:40]), (short.yaws, long.yaws[:40]),
                     (short.extents, long.extents[:40])):
            assert np.array_equal(a, b)


def test_the_expert_forecasts_the_ego_once_per_hazard_check(make_route, make_vehicle, monkeypatch):
    from b2d_data.expert import expert as expert_module
    from b2d_data.expert.forecasting import forecast_ego_boxes

    cfg = ExpertConfig.for_builtin()
    route = make_route(100.0, cfg)
    ego = make_vehicle(1, 0.0, 0.3, yaw=2.0, speed=6.0, half=(2.45, 1.06, 0.75))
    driver = expert_module.Expert(None, [(wp, RoadOption.LANEFOLLOW) for wp in route.coarse_waypoints[:20:10]], cfg)
    calls = []

    def counted(*args, **kwargs):
        calls.append((args[-1], kwargs.get("braking", False)))
        return forecast_ego_boxes(*args, **kwargs)

    monkeypatch.setattr(expert_module, "forecast_ego_boxes", counted)

    def fresh(frames: int, braking: bool = False) -> BoxTrack:
        return forecast_ego_boxes(cfg, ego, route, driver.lateral, driver.longitudinal, 9.0, frames, braking=braking)

    def same(a: BoxTrack, b: BoxTrack) -> bool:
        return all(np.array_equal(x, y) for x, y in ((a.centres, b.centres), (a.yaws, b.yaws),
                                                     (a.extents, b.extents)))

    # outside a hazard check every request is forecast afresh
    assert same(driver._ego_boxes(ego, route, 9.0, 40), fresh(40))
    assert same(driver._ego_boxes(ego, route, 9.0, 40), fresh(40))
    assert len(calls) == 2
    calls.clear()
    driver._ego_tracks = {}  # as during _hazards
    assert same(driver._ego_boxes(ego, route, 9.0, 80), fresh(80))
    assert same(driver._ego_boxes(ego, route, 9.0, 40), fresh(40))  # the start of the 80-frame forecast
    assert same(driver._ego_boxes(ego, route, 9.0, 80, braking=True), fresh(80, braking=True))
    assert same(driver._ego_boxes(ego, route, 9.0, 80, braking=True), fresh(80, braking=True))
    assert same(driver._ego_boxes(ego, route, 7.0, 40), forecast_ego_boxes(cfg, ego, route, driver.lateral,
                                                                          driver.longitudinal, 7.0, 40))
    assert calls == [(80, False), (80, True), (40, False)]
    driver._ego_tracks = {}  # the next check: a longer horizon than the one forecast is forecast anew
    assert same(driver._ego_boxes(ego, route, 9.0, 40), fresh(40))
    assert same(driver._ego_boxes(ego, route, 9.0, 80), fresh(80))


def test_distance_prefilters_agree_with_the_norm(make_vehicle):
    # the expert skips the norm where one axis alone is over a metre beyond the radius; otherwise it is the norm
    from b2d_data.expert.expert import _beyond, _closer_than

    centre = np.array([3.0, -2.0, 0.5])
    assert _beyond((54.1, -2.0, 0.5), centre, 50.0) and not _beyond((53.9, -2.0, 0.5), centre, 50.0)
    assert _beyond(np.array([3.0, 49.5, 0.5]), centre, 50.0) and not _beyond((3.0, 48.0, 0.5), centre, 50.0)
    rng = np.random.default_rng(6)
    for x, y in rng.uniform(-60.0, 60.0, (400, 2)):
        car = make_vehicle(2, float(x), float(y))
        expected = float(np.linalg.norm(np.array([x, y, 0.0]) - centre)) < 50.0
        assert _closer_than(car, centre, 50.0) == expected
        assert _beyond((x, y, 0.0), centre, 50.0) <= (not expected)  # beyond only where the norm says far
