"""Lateral PID on the heading error toward a speed-dependent look-ahead route point (§1.5)."""

from __future__ import annotations

import math

import numpy as np

from b2d_data.expert.config import ExpertConfig


def lookahead_index(config: ExpertConfig, speed: float, n_points: int) -> int:
    """Route points ahead of the current index the controller aims at: clip(0.9755·v[km/h] + 1.9153, 24, 105)."""
    points = config.lateral_speed_scale * speed * 3.6 + config.lateral_speed_offset
    lo = config.lateral_min_lookahead * config.points_per_meter
    hi = config.lateral_max_lookahead * config.points_per_meter
    return int(min(min(max(points, lo), hi), n_points - 1))


def heading_error(position: np.ndarray | tuple[float, float], heading: float, target: np.ndarray) -> float:
    """Wrapped angle (rad) from the heading to the direction of ``target``, in (−π, π]."""
    desired = math.atan2(float(target[1] - position[1]), float(target[0] - position[0]))
    return math.remainder(desired - heading, 2.0 * math.pi)


class LateralPIDController:
    """steer = clip(kp·e + kd·(e_k − e_{k−1}) + ki·mean(last 6 e), −1, 1), e = heading error / 90°."""

    def __init__(self, config: ExpertConfig) -> None:
        self.config = config
        self.errors: list[float] = []
        self._saved: list[float] = []

    def step(self, route_points: np.ndarray, speed: float, position: np.ndarray | tuple[float, float],
             heading: float) -> float:
        """Steer for the route ahead (``route_points[0]`` is the current route point), speed m/s, heading rad."""
        target = route_points[lookahead_index(self.config, speed, route_points.shape[0])]
        # normalised so that ±1 is ±90°, a leftover of PDM-Lite's earlier controller
        error = math.degrees(heading_error(position, heading, target)) / 90.0
        self.errors.append(error)
        self.errors = self.errors[-self.config.lateral_window_size :]
        derivative = 0.0 if len(self.errors) == 1 else self.errors[-1] - self.errors[-2]
        integral = sum(self.errors) / len(self.errors)
        steer = self.config.lateral_kp * error + self.config.lateral_kd * derivative + self.config.lateral_ki * integral
        return min(1.0, max(-1.0, steer))

    def save_state(self) -> None:
        """Remember the error history (before forecasting the ego)."""
        self._saved = list(self.errors)

    def load_state(self) -> None:
        """Restore the remembered error history."""
        self.errors = list(self._saved)
