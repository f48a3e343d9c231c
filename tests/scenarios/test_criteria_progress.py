"""Route completion, route deviation, min-speed checkpoints, route timeout and agent blocked on synthetic ticks.

The route is a straight 100 m line along +x with a point every metre (x = 0 … 100), so completion percentages,
distances and checkpoints can be worked out by hand.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.scenarios.criteria import (
    ActorBlockedTest,
    InRouteTest,
    MinimumSpeedRouteTest,
    RouteCompletionTest,
    RouteTimeout,
)
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import ActorKind, ActorState, Snapshot

EGO = 1


@dataclass(frozen=True)
class _Point:
    """Stands in for a map waypoint: the criteria only read the route's arrays."""

    transform: Transform


def line_route(length: int = 100, speed_limit_kmh: float = 36.0) -> DenseRoute:
    xs = np.arange(length + 1, dtype=float)
    locations = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
    forward = np.tile([1.0, 0.0, 0.0], (len(xs), 1))
    points = tuple(_Point(Transform(Location(float(x), 0.0, 0.0))) for x in xs)
    commands = (RoadOption.LANEFOLLOW,) * len(xs)
    limits = np.full(len(xs), speed_limit_kmh)
    return DenseRoute(points, commands, locations, forward, xs.copy(), limits)  # type: ignore[arg-type]


def vehicle(actor_id: int, x: float, y: float = 0.0, speed: float = 0.0, role: str = "hero") -> ActorState:
    return ActorState(
        id=actor_id, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
        transform=Transform(Location(x, y, 0.0), Rotation()), velocity=Vector3D(speed, 0.0, 0.0),
        angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.44, 1.06, 0.75)), semantic_tags=(14,),
        role_name=role,
    )  # fmt: skip


def snapshot(frame: int, *actors: ActorState, timestamp: float | None = None) -> Snapshot:
    return Snapshot(frame=frame, timestamp=frame * 0.05 if timestamp is None else timestamp,
                    actors={a.id: a for a in actors}, traffic_lights={}, traffic_signs={}, collisions=(),
                    weather=ROUTE_DEFAULT)  # fmt: skip


# ---------------------------------------------------------------------------------------------- completion


def test_completion_is_the_furthest_passed_point():
    route, test = line_route(), RouteCompletionTest(line_route())
    # 1 m per tick (inside the 2-point window): at x = 80.5 point 80 is the furthest passed → 80 %.
    for frame, x in enumerate(np.arange(0.5, 81.0, 1.0), start=1):
        ego = vehicle(EGO, float(x), speed=20.0)
        test.update(snapshot(frame, ego), ego)
    assert test.index == 80 and test.actual_value == 80.0
    assert not test.target_reached and not test.stops_route
    assert route.total_length == 100.0


def test_completion_window_limits_jumps():
    test = RouteCompletionTest(line_route())
    ego = vehicle(EGO, 50.5)
    test.update(snapshot(1, ego), ego)
    # Teleported 50 m ahead: the 2-point window only lets the index move to 2.
    assert test.index == 2 and test.actual_value == 2.0


def test_completion_needs_more_than_99_percent_and_10_m():
    test = RouteCompletionTest(line_route())
    frame = 0
    for x in np.arange(0.5, 99.6, 1.0):  # last position 99.5: point 99 passed → 99 %, not > 99
        frame += 1
        ego = vehicle(EGO, float(x), speed=20.0)
        test.update(snapshot(frame, ego), ego)
    assert test.actual_value == 99.0 and not test.target_reached
    ego = vehicle(EGO, 100.2, speed=20.0)
    test.update(snapshot(frame + 1, ego), ego)
    # 100 % and 0.2 m from the last point: completed, but the route ends one tick later.
    assert test.target_reached and test.actual_value == 100.0 and test.completed_frame == frame + 1
    assert not test.stops_route
    test.update(snapshot(frame + 2, ego), ego)
    assert test.stops_route


