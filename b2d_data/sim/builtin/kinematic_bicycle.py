"""Vehicle dynamics: the kinematic bicycle of expert-and-scenarios.md §1.6, vectorised over vehicles.

One step (dt = 0.05 s) does, for every vehicle, in the same order as PDM-Lite's forecast:

1. the applied steer moves toward the commanded steer at most ``max_steer_rate · dt``;
2. wheel angle δ = 0.36848 · steer, slip β = atan(l_r / (l_f + l_r) · tan δ);
3. the reference point (the actor origin) moves with the speed *before* the update:
   x += v cos(ψ + β) dt, y += v sin(ψ + β) dt, ψ += v / l_r · sin β · dt;
4. the signed speed v along the heading is updated by the vehicle's longitudinal law
   (:class:`~b2d_data.sim.blueprints.LongitudinalLaw`):

   - ``LINEAR`` (every vehicle but the ego's Lincoln): drive = throttle · max(0, a_max − k · |v|) (backwards with
     ``reverse``), then the resistive part brake · b_max + hand_brake · b_hand + rolling + drag · v² pulls v toward 0
     without crossing it. Full brake from 10 m/s stops in about v² / (2 (b_max + rolling)) + v · dt / 2.
   - ``CARLA_LINCOLN`` (``vehicle.lincoln.mkz_2020``), forward gear and v ≥ 0: PDM-Lite's polynomials of CARLA's
     Lincoln, next speed [km/h] = f(v [km/h], throttle) or g(v [km/h]) for a full brake, one 0.05 s step each
     (:func:`lincoln_accel` turns them into accelerations, so a 0.05 s tick reproduces them exactly). Where they do
     not apply, the law is continuous and monotone in throttle and brake: see :func:`lincoln_accel`. The hand brake
     adds ``hand_brake_decel``; reverse gear and rolling backwards use the linear law.

So a vehicle that reports speed v at a tick is exactly v · dt further along at the next one, and with throttle 0 a
vehicle coasts down.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from b2d_data.sim.blueprints import BicycleGeometry, LongitudinalLaw, LongitudinalModel

#: PDM-Lite's ego throttle model of CARLA's Lincoln MKZ 2020 (carla_garage ``kinematic_bicycle_model.py``, the same
#: numbers as ``ExpertConfig.ego_throttle_poly``): next speed [km/h] after 0.05 s = c0·v + c1·v² + c2·t + c3·t² +
#: c4·v·t + c5·v·t² + c6·v²·t + c7·v²·t², v in km/h, t the throttle (valid for t ≥ 0.3).
LINCOLN_THROTTLE_POLY = (
    9.63873001e-01, 4.37535692e-04, -3.80192912e-01, 1.74950069e00, 9.16787414e-02, -7.05461530e-02,
    -1.05996152e-03, 6.71079346e-04,
)  # fmt: skip
#: … and its full-brake model: next speed [km/h] = Σ b_k · v^k, k = 1…7 (``ExpertConfig.ego_brake_poly``).
LINCOLN_BRAKE_POLY = (
    9.31711370e-03, 8.20967431e-02, -2.83832427e-03, 5.06587474e-05, -4.90357228e-07, 2.44419284e-09,
    -4.91381935e-12,
)  # fmt: skip
#: The step the polynomials were fitted for (PDM-Lite's 20 Hz).
LINCOLN_POLY_DT = 0.05
#: Lowest throttle the throttle polynomial describes (PDM-Lite's ``throttle_threshold_during_forecasting``).
LINCOLN_THROTTLE_THRESHOLD = 0.3
#: Highest speed (m/s, 80 km/h) where the throttle polynomial is used as it is: it grows with throttle only up to
#: ~87 km/h; beyond, throttle 0.3 out-accelerates full throttle (at 100 km/h +1.9 against +2.0 m/s², at 120 km/h
#: +4.7 against +1.5), which no car does, so there it no longer describes CARLA's.
LINCOLN_THROTTLE_MAX_SPEED = 80.0 / 3.6
#: Highest speed (m/s, 108 km/h) where the brake polynomial is used as it is: up to there it gives 6.6–8 m/s² above
#: 7.5 m/s; beyond, its deceleration falls to 4.3 m/s² at 130 km/h and the 7th-order terms diverge (61 m/s² at 144).
LINCOLN_BRAKE_MAX_SPEED = 30.0


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
    law: np.ndarray  # LongitudinalLaw values

    @classmethod
    def from_rows(cls, state: np.ndarray, params: np.ndarray) -> VehicleArrays:
        """Build from an (n, 10) state/control matrix (columns :data:`STATE_COLUMNS`) and (n, 12) parameter rows."""
        fields = {name: state[:, k].copy() for k, name in enumerate(STATE_COLUMNS)}
        fields.update({name: params[:, k].copy() for k, name in enumerate(PARAM_COLUMNS)})
        return cls(**fields)


#: Columns of the state/control matrix given to :meth:`VehicleArrays.from_rows`.
STATE_COLUMNS = ("x", "y", "yaw", "speed", "steer", "throttle", "steer_cmd", "brake", "hand_brake", "reverse")
#: Columns of a parameter row (:func:`param_row`).
PARAM_COLUMNS = ("max_accel", "accel_falloff", "max_brake", "hand_brake_decel", "rolling", "drag",
                 "max_reverse_speed", "max_steer_rate", "rear_length", "front_length", "steer_to_wheel", "law")


def param_row(dynamics: LongitudinalModel, geometry: BicycleGeometry) -> np.ndarray:
    """One vehicle's parameters in :data:`PARAM_COLUMNS` order."""
    return np.array([
        dynamics.max_accel, dynamics.accel_falloff, dynamics.max_brake, dynamics.hand_brake, dynamics.rolling,
        dynamics.drag, dynamics.max_reverse_speed, dynamics.max_steer_rate, geometry.rear_length,
        geometry.front_length, geometry.steer_to_wheel, float(dynamics.law),
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
    """Linear law: (driving acceleration along the heading, magnitude of the resistive deceleration) in m/s²."""
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


# -- CARLA's Lincoln (PDM-Lite's fitted polynomials) ---------------------------------------------------------


def _throttle_poly_terms(speed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C) of the throttle polynomial as A + B·t + C·t² in km/h, at speeds (m/s) capped to its range."""
    c = LINCOLN_THROTTLE_POLY
    vk = np.minimum(speed, LINCOLN_THROTTLE_MAX_SPEED) * 3.6
    return c[0] * vk + c[1] * vk * vk, c[2] + c[4] * vk + c[6] * vk * vk, c[3] + c[5] * vk + c[7] * vk * vk


def _poly_accel(next_kmh: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """The acceleration (m/s²) that takes ``speed`` (m/s) to ``next_kmh`` in one polynomial step."""
    return (next_kmh / 3.6 - speed) / LINCOLN_POLY_DT


def lincoln_coast_accel(speed: np.ndarray, rolling: np.ndarray, drag: np.ndarray) -> np.ndarray:
    """Acceleration (≤ 0) at throttle 0, no brake, v ≥ 0: rolling + drag, or throttle 0.3's if that slows more."""
    # The throttle polynomial has CARLA's Lincoln losing 0.9–1.5 m/s² at throttle 0.3 between 5 and 18 m/s (engine
    # braking); with less throttle it can only lose as much or more, so coasting takes the harder of the two.
    speed = np.asarray(speed, dtype=np.float64)
    coast = -(rolling + drag * speed * speed)
    return np.minimum(coast, lincoln_throttle_accel(speed, np.full_like(speed, LINCOLN_THROTTLE_THRESHOLD),
                                                    rolling, drag))


def lincoln_throttle_accel(speed: np.ndarray, throttle: np.ndarray, rolling: np.ndarray,
                           drag: np.ndarray) -> np.ndarray:
    """Acceleration of the throttle polynomial for throttles ≥ 0.3 and v ≥ 0, extended above its speed range."""
    speed = np.asarray(speed, dtype=np.float64)
    a, b, c = _throttle_poly_terms(speed)
    capped = np.minimum(speed, LINCOLN_THROTTLE_MAX_SPEED)
    poly = _poly_accel(a + b * throttle + c * throttle * throttle, capped)
    # Above 80 km/h: the polynomial's driving part at 80 km/h (its acceleration less the coasting loss there) at
    # constant power (× 80 km/h / v), plus the coasting loss at v. Continuous, monotone in throttle, and with full
    # throttle it tops out near 190 km/h; the expert never drives above 76 km/h (0.72 × 105 km/h).
    coast_hi = -(rolling + drag * LINCOLN_THROTTLE_MAX_SPEED**2)
    coast = -(rolling + drag * speed * speed)
    power = LINCOLN_THROTTLE_MAX_SPEED / np.maximum(speed, LINCOLN_THROTTLE_MAX_SPEED)
    return np.where(speed <= LINCOLN_THROTTLE_MAX_SPEED, poly, coast + (poly - coast_hi) * power)


def lincoln_brake_accel(speed: np.ndarray) -> np.ndarray:
    """Acceleration (≤ 0) of the full-brake polynomial for v ≥ 0 (held at its 108 km/h value above that speed)."""
    speed = np.asarray(speed, dtype=np.float64)
    vk = np.minimum(speed, LINCOLN_BRAKE_MAX_SPEED) * 3.6
    acc = np.zeros_like(vk)
    for coefficient in reversed(LINCOLN_BRAKE_POLY):  # Horner: Σ b_k·v^k, k = 1…7, no constant term
        acc = (acc + coefficient) * vk
    return np.minimum(0.0, _poly_accel(acc, np.minimum(speed, LINCOLN_BRAKE_MAX_SPEED)))


def lincoln_accel(speed: np.ndarray, throttle: np.ndarray, brake: np.ndarray, rolling: np.ndarray,
                  drag: np.ndarray) -> np.ndarray:
    """Net acceleration (m/s²) of the CARLA Lincoln law at forward speeds v ≥ 0 in forward gear.

    - throttle ≥ 0.3, no brake: the throttle polynomial (exact up to 80 km/h);
    - throttle < 0.3 (where the polynomial does not hold and PDM-Lite's forecast just keeps the speed): linear in
      throttle from coasting (:func:`lincoln_coast_accel`) at 0 to the polynomial at 0.3 — continuous, and never
      more deceleration than coasting;
    - brake = 1: the brake polynomial, whatever the throttle (PDM-Lite's forecast also drops the throttle; its
      brake test is ``brake == 1``); a partial brake b blends (1 − b)·(throttle law) + b·(brake polynomial).
    """
    speed = np.asarray(speed, dtype=np.float64)
    t = np.clip(throttle, 0.0, 1.0)
    b = np.clip(brake, 0.0, 1.0)
    at_threshold = lincoln_throttle_accel(speed, np.full_like(speed, LINCOLN_THROTTLE_THRESHOLD), rolling, drag)
    coast = np.minimum(-(rolling + drag * speed * speed), at_threshold)
    below = coast + (t / LINCOLN_THROTTLE_THRESHOLD) * (at_threshold - coast)
    driving = np.where(t >= LINCOLN_THROTTLE_THRESHOLD, lincoln_throttle_accel(speed, t, rolling, drag), below)
    return (1.0 - b) * driving + b * lincoln_brake_accel(speed)


def step(v: VehicleArrays, dt: float) -> np.ndarray:
    """Advance every vehicle in place by dt; returns the slip angles β used (for the velocity direction)."""
    max_delta = v.max_steer_rate * dt
    v.steer = np.clip(v.steer + np.clip(np.clip(v.steer_cmd, -1.0, 1.0) - v.steer, -max_delta, max_delta), -1.0, 1.0)
    beta = slip_angle(v.steer, v.rear_length, v.front_length, v.steer_to_wheel)
    v.x, v.y, v.yaw = bicycle_kinematics(v.x, v.y, v.yaw, v.speed, beta, v.rear_length, dt)
    drive, resist = longitudinal_accel(v)
    speed = v.speed + drive * dt
    # resistive forces stop the vehicle but never push it the other way
    speed = np.where(speed > 0.0, np.maximum(0.0, speed - resist * dt), np.minimum(0.0, speed + resist * dt))
    lincoln = (v.law == LongitudinalLaw.CARLA_LINCOLN) & (v.reverse <= 0.5) & (v.speed >= 0.0)
    if lincoln.any():
        k = np.flatnonzero(lincoln)
        accel = lincoln_accel(v.speed[k], v.throttle[k], v.brake[k], v.rolling[k], v.drag[k])
        accel -= (v.hand_brake[k] > 0.5) * v.hand_brake_decel[k]
        # the polynomials clamp the next speed at 0 as well (PDM-Lite: max(0, next speed))
        speed[k] = np.maximum(0.0, v.speed[k] + accel * dt)
    v.speed = speed
    return beta


def accel_for(dynamics: LongitudinalModel, speed: float, accel: float) -> tuple[float, float]:
    """Throttle and brake (each in [0, 1]) that produce ``accel`` m/s² at forward ``speed`` ≥ 0 (inverse model)."""
    if dynamics.law == LongitudinalLaw.CARLA_LINCOLN:
        return _lincoln_accel_for(dynamics, max(0.0, speed), accel)
    resist = dynamics.rolling + dynamics.drag * speed * speed
    available = max(1e-6, dynamics.max_accel - dynamics.accel_falloff * abs(speed))
    if accel + resist >= 0.0:
        return min(1.0, (accel + resist) / available), 0.0
    return 0.0, min(1.0, (-accel - resist) / dynamics.max_brake)


def accel_for_many(dynamics: Sequence[LongitudinalModel], speeds: Sequence[float],
                   accels: Sequence[float]) -> list[tuple[float, float]]:
    """:func:`accel_for` of each (dynamics, speed, accel), the CARLA Lincoln's polynomials evaluated for all at once."""
    out: list[tuple[float, float]] = []
    lincoln = [k for k, d in enumerate(dynamics) if d.law == LongitudinalLaw.CARLA_LINCOLN]
    terms = _lincoln_terms([max(0.0, speeds[k]) for k in lincoln], [dynamics[k] for k in lincoln]) if lincoln else []
    row = dict(zip(lincoln, terms))
    for k, (d, speed, accel) in enumerate(zip(dynamics, speeds, accels)):
        out.append(_lincoln_solve(d, max(0.0, speed), accel, row[k]) if k in row else accel_for(d, speed, accel))
    return out


def _lincoln_accel_for(dynamics: LongitudinalModel, speed: float, accel: float) -> tuple[float, float]:
    """:func:`accel_for` for the CARLA Lincoln law: solves the same three pieces :func:`lincoln_accel` joins."""
    return _lincoln_solve(dynamics, speed, accel, _lincoln_terms([speed], [dynamics])[0])


def _lincoln_terms(speeds: Sequence[float], dynamics: Sequence[LongitudinalModel]) -> list[tuple[float, ...]]:
    """Per speed (m/s, ≥ 0): the Lincoln law's accelerations at the throttle threshold, coasting, at full throttle
    and at full brake, and the throttle polynomial's (A, B, C); numpy's tiny-array overhead paid once for all."""
    v = np.array(speeds, dtype=np.float64)
    rolling = np.array([d.rolling for d in dynamics], dtype=np.float64)
    drag = np.array([d.drag for d in dynamics], dtype=np.float64)
    at_threshold = lincoln_throttle_accel(v, np.full_like(v, LINCOLN_THROTTLE_THRESHOLD), rolling, drag)
    coast = lincoln_coast_accel(v, rolling, drag)
    full = lincoln_throttle_accel(v, np.ones_like(v), rolling, drag)
    a, b, c = _throttle_poly_terms(v)
    brake = lincoln_brake_accel(v)
    return list(zip(*(x.tolist() for x in (at_threshold, coast, full, a, b, c, brake))))


def _lincoln_solve(dynamics: LongitudinalModel, speed: float, accel: float,
                   terms: tuple[float, ...]) -> tuple[float, float]:
    """:func:`_lincoln_accel_for` given the speed's :func:`_lincoln_terms`."""
    at_threshold, coast, full_throttle, a, b, c, full = terms
    if accel >= at_threshold:
        if accel >= full_throttle:
            return 1.0, 0.0
        # Invert the polynomial's A + B·t + C·t² = target (km/h, at the speed capped to its range). Above the range
        # the law is coast + (poly − coast_hi)·v_hi/v, so the polynomial must reach coast_hi + (accel − coast)·v/v_hi.
        capped = min(speed, LINCOLN_THROTTLE_MAX_SPEED)
        wanted = accel
        if speed > LINCOLN_THROTTLE_MAX_SPEED:
            coast_v = -(dynamics.rolling + dynamics.drag * speed * speed)
            coast_hi = -(dynamics.rolling + dynamics.drag * capped * capped)
            wanted = coast_hi + (accel - coast_v) * speed / capped
        d = (capped + wanted * LINCOLN_POLY_DT) * 3.6 - a
        # the root where the polynomial rises with throttle, in the form that stays exact as C → 0
        root = 2.0 * d / (b + np.sqrt(max(0.0, b * b + 4.0 * c * d)))
        return float(min(1.0, max(LINCOLN_THROTTLE_THRESHOLD, root))), 0.0
    if accel >= coast:
        span = at_threshold - coast
        return (LINCOLN_THROTTLE_THRESHOLD * (accel - coast) / span if span > 1e-9 else 0.0), 0.0
    if full >= coast - 1e-9:  # standing (almost) still: the brake cannot slow it further
        return 0.0, 1.0
    return 0.0, float(min(1.0, (coast - accel) / (coast - full)))
