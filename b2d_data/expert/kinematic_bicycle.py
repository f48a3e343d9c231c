"""The kinematic bicycle model PDM-Lite forecasts with (§1.6), tuned on CARLA by World on Rails.

Other vehicles: wheel angle = gain × steer, slip β = atan(l_r / (l_f + l_r) · tan(wheel)), pose moves with the
speed before the update, speed changes by a constant brake deceleration or throttle × a constant acceleration.
The ego uses the same geometry but fitted polynomials for its speed (throttle and brake models, km/h).
"""

from __future__ import annotations

import math

import numpy as np

from b2d_data.expert.config import ExpertConfig


def slip_angle(config: ExpertConfig, steer: np.ndarray | float) -> np.ndarray:
    """β for normalised steer(s)."""
    wheel = config.steering_gain * np.asarray(steer, dtype=np.float64)
    return np.arctan(config.rear_wheel_base / (config.front_wheel_base + config.rear_wheel_base) * np.tan(wheel))


def step_pose(config: ExpertConfig, x: np.ndarray, y: np.ndarray, yaw: np.ndarray, speed: np.ndarray,
              steer: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One Euler step of the reference point (yaw in radians)."""
    beta = slip_angle(config, steer)
    dt = config.dt
    return (
        x + speed * np.cos(yaw + beta) * dt,
        y + speed * np.sin(yaw + beta) * dt,
        yaw + speed / config.rear_wheel_base * np.sin(beta) * dt,
    )


def forecast_other_vehicles(config: ExpertConfig, x: np.ndarray, y: np.ndarray, yaw: np.ndarray, speed: np.ndarray,
                            steer: np.ndarray, throttle: np.ndarray, brake: np.ndarray
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One step for many vehicles holding their control: (x, y, yaw, speed) arrays."""
    nx, ny, nyaw = step_pose(config, x, y, yaw, speed, steer)
    braking = brake >= config.other_vehicle_brake_threshold
    accel = np.where(braking, config.other_brake_acceleration, throttle * config.other_throttle_acceleration)
    return nx, ny, nyaw, np.maximum(0.0, speed + config.dt * accel)


def ego_next_speed(config: ExpertConfig, speed: float, throttle: float, brake: bool) -> float:
    """The ego's speed after one step from the fitted polynomials (CARLA's Lincoln; inputs and fit in km/h)."""
    v = speed * 3.6
    if brake:
        # Σ c_k·v^k for k = 1…7 (no constant term), by Horner's scheme
        acc = 0.0
        for c in reversed(config.ego_brake_poly):
            acc = (acc + c) * v
        next_kmh = acc
    else:
        t = min(1.0, max(0.0, throttle))
        # the polynomial does not hold for small throttles, where the car barely accelerates
        if t < config.ego_throttle_threshold:
            return speed
        c = config.ego_throttle_poly
        next_kmh = (c[0] * v + c[1] * v * v + c[2] * t + c[3] * t * t + c[4] * v * t + c[5] * v * t * t
                    + c[6] * v * v * t + c[7] * v * v * t * t)
    return max(0.0, next_kmh / 3.6)


def forecast_ego(config: ExpertConfig, x: float, y: float, yaw: float, speed: float, steer: float, throttle: float,
                 brake: bool) -> tuple[float, float, float, float]:
    """One ego step: (x, y, yaw, speed) (scalar version of :func:`step_pose` plus the ego's speed model)."""
    wheel = config.steering_gain * steer
    beta = math.atan(config.rear_wheel_base / (config.front_wheel_base + config.rear_wheel_base) * math.tan(wheel))
    dt = config.dt
    return (
        x + speed * math.cos(yaw + beta) * dt,
        y + speed * math.sin(yaw + beta) * dt,
        yaw + speed / config.rear_wheel_base * math.sin(beta) * dt,
        ego_next_speed(config, speed, throttle, brake),
    )
