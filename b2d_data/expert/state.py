"""What the expert exposes after every step for the data agent (expert-and-scenarios.md §1.11)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Transform
from b2d_data.sim.api import TrafficLightState, VehicleControl


@dataclass(frozen=True)
class CloseSignal:
    """A traffic light or stop sign within ``light_radius`` of the ego (the dataset records their boxes)."""

    actor_id: int
    type_id: str
    location: np.ndarray  # world position of the trigger-volume centre
    yaw: float  # the actor's yaw (degrees)
    affects_ego: bool
    state: TrafficLightState | None = None  # lights only


@dataclass(frozen=True)
class ExpertState:
    """The expert's decision and everything behind it at one tick. World frame unless a name says otherwise.

    ``brake`` is the hazard brake (target speed 0), ``control_brake`` the controller's brake flag, ``should_brake``
    the TCP-style geometric heuristic. ``route`` / ``route_original``: 20 points 1 m apart starting 2.5 m ahead
    of the route index, on the working (possibly shifted) and the original route; ``changed_route`` is set while
    they differ. ``aim_point`` is the lateral
    controller's look-ahead point, ``angle`` the normalised heading error toward it (±1 = ±90°).
    """

    frame: int
    control: VehicleControl
    target_speed: float
    speed_limit: float
    speed: float
    route_index: int
    command: RoadOption
    junction: bool
    vehicle_hazard: bool = False
    vehicle_affecting_id: int | None = None
    walker_hazard: bool = False
    walker_affecting_id: int | None = None
    light_hazard: bool = False
    stop_sign_hazard: bool = False
    stop_sign_close: bool = False
    walker_close: bool = False
    walker_close_id: int | None = None
    speed_reduced_by_obj_type: str | None = None
    speed_reduced_by_obj_id: int | None = None
    speed_reduced_by_obj_distance: float | None = None
    brake: bool = False
    control_brake: bool = False
    should_brake: bool = False
    aim_point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angle: float = 0.0
    changed_route: bool = False
    route: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    route_original: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    near_lane_change: bool = False
    keep_driving: bool = False
    active_scenario: str | None = None
    next_traffic_light_id: int | None = None
    distance_to_traffic_light: float = float("inf")
    next_stop_sign_id: int | None = None
    distance_to_stop_sign: float = float("inf")
    close_traffic_lights: tuple[CloseSignal, ...] = ()
    close_stop_signs: tuple[CloseSignal, ...] = ()

    @property
    def steer(self) -> float:
        """Applied steer."""
        return self.control.steer

    @property
    def throttle(self) -> float:
        """Applied throttle."""
        return self.control.throttle


def to_ego_frame(points: np.ndarray, ego: Transform) -> np.ndarray:
    """World points (N, 2 or 3) → the ego's 2D frame (x forward, y right, CARLA's left-handed convention)."""
    pts = np.asarray(points, dtype=np.float64)
    yaw = np.radians(ego.rotation.yaw)
    c, s = np.cos(yaw), np.sin(yaw)
    d = pts[..., :2] - np.array([ego.location.x, ego.location.y])
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)