def test_completion_rounds_to_two_decimals():
    # Points at 0, 1 and 3 m: point 1 is 33.333…% of the length.
    route = line_route(3)
    route = DenseRoute(route.waypoints[:3], route.commands[:3], route.locations[[0, 1, 3]],
                       route.forward_vectors[:3], np.array([0.0, 1.0, 3.0]), route.speed_limits[:3])
    test = RouteCompletionTest(route)
    ego = vehicle(EGO, 1.5)
    test.update(snapshot(1, ego), ego)
    assert test.actual_value == 33.33


# ---------------------------------------------------------------------------------------------- deviation


def test_thirty_metres_off_the_route_ends_it():
    test = InRouteTest(line_route())
    near = vehicle(EGO, 0.0, y=29.9)
    test.update(snapshot(1, near), near)
    assert not test.failed
    far = vehicle(EGO, 0.0, y=30.0)
    test.update(snapshot(2, far), far)
    assert test.failed and test.stops_route
    assert [e.message for e in test.events] == ["Agent deviated from the route at (x=0.0, y=30.0, z=0.0)"]
    assert test.events[0].key == lb.ROUTE_DEV


def test_driving_15_to_30_m_off_for_more_than_30_percent_ends_the_route():
    test = InRouteTest(line_route())
    # 20 m beside the route: each metre of progress counts as out-of-route distance. After x = 30 it is
    # 30 % of the 100 m route (not more); at x = 31 it is 31 % → failure.
    for frame, x in enumerate(range(0, 31), start=1):
        ego = vehicle(EGO, float(x), y=20.0)
        test.update(snapshot(frame, ego), ego)
    assert not test.failed and test.out_route_distance == 30.0
    ego = vehicle(EGO, 31.0, y=20.0)
    test.update(snapshot(40, ego), ego)
    assert test.failed and test.out_route_distance == 31.0


def test_driving_within_15_m_never_accumulates():
    test = InRouteTest(line_route())
    for frame, x in enumerate(range(0, 100), start=1):
        ego = vehicle(EGO, float(x), y=14.0)
        test.update(snapshot(frame, ego), ego)
    assert not test.failed and test.out_route_distance == 0.0


# ---------------------------------------------------------------------------------------------- min speed


def drive_line(test, speed: float, traffic: list[tuple[float, str]], end: float = 100.5, step: float = 0.5) -> int:
    """Drive the ego along the line at ``step`` m per tick with fixed speeds; returns the last frame."""
    frame = 0
    for x in np.arange(0.0, end + 1e-9, step):
        frame += 1
        others = [vehicle(10 + i, 0.0, y=50.0, speed=v, role=role) for i, (v, role) in enumerate(traffic)]
        ego = vehicle(EGO, float(x), speed=speed)
        test.update(snapshot(frame, ego, *others), ego)
    return frame


def test_min_speed_reports_every_checkpoint_and_a_final_one():
    route = line_route()
    test = MinimumSpeedRouteTest(route, checkpoints=20)
    # 20 checkpoints over 100 m → one every 5 m, closed when the passed point is more than 5 m past the last
    # checkpoint: at points 6, 12, …, 96 (16 events); the ego ends at x = 100.5 (100 % > 95 %) → a 17th.
    frame = drive_line(test, speed=10.0, traffic=[(5.0, "background")])
    test.terminate(snapshot(frame, vehicle(EGO, 100.5)), vehicle(EGO, 100.5))
    assert len(test.events) == 17
    assert {e.message for e in test.events} == {"Average speed is 200.0% of the surrounding traffic's one"}
    assert all(e.key == lb.MIN_SPEED_INFRACTIONS and e.percentage == 200.0 for e in test.events)


def test_min_speed_averages_only_background_vehicles():
    test = MinimumSpeedRouteTest(line_route(), checkpoints=20)
    # Ego 3 m/s; background at 4 and 8 (mean 6) → 50 %; a scenario vehicle standing still does not count.
    drive_line(test, speed=3.0, traffic=[(4.0, "background"), (8.0, "background"), (0.0, "scenario")], end=7.0)
    assert [e.message for e in test.events] == ["Average speed is 50.0% of the surrounding traffic's one"]


