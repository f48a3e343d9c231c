"""The vehicle model, worked out by hand from the §1.6 bicycle and the longitudinal law."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.sim import blueprints
from b2d_data.sim.builtin import kinematic_bicycle as kb

DT = 0.05


def _one(speed: float = 0.0, **controls: float) -> kb.VehicleArrays:
    state = np.zeros((1, len(kb.STATE_COLUMNS)))
    state[0, kb.STATE_COLUMNS.index("speed")] = speed
    for name, value in controls.items():
        state[0, kb.STATE_COLUMNS.index(name)] = value
    params = kb.param_row(blueprints.CAR_DYNAMICS, blueprints.DEFAULT_GEOMETRY)[None, :]
    return kb.VehicleArrays.from_rows(state, params)


def test_straight_line_at_constant_speed_travels_v_t():
    x, y, yaw = np.zeros(1), np.zeros(1), np.zeros(1)
    for _ in range(40):  # 2 s at 10 m/s
        x, y, yaw = kb.bicycle_kinematics(x, y, yaw, np.array([10.0]), np.zeros(1), np.array([1.41783]), DT)
    assert x[0] == pytest.approx(20.0) and y[0] == 0.0 and yaw[0] == 0.0


def test_steady_steer_drives_the_predicted_circle():
    g = blueprints.DEFAULT_GEOMETRY
    beta = g.slip_angle(0.4)
    radius = g.turn_radius(0.4)  # l_r / sin β ≈ 9.47 m
    v = 5.0
    x, y, yaw = np.zeros(1), np.zeros(1), np.zeros(1)
    pts = []
    for _ in range(400):
        x, y, yaw = kb.bicycle_kinematics(x, y, yaw, np.array([v]), np.array([beta]), np.array([g.rear_length]), DT)
        pts.append((x[0], y[0]))
    pts = np.array(pts)
    # fit a circle: x² + y² + D x + E y + F = 0 (least squares)
    a = np.column_stack([pts[:, 0], pts[:, 1], np.ones(len(pts))])
    rhs = -(pts[:, 0] ** 2 + pts[:, 1] ** 2)
    d, e, f = np.linalg.lstsq(a, rhs, rcond=None)[0]
    fitted = math.sqrt(d * d / 4 + e * e / 4 - f)
    # Euler chords of length v·dt turning by ω·dt lie on a circle (v·dt/2)/sin(ω·dt/2): 0.05 % above R here
    assert fitted == pytest.approx(radius, rel=2e-3)
    # positive steer turns clockwise seen from above: toward +y (right) in CARLA's frame
    assert pts[10, 1] > 0.0


def test_full_brake_from_10_stops_within_the_decel_distance():
    v = _one(speed=10.0, brake=1.0)
    travelled, ticks = 0.0, 0
    while v.speed[0] > 0.0:
        x0 = v.x[0]
        kb.step(v, DT)
        travelled += v.x[0] - x0
        ticks += 1
    # decel ≥ 8 (brake) + 0.25 (rolling): v²/(2a) + v·dt/2 (positions use the speed before each update)
    assert travelled <= 10.0**2 / (2 * 8.25) + 10.0 * DT / 2 + 1e-9
    assert travelled > 10.0**2 / (2 * 8.5)
    assert ticks == math.ceil(10.0 / (8.25 * DT)) or ticks == math.ceil(10.0 / (8.25 * DT)) - 1
    assert v.speed[0] == 0.0  # and it does not roll backwards


def test_full_throttle_from_rest_accelerates_at_the_model_rate():
    v = _one(throttle=1.0)
    kb.step(v, DT)
    # drive 3.8 m/s² at 0 m/s minus rolling 0.25 m/s²
    assert v.speed[0] == pytest.approx((3.8 - 0.25) * DT)


def test_coasting_slows_down_and_stops():
    v = _one(speed=5.0)
    for _ in range(20 * 20):
        kb.step(v, DT)
    assert v.speed[0] == 0.0


def test_reverse_and_hand_brake():
    v = _one(throttle=1.0, reverse=1.0)
    for _ in range(20):
        kb.step(v, DT)
    assert v.speed[0] < -2.0 and v.x[0] < 0.0
    v = _one(speed=10.0, hand_brake=1.0)
    kb.step(v, DT)
    assert v.speed[0] == pytest.approx(10.0 - (6.0 + 0.25 + 4e-4 * 100.0) * DT)


def test_steer_rate_limit():
    v = _one(speed=5.0, steer_cmd=1.0)
    kb.step(v, DT)
    assert v.steer[0] == pytest.approx(blueprints.CAR_DYNAMICS.max_steer_rate * DT)


def test_inverse_longitudinal_model():
    d = blueprints.CAR_DYNAMICS
    throttle, brake = kb.accel_for(d, 10.0, 1.0)
    assert brake == 0.0
    assert throttle * (d.max_accel - d.accel_falloff * 10.0) - d.rolling - d.drag * 100.0 == pytest.approx(1.0)
    throttle, brake = kb.accel_for(d, 10.0, -4.0)
    assert throttle == 0.0 and brake * d.max_brake + d.rolling + d.drag * 100.0 == pytest.approx(4.0)
