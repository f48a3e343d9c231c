"""The gap acceptance across a flow that never yields (``expert/crossing_flow.py``, ``Expert._crossing_flow``).

The scene, in every test: the ego's route runs along +x on y = 0 (10 points/m); a flow lane crosses it at right
angles along x = 12.1, its cars driving toward +y; cars and ego are the fixtures' 4.8 x 2 m box (half 2.4 x 1.0).
"""

from __future__ import annotations

from functools import partial
from types import SimpleNamespace

import numpy as np
import pytest

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.crossing_flow import box_clearance, crossing_cars, densify, lengthened, line_distance
from b2d_data.expert.expert import Expert
from b2d_data.expert.forecasting import BoxTrack
from b2d_data.expert.lateral_controller import LateralPIDController
from b2d_data.expert.longitudinal_controller import make_longitudinal_controller

CFG = ExpertConfig.for_builtin()
LANE_X = 12.1
#: the flow lane, 60 m either side of the route
LANE = np.stack([np.full(121, LANE_X), np.linspace(-60.0, 60.0, 121)], axis=1)


def _ahead(route, length: float = 25.0):
    """Route points and headings from the index, one per ROUTE_STEP (0.2 m)."""
    end = route.index + CFG.points(length)
    return route.points[route.index : end : 2], route.headings[route.index : end : 2]


def _path_from(car) -> np.ndarray:
    """A flow car's path ahead: the lane from the car on."""
    return LANE[LANE[:, 1] >= car.location.y]


def test_box_clearance_is_the_distance_from_the_box_edge():
    # a 4.8 x 2 box at the origin, heading east: a point 3 m ahead of its front, one 0.5 m beside its side, one inside
    points = np.array([[5.4, 0.0], [0.0, 1.5], [1.0, 0.5]])
    got = [box_clearance(np.zeros((1, 2)), np.zeros(1), (2.4, 1.0), p[None, :])[0] for p in points]
    assert got == pytest.approx([3.0, 0.5, 0.0])
    # turned 90 degrees the box reaches 2.4 m sideways: the first point is now 5.4 - 1.0 = 4.4 m off its side
    assert box_clearance(np.zeros((1, 2)), np.array([np.pi / 2]), (2.4, 1.0), points[:1])[0] == pytest.approx(4.4)


def test_the_line_is_where_the_box_comes_within_a_car_width_and_the_margin(make_route, make_vehicle):
    route = make_route(60.0, CFG)
    ego = make_vehicle(0, 0.0, 0.0)
    points, headings = _ahead(route)
    # clearance 1.0 (the car's half width) + 1.0 (flow_hold_margin) = 2.0 from the path: the box's front (centre
    # + 2.4) must stay short of 12.1 - 2.0 = 10.1, so the centre may drive 7.7 m; the first 0.2 m point past is 7.8
    assert line_distance(points, headings, ego, densify(LANE), 2.0) == pytest.approx(7.8)
    # a lane beside the route (3.5 m off, parallel) is 3.5 - 1.0 = 2.5 m from the box: not within 2.0
    beside = np.stack([np.linspace(-10.0, 60.0, 71), np.full(71, -3.5)], axis=1)
    assert line_distance(points, headings, ego, densify(beside), 2.0) is None
    # a crossing 30 m on lies beyond the 25 m looked at
    assert line_distance(points, headings, ego, densify(LANE + [20.0, 0.0]), 2.0) is None


def test_crossing_cars_are_those_whose_path_ahead_crosses_the_route(make_route, make_vehicle):
    route = make_route(60.0, CFG)
    ego = make_vehicle(0, 0.0, 0.0)
    points, headings = _ahead(route)
    coming = make_vehicle(7, LANE_X, -30.0, yaw=90.0, speed=10.0, role="scenario")
    gone = make_vehicle(8, LANE_X, 10.0, yaw=90.0, speed=10.0, role="scenario")  # already across
    paths = {7: _path_from(coming), 8: _path_from(gone)}
    # the passed car's path starts 10 m off the route: its nearest point is 10 - 1.0 = 9 m from the box
    assert crossing_cars(points, headings, ego, [coming, gone], paths, CFG.flow_hold_margin) == {7: pytest.approx(7.8)}


def test_lengthened_adds_seconds_of_speed_at_both_ends(make_vehicle):
    car = make_vehicle(7, LANE_X, -30.0, yaw=90.0, speed=10.0)
    track = BoxTrack(7, np.zeros((3, 3)), np.zeros(3), np.ones((3, 3)))
    # 0.2 s at 10 m/s: 2 m longer at each end, width and height the real ones
    assert np.allclose(lengthened(track, car, 0.2).extents, [[4.4, 1.0, 0.75]] * 3)


