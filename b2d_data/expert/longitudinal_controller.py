"""Target speed → throttle / brake (expert-and-scenarios.md §1.4).

The default is PDM-Lite's "linear regression" controller: full throttle for large speed errors, a brake when
the ego is more than 3.1 % too fast, otherwise a six-feature polynomial in speed and speed error (km/h / 100).
The PID variant exists for ablations. :func:`fit_linear_regression_params` re-fits the regression for other
vehicle dynamics (the builtin expert no longer needs it: its ego follows the CARLA fit the published parameters
were made for; see :data:`b2d_data.expert.config.CARLA_LINEAR_REGRESSION_PARAMS`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from b2d_data.expert.config import ExpertConfig

_KMH = 3.6


def _features(speed_kmh: float, error_kmh: float) -> np.ndarray:
    """The regression's features; the /100 scaling is a leftover of PDM-Lite's optimisation."""
    u = speed_kmh / 100.0
    w = max(error_kmh, 0.0) / 100.0
    return np.array([u, u * u, 100.0 * w, w * w, u * w, u * u * w])


class LongitudinalController(Protocol):
    """Anything that turns a target speed into (throttle, brake)."""

    def get_throttle_and_brake(self, hazard_brake: bool, target_speed: float,
                               current_speed: float) -> tuple[float, bool]:
        """(throttle in [0, 1], brake flag) for driving."""
        ...

    def get_throttle_extrapolation(self, target_speed: float, current_speed: float) -> float:
        """Throttle for forecasting the ego (never brakes)."""
        ...

    def save(self) -> None:
        """Remember the internal state (before forecasting)."""
        ...

    def load(self) -> None:
        """Restore the remembered state."""
        ...


class LinearRegressionController:
    """PDM-Lite's default longitudinal controller (stateless)."""

    def __init__(self, config: ExpertConfig) -> None:
        self.config = config
        self.params = np.asarray(config.linear_regression_params, dtype=np.float64)

    def get_throttle_and_brake(self, hazard_brake: bool, target_speed: float,
                               current_speed: float) -> tuple[float, bool]:
        """(throttle, brake flag) for the speeds in m/s."""
        if hazard_brake or target_speed < 1e-5:
            return 0.0, True
        target_speed = max(target_speed, self.config.linear_regression_min_target_speed)
        v, vt = current_speed * _KMH, target_speed * _KMH
        error = vt - v
        if error > self.config.linear_regression_max_acceleration:
            return 1.0, False
        if v / vt > self.params[-1]:
            return 0.0, True
        throttle = float(np.clip(_features(v, error) @ self.params[:-1], 0.0, 1.0))
        return throttle, False

    def get_throttle_extrapolation(self, target_speed: float, current_speed: float) -> float:
        """Throttle of the forecasting variant: 0 when much too fast, never a brake."""
        v, vt = current_speed * _KMH, target_speed * _KMH
        error = vt - v
        if error > self.config.linear_regression_max_acceleration:
            return 1.0
        if error < self.config.linear_regression_max_deceleration:
            return 0.0
        # 0.1 km/h: tiny targets mean standing still
        if vt < 0.1 or v / vt > self.params[-1]:
            return 0.0
        return min(1.0, max(0.0, float(_features(v, error) @ self.params[:-1])))

    def save(self) -> None:
        """Nothing to remember: the controller is stateless."""

    def load(self) -> None:
        """Nothing to restore: the controller is stateless."""


class PIDLongitudinalController:
    """The PID alternative of PDM-Lite's ablations (km/h errors, empty error window by default)."""

    def __init__(self, config: ExpertConfig, window: int = 0) -> None:
        self.config = config
        self.window = window
        self.errors: list[float] = []
        self._saved: list[float] = []

    def get_throttle_and_brake(self, hazard_brake: bool, target_speed: float,
                               current_speed: float) -> tuple[float, bool]:
        """(throttle, brake flag) for the speeds in m/s."""
        if hazard_brake or target_speed < 1e-5:
            return 0.0, True
        target_speed = max(target_speed, self.config.pid_min_target_speed)
        v, vt = current_speed * _KMH, target_speed * _KMH
        if v / vt > self.config.pid_brake_ratio:
            self.errors = [0.0] * self.window
            return 0.0, True
        error = vt - v
        self.errors.append(error)
        # PDM-Lite's window length 0 keeps the whole list (list[-0:]); a positive window trims it
        if self.window > 0:
            self.errors = self.errors[-self.window :]
        derivative = 0.0 if len(self.errors) == 1 else self.errors[-1] - self.errors[-2]
        integral = float(np.mean(self.errors))
        throttle = self.config.pid_kp * error + self.config.pid_kd * derivative + self.config.pid_ki * integral
        return float(np.clip(throttle, 0.0, 1.0)), False

    def get_throttle_extrapolation(self, target_speed: float, current_speed: float) -> float:
        """Throttle for forecasting (the PID's own state is saved/restored around the forecast)."""
        throttle, _ = self.get_throttle_and_brake(False, target_speed, current_speed)
        return throttle

    def save(self) -> None:
        """Remember the error window."""
        self._saved = list(self.errors)

    def load(self) -> None:
        """Restore the error window."""
        self.errors = list(self._saved)


def make_longitudinal_controller(config: ExpertConfig) -> LinearRegressionController | PIDLongitudinalController:
    """The controller named by ``config.longitudinal_controller``."""
    if config.longitudinal_controller == "linear_regression":
        return LinearRegressionController(config)
    if config.longitudinal_controller == "pid":
        return PIDLongitudinalController(config)
    raise ValueError(f"unknown longitudinal controller {config.longitudinal_controller!r} (linear_regression, pid)")


def fit_linear_regression_params(throttle_for: Callable[[float, float], float], gain: float = 2.0,
                                 max_speed_kmh: float = 120.0, max_error_kmh: float = 1.89,
                                 brake_ratio: float = 1.031266635497984) -> tuple[float, ...]:
    """Least-squares fit of the six regression parameters for a vehicle model.

    ``throttle_for(speed, accel)`` is the model's inverse: the throttle that gives ``accel`` m/s² at ``speed``
    m/s. The wanted acceleration is ``gain`` × speed error (m/s² per m/s), i.e. the controller should close the
    error with a time constant of 1/gain seconds; samples cover speeds 0…``max_speed_kmh`` and errors
    0…``max_error_kmh`` (beyond that the controller gives full throttle anyway).
    """
    rows, targets = [], []
    for v_kmh in np.linspace(0.0, max_speed_kmh, 121):
        for e_kmh in np.linspace(0.0, max_error_kmh, 12):
            accel = gain * e_kmh / _KMH
            rows.append(_features(float(v_kmh), float(e_kmh)))
            targets.append(throttle_for(float(v_kmh) / _KMH, accel))
    params, *_ = np.linalg.lstsq(np.array(rows), np.array(targets), rcond=None)
    return tuple(float(p) for p in params) + (float(brake_ratio),)
