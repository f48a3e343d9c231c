"""Red lights and stop signs: synthetic ego trajectories on CARLA's Town01 lanes.

The approach lane is Town01 road 0, lane -1 (heading −x) from spawn point 0; a junction starts about 21 m on.
Lights and the stop sign are built by hand on that lane, so the expected crossings follow from the geometry.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.maps import load_opendrive
from b2d_data.scenarios.criteria import RunningRedLightTest, RunningStopTest, stop_line_waypoints
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import Route
from b2d_data.sim.api import (
    ActorKind,
    ActorState,
    Snapshot,
    TrafficLightInfo,
    TrafficLightState,
    TrafficSignInfo,
)

EGO = 1


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town01.xodr")


@pytest.fixture(scope="module")
def approach(town01):
    """The dense route across the junction and the last approach-lane waypoint before it."""
    start = town01.get_waypoint(town01.get_spawn_points()[0].location)
    route = Route(id="1", town="Town01", waypoints=(start.transform.location, start.next(60.0)[0].transform.location))
    dense = DenseRoute.from_route(town01, route)
    first_junction = next(i for i, wp in enumerate(dense.waypoints) if wp.is_junction)
    return dense, first_junction


def ego_state(x: float, y: float, z: float, yaw: float, speed: float) -> ActorState:
    rad = math.radians(yaw)
    return ActorState(
        id=EGO, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
        transform=Transform(Location(x, y, z), Rotation(yaw=yaw)),
        velocity=Vector3D(speed * math.cos(rad), speed * math.sin(rad), 0.0), angular_velocity=Vector3D(),
        acceleration=Vector3D(), bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.44, 1.06, 0.75)),
        semantic_tags=(14,), role_name="hero",
    )  # fmt: skip


def along(dense: DenseRoute, start: float, end: float, step: float = 0.5):
    """(x, y, z, yaw) every ``step`` m of route length between ``start`` and ``end`` metres."""
    s = dense.cumulative_length
    for d in np.arange(start, end + 1e-9, step):
        i = min(int(np.searchsorted(s, d, side="right")) - 1, len(s) - 2)
        t = (d - s[i]) / (s[i + 1] - s[i])
        p = dense.locations[i] + t * (dense.locations[i + 1] - dense.locations[i])
        yaw = math.degrees(math.atan2(*(dense.locations[i + 1] - dense.locations[i])[[1, 0]]))
        yield float(p[0]), float(p[1]), float(p[2]), yaw


def run(test, poses, lights=None, signs=None, speeds=None):
    for frame, (x, y, z, yaw) in enumerate(poses, start=1):
        speed = 8.0 if speeds is None else speeds(frame, x, y)
        ego = ego_state(x, y, z, yaw, speed)
        snap = Snapshot(frame=frame, timestamp=frame * 0.05, actors={EGO: ego}, traffic_lights=lights or {},
                        traffic_signs=signs or {}, collisions=(), weather=ROUTE_DEFAULT)
        test.update(snap, ego)
    return test


# ---------------------------------------------------------------------------------------------- red lights


def make_light(stop_wp, state: TrafficLightState) -> TrafficLightInfo:
    # The pole 4 m to the right of the stop waypoint; its trigger volume centred on the pole (within 15 m).
    right = stop_wp.transform.get_right_vector()
    pole = stop_wp.location + right * 4.0
    box = BoundingBox(Location(), Location(1.5, 1.0, 1.0))
    return TrafficLightInfo(
        id=900, transform=Transform(pole, Rotation(yaw=stop_wp.transform.rotation.yaw + 90)), state=state,
        trigger_volume=box, stop_waypoints=(stop_wp,), affected_lane_waypoints=(stop_wp,), group_id=1,
        opendrive_id="900", level_bbox=box, level_bbox_transform=Transform(pole),
    )  # fmt: skip


def test_stop_line_is_the_last_lane_point_before_the_junction(approach):
    dense, first_junction = approach
    stop_wp = dense.waypoints[first_junction - 3]  # like CARLA's stop waypoint, 3 m before the junction
    (line_wp,) = stop_line_waypoints(make_light(stop_wp, TrafficLightState.RED))
    assert not line_wp.is_junction and line_wp.next(0.5)[0].is_junction
    assert (line_wp.road_id, line_wp.lane_id) == (stop_wp.road_id, stop_wp.lane_id)


def test_stop_lines_of_the_builtin_worlds_lights_sit_at_their_junctions(town01):
    from b2d_data.sim.builtin.world import BuiltinSimulator

    lights = BuiltinSimulator(town01, seed=0).snapshot().traffic_lights
    assert lights
    for light in lights.values():
        for wp in stop_line_waypoints(light):
            assert not wp.is_junction and wp.next(0.5)[0].is_junction


def test_crossing_the_stop_line_on_red_is_one_infraction(approach, town01):
    dense, first_junction = approach
    light = make_light(dense.waypoints[first_junction - 3], TrafficLightState.RED)
    test = run(RunningRedLightTest(town01), along(dense, 0.0, dense.total_length), lights={light.id: light})
    assert [(e.key, e.message) for e in test.events] == [
        (lb.RED_LIGHT, lb.red_light_message(900, light.transform.location))
    ]
    assert test.events[0].message.startswith("Agent ran a red light 900 at (x=")


def test_green_or_yellow_lights_are_no_infraction(approach, town01):
    dense, first_junction = approach
    for state in (TrafficLightState.GREEN, TrafficLightState.YELLOW):
        light = make_light(dense.waypoints[first_junction - 3], state)
        test = run(RunningRedLightTest(town01), along(dense, 0.0, dense.total_length), lights={light.id: light})
        assert test.events == []


def test_stopping_before_the_line_is_no_infraction(approach, town01):
    dense, first_junction = approach
    light = make_light(dense.waypoints[first_junction - 3], TrafficLightState.RED)
    line_s = float(dense.cumulative_length[first_junction - 1])
    # The ego's centre stops 1 m past the last lane point (its tail is then well before the line).
    test = run(RunningRedLightTest(town01), along(dense, 0.0, line_s + 1.0), lights={light.id: light})
    assert test.events == []


def test_a_red_light_of_another_lane_is_no_infraction(approach, town01):
    dense, first_junction = approach
    stop_wp = dense.waypoints[first_junction - 3]
    other = stop_wp.get_left_lane()  # the opposite direction's lane
    assert other is not None and other.lane_id != stop_wp.lane_id
    light = make_light(other, TrafficLightState.RED)
    test = run(RunningRedLightTest(town01), along(dense, 0.0, dense.total_length), lights={light.id: light})
    assert test.events == []


# ---------------------------------------------------------------------------------------------- stop signs


def make_stop(wp) -> TrafficSignInfo:
    # A CARLA stop trigger: a cube of half size 0.45 × lane width centred on the lane.
    half = 0.45 * wp.lane_width
    box = BoundingBox(Location(), Location(half, half, half))
    return TrafficSignInfo(id=901, type_id="traffic.stop", transform=Transform(wp.location, wp.transform.rotation),
                           trigger_volume=box, level_bbox=box, level_bbox_transform=Transform(wp.location))


def test_driving_through_a_stop_is_one_infraction(approach, town01):
    dense, first_junction = approach
    sign = make_stop(dense.waypoints[first_junction - 8])
    test = run(RunningStopTest(town01), along(dense, 0.0, dense.total_length), signs={sign.id: sign})
    assert [(e.key, e.message) for e in test.events] == [
        (lb.STOP_INFRACTION, lb.stop_message(901, sign.transform.location))
    ]


def test_stopping_at_the_stop_is_no_infraction(approach, town01):
    dense, first_junction = approach
    sign_index = first_junction - 8
    sign = make_stop(dense.waypoints[sign_index])
    stop_at = float(dense.cumulative_length[sign_index]) - 1.5
    poses = list(along(dense, 0.0, dense.total_length))
    stop_frame = 1 + int(round(stop_at / 0.5))

    def speeds(frame, x, y):
        return 0.0 if frame == stop_frame else 8.0

    test = run(RunningStopTest(town01), poses, signs={sign.id: sign}, speeds=speeds)
    assert test.events == []


def test_stopping_before_the_stop_zone_does_not_count(approach, town01):
    dense, first_junction = approach
    sign_index = first_junction - 8
    sign = make_stop(dense.waypoints[sign_index])
    stop_frame = 1 + int(round((float(dense.cumulative_length[sign_index]) - 7.0) / 0.5))  # 7 m before: outside
    test = run(RunningStopTest(town01), along(dense, 0.0, dense.total_length), signs={sign.id: sign},
               speeds=lambda frame, x, y: 0.0 if frame == stop_frame else 8.0)
    assert len(test.events) == 1


def test_other_signs_are_not_stops(approach, town01):
    dense, first_junction = approach
    sign = make_stop(dense.waypoints[first_junction - 8])
    yield_sign = TrafficSignInfo(901, "traffic.yield", sign.transform, sign.trigger_volume, sign.level_bbox,
                                 sign.level_bbox_transform)
    test = run(RunningStopTest(town01), along(dense, 0.0, dense.total_length), signs={901: yield_sign})
    assert test.events == []