def _decide(route, ego, cars, target: float = 10.0):
    """``Expert._crossing_flow`` on a stand-in expert (its config, controllers and ego forecasts only)."""
    me = SimpleNamespace(config=CFG, lateral=LateralPIDController(CFG), longitudinal=make_longitudinal_controller(CFG),
                         _ego_tracks=None)
    me._ego_boxes = partial(Expert._ego_boxes, me)
    paths = {c.id: _path_from(c) for c in cars}
    points, headings = _ahead(route, 50.0)
    lines = crossing_cars(points, headings, ego, cars, paths, CFG.flow_hold_margin)
    return Expert._crossing_flow(me, ego, route, [c for c in cars if c.id in lines], lines, target, paths)


def test_a_standing_ego_waits_at_the_line_for_a_car_it_cannot_beat(make_route, make_vehicle):
    route = make_route(100.0, CFG)
    ego = make_vehicle(0, 0.0, 0.0)
    # the car reaches the route (y = 0) in 2.0 s and covers |y| < 1.0 + 2.4 from 1.66 to 2.34 s; the ego's box is
    # on the lane (centre 12.1 - 1.0 - 2.4 = 8.7 to 15.5 m on) from about 1.6 s (PDM-Lite's Lincoln: 12.5 m after
    # 2 s of full throttle from a standstill) to past 2.34 s: going would meet it
    near = make_vehicle(7, LANE_X, -20.0, yaw=90.0, speed=10.0, role="scenario")
    got = _decide(route, ego, [near])
    assert got.blocking == (7,) and not got.committed and got.line == pytest.approx(7.8)
    # a car 60 m off is 20 m short of the route after the 4 s looked at: go
    far = make_vehicle(8, LANE_X, -60.0, yaw=90.0, speed=10.0, role="scenario")
    got = _decide(route, ego, [far])
    assert got.blocking == () and not got.committed


def test_an_ego_that_cannot_stop_short_of_the_lane_is_committed(make_route, make_vehicle):
    route = make_route(100.0, CFG)
    route.index = 80
    # centre at 8 m at 8 m/s: a full brake stands it within 1.6-3.2 m (test_geometry), its front at 12.0-13.6 m,
    # inside the car's band 11.1-13.1: committed, and the line is already behind it (0)
    ego = make_vehicle(0, 8.0, 0.0, speed=8.0)
    far = make_vehicle(8, LANE_X, -60.0, yaw=90.0, speed=10.0, role="scenario")
    got = _decide(route, ego, [far])
    assert got.committed and got.line == 0.0 and got.blocking == ()


def test_a_committed_ego_drives_on_even_before_a_car(make_route, make_vehicle):
    route = make_route(100.0, CFG)
    route.index = 80
    ego = make_vehicle(0, 8.0, 0.0, speed=8.0)  # committed, as above
    # a car 10 m short of the route at 10 m/s is within 1.0 + 2.4 of it from 0.66 s on, while the ego (front at
    # 10.4 m, 8 m/s) is on its band 11.1-13.1 (centre 8.7-15.5) from ~0.1 s to ~0.9 s: the forecasts meet, but
    # standing there instead the ego would be struck by this car or the next, so it keeps going (nothing to brake for)
    near = make_vehicle(7, LANE_X, -10.0, yaw=90.0, speed=10.0, role="scenario")
    got = _decide(route, ego, [near])
    assert got.committed and got.blocking == ()


def test_only_the_unprotected_left_turns_get_the_crossing_gap_acceptance():
    from b2d_data.expert.crossing_flow import crossing_flow_paths
    from b2d_data.sim.api import ScenarioHint

    left = ScenarioHint("SignalizedJunctionLeftTurn", 0, 0, "right", paths={7: LANE})
    bikes = ScenarioHint("CrossingBicycleFlow", 0, 0, "right", paths={8: LANE})
    # seed 131: the rule cost CrossingBicycleFlow and EnterActorFlow a route each, so their flows keep the older
    # checks; the left turn's car 7 gets it, and nothing does with the rule off (PDM-Lite's own config)
    assert list(crossing_flow_paths(CFG, [left, bikes])) == [7]
    assert crossing_flow_paths(ExpertConfig(), [left, bikes]) == {}
