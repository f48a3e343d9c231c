"""Vehicle dynamics: the kinematic bicycle of expert-and-scenarios.md §1.6, vectorised over vehicles.

One step (dt = 0.05 s) does, for every vehicle, in the same order as PDM-Lite's forecast:

1. the applied steer moves toward the commanded steer at most ``max_steer_rate · dt``;
2. wheel angle δ = 0.36848 · steer, slip β = atan(l_r / (l_f + l_r) · tan δ);
3. the reference point (the actor origin) moves with the speed *before* the update:
   x += v cos(ψ + β) dt, y += v sin(ψ + β) dt, ψ += v / l_r · sin β · dt;
4. the signed speed v along the heading is updated from throttle / brake / hand brake / reverse:
   drive = throttle · max(0, a_max − k · |v|) (backwards with ``reverse``), then the resistive part
   brake · b_max + hand_brake · b_hand + rolling + drag · v² pulls v toward 0 without crossing it.

So a vehicle that reports speed v at a tick is exactly v · dt further along at the next one, full brake from
10 m/s stops in about v² / (2 (b_max + rolling)) + v · dt / 2, and with throttle 0 a vehicle coasts down.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from b2d_data.sim.blueprints import BicycleGeometry, LongitudinalModel


@dataclass
class VehicleArrays:
    """State and parameters of n vehicles as parallel arrays (angles in radians, SI units)."""

    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    speed: np.ndarray  # signed, along the heading
    steer: np.ndarray  # applied normalised steer (after the rate limit)
    # controls
    throttle: np.ndarray
    steer_cmd: np.ndarray
    brake: np.ndarray
    hand_brake: np.ndarray  # 0/1
    reverse: np.ndarray  # 0/1
    # parameters
    max_accel: np.ndarray
    accel_falloff: np.ndarray
    max_brake: np.ndarray
    hand_brake_decel: np.ndarray
    rolling: np.ndarray
    drag: np.ndarray
    max_reverse_speed: np.ndarray
    max_steer_rate: np.ndarray
    rear_length: np.ndarray
    front_length: np.ndarray
    steer_to_wheel: np.ndarray

    @classmethod
    def from_rows(cls, state: np.ndarray, params: np.ndarray) -> VehicleArrays:
        """Build from an (n, 10) state/control matrix (columns :data:`STATE_COLUMNS`) and (n, 11) parameter rows."""
        fields = {name: state[:, k].copy() for k, name in enumerate(STATE_COLUMNS)}
        fields.update({name: params[:, k].copy() for k, name in enumerate(PARAM_COLUMNS)})
        return cls(**fields)


#: Columns of the state/control matrix given to :meth:`VehicleArrays.from_rows`.
STATE_COLUMNS = ("x", "y", "yaw", "speed", "steer", "throttle", "steer_cmd", "brake", "hand_brake", "reverse")
#: Columns of a parameter row (:func:`param_row`).
PARAM_COLUMNS = ("max_accel", "accel_falloff", "max_brake", "hand_brake_decel", "rolling", "drag",
                 "max_reverse_speed", "max_steer_rate", "rear_length", "front_length", "steer_to_wheel")


def param_row(dynamics: LongitudinalModel, geometry: BicycleGeometry) -> np.ndarray:
    """One vehicle's parameters in :data:`PARAM_COLUMNS` order."""
    return np.array([
        dynamics.max_accel, dynamics.accel_falloff, dynamics.max_brake, dynamics.hand_brake, dynamics.rolling,
        dynamics.drag, dynamics.max_reverse_speed, dynamics.max_steer_rate, geometry.rear_length,
        geometry.front_length, geometry.steer_to_wheel,
    ])  # fmt: skip


def slip_angle(steer: np.ndarray, rear_length: np.ndarray, front_length: np.ndarray,
               steer_to_wheel: np.ndarray) -> np.ndarray:
    """β = atan(l_r / (l_f + l_r) · tan(k · steer)) for normalised steers."""
    wheel = steer_to_wheel * np.clip(steer, -1.0, 1.0)
    return np.arctan(rear_length / (front_length + rear_length) * np.tan(wheel))


def bicycle_kinematics(x: np.ndarray, y: np.ndarray, yaw: np.ndarray, speed: np.ndarray, beta: np.ndarray,
                       rear_length: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One explicit Euler step of the reference point's pose at the given speed and slip angle."""
    heading = yaw + beta
    return (
        x + speed * np.cos(heading) * dt,
        y + speed * np.sin(heading) * dt,
        yaw + speed / rear_length * np.sin(beta) * dt,
    )


def longitudinal_accel(v: VehicleArrays) -> tuple[np.ndarray, np.ndarray]:
    """(driving acceleration along the heading, magnitude of the resistive deceleration) in m/s²."""
    available = np.maximum(0.0, v.max_accel - v.accel_falloff * np.abs(v.speed))
    drive = np.clip(v.throttle, 0.0, 1.0) * available
    backwards = v.reverse > 0.5
    drive = np.where(backwards, -drive, drive)
    # reverse gear is speed-limited; forward speed is limited by the power fall-off and drag
    drive = np.where(backwards & (v.speed <= -v.max_reverse_speed), 0.0, drive)
    resist = (
        np.clip(v.brake, 0.0, 1.0) * v.max_brake
        + (v.hand_brake > 0.5) * v.hand_brake_decel
        + v.rolling
        + v.drag * v.speed * v.speed
    )
    return drive, resist


def step(v: VehicleArrays, dt: float) -> np.ndarray:
    """Advance every vehicle in place by dt; returns the slip angles β used (for the velocity direction)."""
    max_delta = v.max_steer_rate * dt
    v.steer = np.clip(v.steer + np.clip(np.clip(v.steer_cmd, -1.0, 1.0) - v.steer, -max_delta, max_delta), -1.0, 1.0)
    beta = slip_angle(v.steer, v.rear_length, v.front_length, v.steer_to_wheel)
    v.x, v.y, v.yaw = bicycle_kinematics(v.x, v.y, v.yaw, v.speed, beta, v.rear_length, dt)
    drive, resist = longitudinal_accel(v)
    speed = v.speed + drive * dt
    # resistive forces stop the vehicle but never push it the other way
    v.speed = np.where(speed > 0.0, np.maximum(0.0, speed - resist * dt), np.minimum(0.0, speed + resist * dt))
    return beta


def accel_for(dynamics: LongitudinalModel, speed: float, accel: float) -> tuple[float, float]:
    """Throttle and brake (each in [0, 1]) that produce ``accel`` m/s² at forward ``speed`` ≥ 0 (inverse model)."""
    resist = dynamics.rolling + dynamics.drag * speed * speed
    available = max(1e-6, dynamics.max_accel - dynamics.accel_falloff * abs(speed))
    if accel + resist >= 0.0:
        return min(1.0, (accel + resist) / available), 0.0
    return 0.0, min(1.0, (-accel - resist) / dynamics.max_brake)
