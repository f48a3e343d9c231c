"""TCP-style route planners: sparse route selection and point popping, worked out by hand."""

from __future__ import annotations

from b2d_data.collection.route_planners import CommandPlanners, RoutePoint, RoutePointPlanner, downsample_route
from b2d_data.format.road_option import RoadOption

LF, LEFT = RoadOption.LANEFOLLOW, RoadOption.LEFT


def test_downsample_keeps_changes_and_every_50_m():
    # 121 points 1 m apart on the x axis; the command is LEFT on points 60..69.
    points = [(float(i), 0.0) for i in range(121)]
    commands = [LEFT if 60 <= i < 70 else LF for i in range(121)]
    keep = downsample_route(points, commands)
    # 0 (start), 50 (50 m travelled), 59 (last LANEFOLLOW before the change), 60 (change), 69 (last LEFT),
    # 70 (change back), 120 (50 m after 70, also the end).
    assert keep == [0, 50, 59, 60, 69, 70, 120]


def test_planner_pops_points_within_min_distance():
    route = [RoutePoint(0.0, 0.0, LF), RoutePoint(10.0, 0.0, LF), RoutePoint(20.0, 0.0, LEFT), RoutePoint(30.0, 0.0, LF)]
    planner = RoutePointPlanner(route, min_distance=4.0, max_distance=50.0)
    # At x = 1 no later point is within 4 m: the next point is the one at 10 m.
    assert planner.run_step(1.0, 0.0).x == 10.0
    # At x = 7, the 10 m point is 3 m away (≤ 4): it is popped together with the start; next is 20 m.
    assert planner.run_step(7.0, 0.0) == RoutePoint(20.0, 0.0, LEFT)
    # Never fewer than two points remain: at the end the last point keeps being returned.
    assert planner.run_step(30.0, 0.0).x == 30.0
    assert planner.run_step(30.0, 0.0).x == 30.0


def test_max_distance_limits_the_lookahead():
    # Points every 10 m; the ego stands at x = 40. With a 25 m look-ahead the scan stops before reaching 40 m.
    route = [RoutePoint(10.0 * i, 0.0, LF) for i in range(6)]
    far = RoutePointPlanner(route, min_distance=7.5, max_distance=25.0)
    assert far.run_step(40.0, 0.0).x == 10.0
    near = RoutePointPlanner(route, min_distance=4.0, max_distance=50.0)
    assert near.run_step(40.0, 0.0).x == 50.0


def test_command_planners_from_dense_route():
    points = [(float(i), 0.0) for i in range(101)]
    commands = [LF] * 101
    planners = CommandPlanners.from_dense_route(points, commands)
    out = planners.run_step(0.0, 0.0)
    # Sparse route = points 0, 50, 100; nothing reached yet, so every planner heads for x = 50.
    assert (out.near.x, out.far.x, out.target.x) == (50.0, 50.0, 50.0)