def test_min_speed_without_traffic_is_100():
    test = MinimumSpeedRouteTest(line_route(), checkpoints=20)
    drive_line(test, speed=3.0, traffic=[], end=7.0)
    assert [e.message for e in test.events] == ["Average speed is 100% of the surrounding traffic's one"]
    # No final event when the route ended before 95 %.
    test.terminate(snapshot(99, vehicle(EGO, 7.0)), vehicle(EGO, 7.0))
    assert len(test.events) == 1


# ---------------------------------------------------------------------------------------------- route timeout


def test_route_timeout_starts_at_300_s_and_grows_with_progress():
    # 36 km/h limit → 10 % of it is 1 m/s → every metre of progress adds 1 s.
    timeout = RouteTimeout(line_route(speed_limit_kmh=36.0))
    ego = vehicle(EGO, 0.5)
    timeout.update(snapshot(1, ego), ego)  # the clock starts at the first update (t = 0.05)
    timeout.update(snapshot(6001, ego), ego)  # elapsed 300.0 s: not more than 300
    assert not timeout.timed_out and timeout.timeout_value == 300.0
    timeout.update(snapshot(6003, ego), ego)
    assert timeout.timed_out

    timeout = RouteTimeout(line_route(speed_limit_kmh=36.0))
    for frame, x in enumerate(np.arange(0.5, 10.6, 1.0), start=1):  # passes points 0 … 10
        ego = vehicle(EGO, float(x))
        timeout.update(snapshot(frame, ego), ego)
    assert timeout.index == 10 and timeout.timeout_value == pytest.approx(310.0)


def test_route_timeout_uses_the_lane_speed_limit():
    # 72 km/h → 2 m/s allowed average → 0.5 s per metre.
    timeout = RouteTimeout(line_route(speed_limit_kmh=72.0))
    for frame, x in enumerate(np.arange(0.5, 20.6, 1.0), start=1):
        ego = vehicle(EGO, float(x))
        timeout.update(snapshot(frame, ego), ego)
    assert timeout.timeout_value == pytest.approx(310.0)


# ---------------------------------------------------------------------------------------------- blocked


def stand(test: ActorBlockedTest, start_frame: int, end_frame: int, speed: float = 0.0) -> None:
    for frame in range(start_frame, end_frame + 1):
        ego = vehicle(EGO, 5.0, speed=speed)
        test.update(snapshot(frame, ego, timestamp=frame / 20), ego)


def test_sixty_seconds_below_0_1_m_s_is_blocked():
    test = ActorBlockedTest()
    stand(test, 1, 1, speed=1.0)  # moving at t = 0.05: the clock starts there
    stand(test, 2, 1200)  # standing until t = 60.0: 59.95 s since the last valid state
    assert not test.failed
    stand(test, 1201, 1203)  # t = 60.15 at the latest → more than 60 s (the exact 60.0 s tick is float noise)
    assert test.failed and test.stops_route
    assert [e.message for e in test.events] == ["Agent got blocked at (x=5.0, y=0.0, z=0.0)"]


def test_creeping_at_0_1_m_s_is_not_blocked():
    test = ActorBlockedTest()
    stand(test, 1, 2000, speed=0.1)
    assert not test.failed


def test_an_ego_that_never_moves_is_blocked_after_60_s():
    # The clock starts at the first update (t = 0.05), moving or not.
    test = ActorBlockedTest()
    stand(test, 1, 1200)
    assert not test.failed
    stand(test, 1201, 1203)
    assert test.failed


def test_scenarios_can_pause_the_blocked_test():
    test = ActorBlockedTest()
    stand(test, 1, 1, speed=1.0)
    test.switch(False)
    stand(test, 2, 2400)  # two minutes standing while paused
    assert not test.failed
    test.switch(True)  # re-activation restarts the clock at t = 120.05
    stand(test, 2401, 3600)  # t = 180.0: 59.95 s
    assert not test.failed
    stand(test, 3601, 3603)
    assert test.failed and len(test.events) == 1
