"""Fixtures of the expert tests: stand-ins for map waypoints and actors (geometry tests need no town)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.route_processing import DenseRoute, route_headings
from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.maps import LaneChange, LaneType
from b2d_data.sim.api import ActorKind, ActorState, VehicleControl, WalkerControl


@dataclass(frozen=True)
class FakeWaypoint:
    """A waypoint on a straight east-bound road along y = ``y``; lane ``lane_id``; lanes 3.5 m wide.

    Left of an east-bound lane is −y (north) in CARLA's frame.
    """

    x: float
    y: float = 0.0
    lane_id: int = -1
    road_id: int = 1
    lane_width: float = 3.5
    lane_type: LaneType = LaneType.DRIVING
    lane_change: LaneChange = LaneChange.BOTH
    is_junction: bool = False
    right_type: LaneType = LaneType.DRIVING

    @property
    def transform(self) -> Transform:
        return Transform(Location(self.x, self.y, 0.0), Rotation(yaw=0.0))

    def get_left_lane(self) -> FakeWaypoint:
        # like OpenDRIVE: left of lane −1 is the opposite lane 1
        return FakeWaypoint(self.x, self.y - self.lane_width, 1 if self.lane_id == -1 else self.lane_id + 1,
                            self.road_id)

    def get_right_lane(self) -> FakeWaypoint:
        return FakeWaypoint(self.x, self.y + self.lane_width, self.lane_id - 1, self.road_id,
                            lane_type=self.right_type)

    def previous(self, distance: float) -> list[FakeWaypoint]:
        return [FakeWaypoint(self.x - distance, self.y, self.lane_id, self.road_id)]


def straight_route(length: float = 100.0, config: ExpertConfig | None = None, **wp_kwargs) -> DenseRoute:
    """A dense route along the x axis from 0 to ``length`` (10 points/m), index 0, on fake waypoints."""
    config = config or ExpertConfig()
    n = round(length * config.points_per_meter) + 1
    x = np.arange(n) / config.points_per_meter
    points = np.stack([x, np.zeros(n), np.zeros(n)], axis=1)
    wps = [FakeWaypoint(float(xi), **wp_kwargs) for xi in x]
    cmds = [RoadOption.LANEFOLLOW] * n
    return DenseRoute(
        points=points.copy(), original_points=points.copy(), coarse_waypoints=wps, commands=list(cmds),
        original_commands=list(cmds), headings=route_headings(points), next_light=[None] * n,
        light_distance=np.full(n, np.inf), next_stop=[None] * n, stop_distance=np.full(n, np.inf),
        speed_limits=np.full(n, 50 / 3.6), is_junction=np.zeros(n, dtype=bool), town=None, index=0, config=config,
    )  # fmt: skip


def vehicle(actor_id: int, x: float, y: float, yaw: float = 0.0, speed: float = 0.0, half=(2.4, 1.0, 0.75),
            control: VehicleControl | None = None, role: str = "", base_type: str = "car") -> ActorState:
    """A vehicle actor at (x, y) heading ``yaw`` degrees with forward ``speed``."""
    r = np.radians(yaw)
    return ActorState(
        id=actor_id, type_id="vehicle.test.car", kind=ActorKind.VEHICLE,
        transform=Transform(Location(x, y, 0.0), Rotation(yaw=yaw)),
        velocity=Vector3D(speed * np.cos(r), speed * np.sin(r), 0.0), angular_velocity=Vector3D(),
        acceleration=Vector3D(), bounding_box=BoundingBox(Location(0.0, 0.0, half[2]), Location(*half)),
        semantic_tags=(14,), role_name=role, base_type=base_type, control=control or VehicleControl(),
    )  # fmt: skip


def walker(actor_id: int, x: float, y: float, direction=(0.0, 1.0), speed: float = 1.4) -> ActorState:
    """A walker at (x, y) walking along ``direction`` (unit, world frame)."""
    yaw = float(np.degrees(np.arctan2(direction[1], direction[0])))
    return ActorState(
        id=actor_id, type_id="walker.pedestrian.0001", kind=ActorKind.WALKER,
        transform=Transform(Location(x, y, 0.9), Rotation(yaw=yaw)),
        velocity=Vector3D(direction[0] * speed, direction[1] * speed, 0.0), angular_velocity=Vector3D(),
        acceleration=Vector3D(), bounding_box=BoundingBox(Location(), Location(0.25, 0.25, 0.9)),
        semantic_tags=(12,), control=WalkerControl(Vector3D(direction[0], direction[1], 0.0), speed),
    )  # fmt: skip


@pytest.fixture
def make_route():
    """Factory: :func:`straight_route`."""
    return straight_route


@pytest.fixture
def make_vehicle():
    """Factory: :func:`vehicle`."""
    return vehicle


@pytest.fixture
def make_walker():
    """Factory: :func:`walker`."""
    return walker
