"""The TCP-style ``should_brake`` heuristic recorded in Bench2Drive annotations (format.md §3.1).

It is the geometric hazard test of the older CARLA auto-pilots (LBC / Transfuser / TCP), independent of the
expert's own decision: a vehicle in a cone ahead within max(7.5 m, 2 s × speed) heading roughly the same way
(or straight ahead and close whatever its heading), a walker whose short path crosses a 10 m ray ahead of the
ego, or a red light / uncleared stop sign that affects the ego.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.sim.api import ActorState


def _heading(yaw_deg: float) -> np.ndarray:
    return np.array([math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))])


def segments_cross(p1: np.ndarray, v1: np.ndarray, p2: np.ndarray, v2: np.ndarray) -> bool:
    """Do segments p1 → p1 + v1 and p2 → p2 + v2 intersect (parallel ones never do)?"""
    a = np.stack([v1, -v2], axis=1)
    if abs(np.linalg.det(a)) < 1e-3:
        return False
    t = np.linalg.solve(a, p2 - p1)
    return bool(np.all(t >= 0.0) and np.all(t <= 1.0))


def vehicle_hazard(config: ExpertConfig, ego: ActorState, vehicles: Sequence[ActorState]) -> int | None:
    """Id of the first vehicle in the cone ahead of the ego, or ``None``."""
    o1 = _heading(ego.transform.rotation.yaw)
    p1 = np.array([ego.location.x, ego.location.y])
    reach = max(config.tcp_vehicle_min_distance, config.tcp_vehicle_time * ego.speed())
    for other in vehicles:
        if other.id == ego.id:
            continue
        if abs(other.location.x - p1[0]) > reach + 1.0 or abs(other.location.y - p1[1]) > reach + 1.0:
            continue  # farther than ``reach`` whatever its heading: the tests below would skip it too
        o2 = _heading(other.transform.rotation.yaw)
        offset = np.array([other.location.x, other.location.y]) - p1
        distance = float(np.linalg.norm(offset))
        direction = offset / (distance + 1e-4)
        angle_to_car = math.degrees(math.acos(float(np.clip(o1 @ direction, -1.0, 1.0))))
        angle_between = math.degrees(math.acos(float(np.clip(o1 @ o2, -1.0, 1.0))))
        if angle_between > config.tcp_vehicle_heading_limit and not (
            angle_to_car < config.tcp_vehicle_straight_cone and distance < reach
        ):
            continue
        if angle_to_car > config.tcp_vehicle_cone or distance > reach:
            continue
        return other.id
    return None


def walker_hazard(config: ExpertConfig, ego: ActorState, walkers: Sequence[ActorState]) -> int | None:
    """Id of the first walker whose path (3 m back to 5 m ahead) crosses a 10 m ray ahead of the ego."""
    p1 = np.array([ego.location.x, ego.location.y])
    v1 = config.tcp_walker_ray * _heading(ego.transform.rotation.yaw)
    for walker in walkers:
        v2_hat = _heading(walker.transform.rotation.yaw)
        if walker.speed() < 0.05:
            v2_hat = v2_hat * walker.speed()  # a standing walker is a point
        p2 = np.array([walker.location.x, walker.location.y]) - config.tcp_walker_back * v2_hat
        if segments_cross(p1, v1, p2, config.tcp_walker_length * v2_hat):
            return walker.id
    return None


def should_brake(config: ExpertConfig, ego: ActorState, vehicles: Sequence[ActorState],
                 walkers: Sequence[ActorState], light_hazard: bool, stop_sign_hazard: bool) -> bool:
    """Any of: vehicle hazard, walker hazard, red light affecting the ego, uncleared stop sign."""
    return bool(
        light_hazard
        or stop_sign_hazard
        or vehicle_hazard(config, ego, vehicles) is not None
        or walker_hazard(config, ego, walkers) is not None
    )
