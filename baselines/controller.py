"""Waypoints → vehicle control: the PID conversion of TCP and AD-MLP's Bench2DriveZoo agents.

Facts taken from Bench2DriveZoo (``TCP/config.py``, ``ADMLP/config.py``, ``control_pid`` of their models and the
agents' ``run_step``): lateral PID K_P 0.75, K_I 0.75, K_D 0.3 over a 40-step window; longitudinal PID K_P 5.0,
K_I 0.5, K_D 1.0 over 40 steps; aim at the predicted waypoint whose segment midpoint lies nearest 4 m ahead, or at
the route's target point when that turns less or when the prediction's last segment disagrees with it by more than
0.3 (in units of 90°) while the target is less than 10 m ahead; desired speed = mean waypoint spacing / 0.5 s;
brake when the desired speed is under 0.4 m/s or the speed exceeds it by 10 %; the speed error fed to the PID is
clipped to [0, 0.25] and the throttle to [0, 0.75]; the agent then turns any brake into a full brake with no
throttle. Waypoints and the target are in CARLA's ego frame (x forward, y right), steer + = right.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ControllerConfig:
    """Gains and thresholds of the waypoint controller (Bench2DriveZoo's values)."""

    turn_kp: float = 0.75
    turn_ki: float = 0.75
    turn_kd: float = 0.3
    turn_n: int = 40
    speed_kp: float = 5.0
    speed_ki: float = 0.5
    speed_kd: float = 1.0
    speed_n: int = 40
    max_throttle: float = 0.75
    brake_speed: float = 0.4
    brake_ratio: float = 1.1
    clip_delta: float = 0.25
    aim_dist: float = 4.0
    angle_thresh: float = 0.3
    dist_thresh: float = 10.0
    waypoint_dt: float = 0.5


class PID:
    """PID with a windowed mean as its integral term (TCP's ``PIDController``)."""

    def __init__(self, k_p: float, k_i: float, k_d: float, n: int = 20) -> None:
        self.k_p, self.k_i, self.k_d = k_p, k_i, k_d
        self.window: deque[float] = deque([0.0] * n, maxlen=n)

    def step(self, error: float) -> float:
        """Control for this error; the window starts full of zeros."""
        self.window.append(float(error))
        integral = float(np.mean(self.window))
        derivative = self.window[-1] - self.window[-2]
        return self.k_p * error + self.k_i * integral + self.k_d * derivative


def heading_units(forward: float, right: float) -> float:
    """Angle of a point from straight ahead, clockwise, in units of 90° (TCP's steering error)."""
    return float(np.degrees(np.pi / 2.0 - np.arctan2(forward, right)) / 90.0)


@dataclass(frozen=True)
class ControlOutput:
    """What the conversion decided, with the intermediate values the Zoo agents log."""

    steer: float
    throttle: float
    brake: bool
    desired_speed: float
    angle_final: float
    aim: tuple[float, float]


class WaypointController:
    """Turns predicted waypoints (K, 2) and the route target point into steer / throttle / brake."""

    def __init__(self, config: ControllerConfig | None = None) -> None:
        self.config = config or ControllerConfig()
        c = self.config
        self.turn = PID(c.turn_kp, c.turn_ki, c.turn_kd, c.turn_n)
        self.speed = PID(c.speed_kp, c.speed_ki, c.speed_kd, c.speed_n)

    def step(self, waypoints: np.ndarray, speed: float, target: np.ndarray) -> ControlOutput:
        """One control step; ``waypoints`` every 0.5 s ahead, ``target`` the route's next target point."""
        c = self.config
        wp = np.asarray(waypoints, np.float64)[:, :2]
        target = np.asarray(target, np.float64).reshape(2)
        pairs = len(wp) - 1
        desired = 0.0
        aim, best = wp[0], 1e5
        for i in range(pairs):
            desired += float(np.linalg.norm(wp[i + 1] - wp[i])) / c.waypoint_dt / pairs
            norm = float(np.linalg.norm((wp[i + 1] + wp[i]) / 2.0))
            if abs(c.aim_dist - best) > abs(c.aim_dist - norm):
                aim, best = wp[i], norm
        last = wp[-1] - wp[-2]
        angle = heading_units(aim[0], aim[1])
        angle_last = heading_units(last[0], last[1])
        angle_target = heading_units(target[0], target[1])
        # The target point wins when it turns less, or when the prediction's end disagrees with a near target.
        use_target = abs(angle_target) < abs(angle) or (
            abs(angle_target - angle_last) > c.angle_thresh and target[0] < c.dist_thresh
        )
        angle_final = angle_target if use_target else angle
        steer = float(np.clip(self.turn.step(angle_final), -1.0, 1.0))
        brake = desired < c.brake_speed or (speed / desired) > c.brake_ratio
        delta = float(np.clip(desired - speed, 0.0, c.clip_delta))
        throttle = float(np.clip(self.speed.step(delta), 0.0, c.max_throttle))
        if brake:
            throttle = 0.0
        return ControlOutput(steer, throttle, bool(brake), desired, angle_final, (float(aim[0]), float(aim[1])))


def agent_control(out: ControlOutput, speed: float, throttle_cap: bool = False) -> tuple[float, float, float]:
    """The Zoo agents' last step: any brake is a full brake with no throttle (steer, throttle, brake).

    ``throttle_cap`` adds the Zoo TCP agent's creep rule (throttle ≤ 0.05 above 1.5 m/s, 1.0 m/s while steering
    more than 0.07); it is off by default because it holds the car near walking pace (see baselines/README.md).
    """
    steer, throttle = out.steer, out.throttle
    if throttle_cap:
        limit = 1.0 if abs(steer) > 0.07 else 1.5
        throttle = min(throttle, 0.05 if speed > limit else 0.5)
    brake = 1.0 if out.brake else 0.0
    if brake > 0.5:
        throttle = 0.0
    return steer, throttle, brake
