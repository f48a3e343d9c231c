"""OutsideRouteLanesTest on Town01 road 1: a straight two-way road with 4 m lanes (ours heads −x at y ≈ −2,
the opposite one at y ≈ +2), shoulders and sidewalks outside."""

from __future__ import annotations

import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.maps import load_opendrive
from b2d_data.scenarios.criteria import SWITCH_WRONG_DIRECTION, OutsideRouteLanesTest, RouteCriteria
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import Route
from b2d_data.sim.api import ActorKind, ActorState, Snapshot

EGO = 1


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town01.xodr")


@pytest.fixture(scope="module")
def road1(town01):
    start = town01.get_waypoint(town01.get_spawn_points()[2].location)
    assert (start.road_id, start.lane_id, start.lane_width) == (1, -1, 4.0)
    route = Route(id="2", town="Town01", waypoints=(start.transform.location, start.next(50.0)[0].transform.location))
    return DenseRoute.from_route(town01, route)


def drive(test: OutsideRouteLanesTest, route: DenseRoute, lateral, end: float = 40.5) -> None:
    """Drive along the route heading −x, 0.5 m per tick, ``lateral(d)`` metres to the left of the lane centre."""
    x0, y0, z0 = route.locations[0]
    frame = 0
    d = 0.0
    while d <= end + 1e-9:
        frame += 1
        # Left of a −x heading is +y in CARLA's frame.
        ego = ActorState(
            id=EGO, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
            transform=Transform(Location(x0 - d, y0 + lateral(d), z0), Rotation(yaw=180.0)),
            velocity=Vector3D(-8.0, 0.0, 0.0), angular_velocity=Vector3D(), acceleration=Vector3D(),
            bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.44, 1.06, 0.75)), semantic_tags=(14,),
            role_name="hero",
        )  # fmt: skip
        snap = Snapshot(frame=frame, timestamp=frame * 0.05, actors={EGO: ego}, traffic_lights={},
                        traffic_signs={}, collisions=(), weather=ROUTE_DEFAULT)
        test.update(snap, ego)
        d += 0.5


def in_window(lo: float, hi: float, offset: float):
    return lambda d: offset if lo <= d < hi else 0.0


def expected_message(route: DenseRoute) -> str:
    """Route points 20 … 29 passed while out (hops 19→20 … 28→29) out of points 0 … 40: ≈ 10 m, ≈ 25 %.

    Road 1 is very slightly curved, so a 1 m hop is 1.00002 m: the exact figures come from the route itself.
    """
    wrong = float(route.cumulative_length[29] - route.cumulative_length[19])
    total = float(route.cumulative_length[40])
    assert wrong == pytest.approx(10.0, abs=0.01) and wrong / total * 100 == pytest.approx(25.0, abs=0.01)
    return lb.outside_lanes_message(wrong, wrong / total * 100)


def test_keeping_the_lane_is_no_event(town01, road1):
    test = OutsideRouteLanesTest(town01, road1)
    drive(test, road1, lambda d: 0.0)
    assert test.events == [] and not test.failed
    # The ego ends at 40.5 m: route points 0 … 40 passed, 40 m of completed route.
    assert test.total_distance == pytest.approx(float(road1.cumulative_length[40]), abs=1e-9)
    assert test.total_distance == pytest.approx(40.0, abs=0.01)


def test_ten_metres_in_the_opposite_lane(town01, road1):
    test = OutsideRouteLanesTest(town01, road1)
    # In the opposite lane (4 m left) from 20 m to 30 m: route points 20 … 29 are passed while there (10 hops of
    # 1 m) out of 40 → 10 m, 25 %.
    drive(test, road1, in_window(20.0, 30.0, 4.0))
    assert [(e.key, e.message) for e in test.events] == [(lb.OUTSIDE_ROUTE_LANES, expected_message(road1))]
    assert test.events[0].percentage == pytest.approx(25.0, abs=0.01)
    assert not test.wrong_lane_active  # coming back toggled it off


def test_scenarios_can_switch_the_wrong_direction_check_off(town01, road1):
    test = OutsideRouteLanesTest(town01, road1)
    test.switch_wrong_direction(False)
    drive(test, road1, in_window(20.0, 30.0, 4.0))
    assert test.events == []


def test_ten_metres_off_the_road(town01, road1):
    test = OutsideRouteLanesTest(town01, road1)
    # 3.5 m right of the lane centre: more than half the lane width (2 m) + 0.5 m from any driving lane.
    drive(test, road1, in_window(20.0, 30.0, -3.5))
    assert [e.message for e in test.events] == [expected_message(road1)]


def test_half_lane_width_plus_half_a_metre_is_still_inside(town01, road1):
    test = OutsideRouteLanesTest(town01, road1)
    drive(test, road1, in_window(20.0, 30.0, -2.4))
    assert test.events == []


def test_route_criteria_together(town01, road1):
    criteria = RouteCriteria(town01, road1, EGO)
    criteria.switch(SWITCH_WRONG_DIRECTION, False)  # a scenario allows the opposite lane
    end = road1.total_length + 0.5
    drive(criteria, road1, in_window(20.0, 30.0, 4.0), end=end)
    # The last tick detected completion; the route stops on the next one.
    assert criteria.route_completion.target_reached and criteria.stop_reason is None
    last = ActorState(
        id=EGO, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
        transform=Transform(Location(road1.locations[-1][0] - 1.0, road1.locations[-1][1], 0.0), Rotation(yaw=180.0)),
        velocity=Vector3D(-8.0, 0.0, 0.0), angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.44, 1.06, 0.75)), semantic_tags=(14,),
        role_name="hero",
    )  # fmt: skip
    snap = Snapshot(frame=999, timestamp=49.95, actors={EGO: last}, traffic_lights={}, traffic_signs={},
                    collisions=(), weather=ROUTE_DEFAULT)
    criteria.update(snap, last)
    assert criteria.stop_reason == "completed"
    criteria.terminate(snap, last)
    result = criteria.result()
    # No background traffic: every min-speed checkpoint says 100 %. 20 checkpoints over ~50 m close at route
    # points 3, 6, …, 48 (16) and the end adds one (100 % > 95 %): 17 messages, nothing else.
    assert result.target_reached and result.score_route == 100.0 and not result.route_timeout
    assert [e.key for e in result.events] == [lb.MIN_SPEED_INFRACTIONS] * 17
    assert {e.message for e in result.events} == {"Average speed is 100% of the surrounding traffic's one"}
    with pytest.raises(ValueError, match="unknown criteria switch"):
        criteria.switch("AC_SomethingElse", True)
