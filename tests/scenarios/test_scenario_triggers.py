"""Trigger and end conditions of the scenario framework, on hand-made actor states (values worked out by hand)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.scenarios.triggers import (
    DistanceTrigger,
    DriveDistance,
    Timer,
    TimeToArrivalTrigger,
    WaitEndIntersection,
    horizontal_distance,
    is_in_front,
)
from b2d_data.sim.api import ActorKind, ActorState, Snapshot


def actor(x: float, y: float, yaw: float = 0.0, vx: float = 0.0, vy: float = 0.0, actor_id: int = 1) -> ActorState:
    """A car at (x, y) heading ``yaw`` degrees with a world-frame velocity."""
    return ActorState(
        id=actor_id, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
        transform=Transform(Location(x, y, 0.0), Rotation(yaw=yaw)), velocity=Vector3D(vx, vy, 0.0),
        angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0.0, 0.0, 0.75), Location(2.45, 1.06, 0.75)), semantic_tags=(14,),
    )  # fmt: skip


def snapshot_at(t: float) -> Snapshot:
    return Snapshot(frame=round(t / 0.05), timestamp=t, actors={}, traffic_lights={}, traffic_signs={},
                    collisions=(), weather=ROUTE_DEFAULT)  # fmt: skip


def test_horizontal_distance_ignores_height():
    assert horizontal_distance(Location(0, 0, 0), Location(3, 4, 100)) == pytest.approx(5.0)


def test_time_to_arrival_trigger_fires_on_time_or_distance():
    # conflict point 12 m ahead; TTA (2.2 s, 6 m)
    trigger = TimeToArrivalTrigger(Location(12.0, 0.0, 0.0), time=2.2, distance=6.0)
    assert not trigger.check(actor(0, 0, vx=5.0))  # 12 / 5 = 2.4 s
    assert trigger.check(actor(0, 0, vx=6.0))  # 12 / 6 = 2.0 s
    assert trigger.check(actor(0, 0))  # once fired it stays fired
    standing = TimeToArrivalTrigger(Location(12.0, 0.0, 0.0), time=2.2, distance=6.0)
    assert not standing.check(actor(5.5, 0))  # at rest (infinite time) and 6.5 m away
    assert standing.check(actor(6.5, 0))  # at rest but 5.5 m away


def test_time_to_arrival_trigger_at_rest_far_away_waits():
    trigger = TimeToArrivalTrigger(Location(20.0, 0.0, 0.0), time=3.5, distance=12.0)
    assert not trigger.check(actor(0, 0))  # 20 m, speed 0
    assert not trigger.check(actor(7.0, 0, vx=3.0))  # 13 m / 3 = 4.33 s
    assert trigger.check(actor(8.5, 0, vx=3.0))  # 11.5 m < 12 m


def test_distance_trigger_keeps_firing():
    trigger = DistanceTrigger(50.0)
    assert not trigger.check(actor(0, 0), Location(50.0, 0.0, 0.0))
    assert trigger.check(actor(0.5, 0), Location(50.0, 0.0, 0.0))
    assert trigger.check(actor(-100, 0), Location(50.0, 0.0, 0.0))


def test_drive_distance_accumulates_motion():
    drive = DriveDistance(10.0)
    assert not drive.check(actor(0, 0))
    assert not drive.check(actor(3, 4))  # 5 m
    assert drive.travelled == pytest.approx(5.0)
    assert drive.check(actor(6, 8))  # 10 m
    assert not DriveDistance(1.0).check(None)


def test_timer_counts_game_time_from_its_first_check():
    timer = Timer(1.0)
    assert not timer.check(snapshot_at(10.0))
    assert not timer.check(snapshot_at(10.95))
    assert timer.check(snapshot_at(11.0))


def test_is_in_front_uses_the_reference_heading():
    reference = actor(0, 0, yaw=0.0)
    assert is_in_front(actor(1, 0), reference)
    assert not is_in_front(actor(-1, 0), reference)
    # heading south (yaw 90 in CARLA's frame): "ahead" is +y
    south = actor(0, 0, yaw=90.0)
    assert is_in_front(actor(0, 1), south)
    assert not is_in_front(actor(0, -1), south)
    assert is_in_front(Transform(Location(3, 0, 0)), Transform(Location(0, 0, 0)))


@dataclass
class _Wp:
    is_junction: bool
    junction_id: int = -1


class _Town:
    """get_waypoint answers by x: inside junction 7 for 10 <= x < 20."""

    def get_waypoint(self, location):
        return _Wp(True, 7) if 10.0 <= location.x < 20.0 else _Wp(False)


def test_wait_end_intersection_needs_entering_then_leaving():
    cond = WaitEndIntersection(_Town(), junction_id=7)
    assert not cond.check(actor(0, 0))
    assert not cond.check(actor(12, 0))
    assert not cond.check(actor(19, 0))
    assert cond.check(actor(21, 0))
    assert cond.check(actor(0, 0))
    other = WaitEndIntersection(_Town(), junction_id=3)
    assert not other.check(actor(12, 0)) and not other.check(actor(21, 0))
    assert math.isclose(horizontal_distance(Location(1, 1, 0), Location(1, 1, 0)), 0.0)
