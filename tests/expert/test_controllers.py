"""IDM, longitudinal and lateral controllers, the kinematic bicycle: expected values worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.expert.config import CARLA_LINEAR_REGRESSION_PARAMS, ExpertConfig
from b2d_data.expert.idm import idm_acceleration, idm_target_speed
from b2d_data.expert.kinematic_bicycle import ego_next_speed, forecast_ego, forecast_other_vehicles
from b2d_data.expert.lateral_controller import LateralPIDController, lookahead_index
from b2d_data.expert.longitudinal_controller import (
    LinearRegressionController,
    PIDLongitudinalController,
    fit_linear_regression_params,
)
from b2d_data.sim import blueprints
from b2d_data.sim.builtin import kinematic_bicycle as kb

CFG = ExpertConfig()


# ---------------------------------------------------------------------------------------------------- IDM
def test_idm_acceleration_formula():
    # v = 5, v_des = 10, same-speed leader 100 m ahead, s0 4, T 0.25, a 24, b 3.72:
    # s* = 4 + 5·0.25 + 0 = 5.25; 24·(1 − 0.5⁴ − (5.25/100)²) = 24·(1 − 0.0625 − 0.00275625) = 22.43385
    assert idm_acceleration(5.0, 10.0, 100.0, 5.0, 4.0, 0.25, 24.0, 3.72, 4.0) == pytest.approx(22.43385, abs=1e-9)


def test_idm_free_road_one_step():
    # standing start, no leader: dv/dt ≈ a = 24 m/s² for 0.05 s → 1.2 m/s ((v/v_des)⁴ ≤ 2e-4 is negligible)
    assert idm_target_speed(CFG, 10.0, 0.0, 0.0, 0.0, math.inf, 4.0, 0.25) == pytest.approx(1.2, abs=1e-3)


def test_idm_same_speed_leader_far_ahead():
    # starts at 22.43 m/s² and drops as v grows (v⁴ term): between v + 0.05·20 and v + 0.05·22.43
    target = idm_target_speed(CFG, 10.0, 5.0, 0.0, 5.0, 100.0, 4.0, 0.25)
    assert 6.0 < target < 5.0 + 0.05 * 22.43385


def test_idm_standing_at_minimum_gap_gives_zero():
    # v = 0 and gap = s0: s* = s0, so dv/dt = a·(1 − 0 − 1) = 0 → stays at 0
    assert idm_target_speed(CFG, 10.0, 0.0, 0.0, 0.0, 6.0, 6.0, 0.1) == 0.0


def test_idm_brakes_for_close_stop_line():
    # 10 m/s with a stop line 10 m ahead, s0 6 m: strong braking (b = 3.72 above 6.02 m/s)
    target = idm_target_speed(CFG, 10.0, 10.0, 0.0, 0.0, 10.0, 6.0, 0.1)
    assert target < 9.0


def test_idm_zero_desired_speed():
    assert idm_target_speed(CFG, 0.0, 3.0, 0.0, 0.0, 50.0, 4.0, 0.25) == 0.0


# ------------------------------------------------------------------------------------ longitudinal control
def test_linear_regression_brakes_for_zero_target_or_hazard():
    ctrl = LinearRegressionController(CFG)
    assert ctrl.get_throttle_and_brake(False, 0.0, 5.0) == (0.0, True)
    assert ctrl.get_throttle_and_brake(True, 10.0, 5.0) == (0.0, True)


def test_linear_regression_full_throttle_for_large_error():
    # 0 → 10 m/s: error 36 km/h > 1.89 km/h
    assert LinearRegressionController(CFG).get_throttle_and_brake(False, 10.0, 0.0) == (1.0, False)


def test_linear_regression_brakes_when_3_percent_too_fast():
    # 10.4 / 10 = 1.04 > 1.031266
    assert LinearRegressionController(CFG).get_throttle_and_brake(False, 10.0, 10.4) == (0.0, True)


def test_linear_regression_at_target_speed():
    # v = v_t = 36 km/h: u = 0.36, w = 0 → 1.1990342·0.36 − 0.8057602·0.1296 = 0.431652 − 0.104427 = 0.327226
    throttle, brake = LinearRegressionController(CFG).get_throttle_and_brake(False, 10.0, 10.0)
    assert not brake
    assert throttle == pytest.approx(0.327226, abs=1e-5)


def test_linear_regression_small_error():
    # v = 36 km/h, v_t = 36.1 km/h: u = 0.36, w = 0.001
    # 0.431652 − 0.104427 + 1.7108187·0.1 + 0.9218903·1e-6 + 1.5564975·0.00036 − 0.7013480·0.0001296
    # = 0.327226 + 0.171082 + 0.000001 + 0.000560 − 0.000091 = 0.498778
    throttle, brake = LinearRegressionController(CFG).get_throttle_and_brake(False, 36.1 / 3.6, 10.0)
    assert not brake
    assert throttle == pytest.approx(0.498778, abs=1e-5)


def test_linear_regression_raises_tiny_targets():
    # 0.1 m/s is raised to 0.278 m/s (1.0008 km/h); standing: u = 0, w = 0.010008 → 1.7108·1.0008 > 1 → clipped
    assert LinearRegressionController(CFG).get_throttle_and_brake(False, 0.1, 0.0) == (1.0, False)


def test_forecast_variant_never_brakes():
    ctrl = LinearRegressionController(CFG)
    assert ctrl.get_throttle_extrapolation(10.0, 0.0) == 1.0
    # error −5.4 km/h < −4.82 km/h → 0
    assert ctrl.get_throttle_extrapolation(10.0, 11.5) == 0.0
    assert ctrl.get_throttle_extrapolation(10.0, 10.0) == pytest.approx(0.327226, abs=1e-5)


def test_pid_controller_first_step():
    # error 1 km/h, first sample: kp·1 + kd·0 + ki·mean(1) = 1.0016429 + 0.2941564 = 1.2958 → clipped to 1
    ctrl = PIDLongitudinalController(CFG)
    assert ctrl.get_throttle_and_brake(False, 10.0, 10.0 - 1.0 / 3.6) == (1.0, False)
    ctrl = PIDLongitudinalController(CFG)
    # error 0.5 km/h: 0.5008215 + 0.1470782 = 0.6478997
    throttle, brake = ctrl.get_throttle_and_brake(False, 10.0, 10.0 - 0.5 / 3.6)
    assert throttle == pytest.approx(0.6478997, abs=1e-6)
    assert not brake


def test_fit_recovers_an_exactly_representable_model():
    # a "vehicle" whose ideal throttle is 0.5·u + 2·(100 w) is fitted exactly by the six features
    def throttle_for(speed: float, accel: float) -> float:
        e_kmh = accel / 2.0 * 3.6  # the fit asks for accel = gain · error [m/s] with gain 2
        return 0.5 * (speed * 3.6 / 100.0) + 0.02 * e_kmh  # 0.5·u + 0.02·(100 w)

    params = fit_linear_regression_params(throttle_for, gain=2.0)
    assert params[0] == pytest.approx(0.5, abs=1e-9)
    assert params[2] == pytest.approx(0.02, abs=1e-9)
    assert np.allclose([params[1], params[3], params[4], params[5]], 0.0, atol=1e-7)
    assert params[6] == pytest.approx(1.031266635497984)


def test_builtin_expert_uses_pdm_lites_published_regression():
    assert ExpertConfig.for_builtin().linear_regression_params == CARLA_LINEAR_REGRESSION_PARAMS
    assert CFG.linear_regression_params == CARLA_LINEAR_REGRESSION_PARAMS


def _track(target_kmh: float, start_kmh: float, seconds: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Speeds (km/h) and brake flags of the ego's car under the builtin expert's controller on a straight road."""
    ctrl = LinearRegressionController(ExpertConfig.for_builtin())
    state = np.zeros((1, len(kb.STATE_COLUMNS)))
    state[0, kb.STATE_COLUMNS.index("speed")] = start_kmh / 3.6
    ego = kb.VehicleArrays.from_rows(state, kb.param_row(blueprints.EGO_DYNAMICS, blueprints.DEFAULT_GEOMETRY)[None])
    speeds, brakes = [], []
    for _ in range(int(seconds * 20)):
        throttle, brake = ctrl.get_throttle_and_brake(False, target_kmh / 3.6, float(ego.speed[0]))
        ego.throttle[:], ego.brake[:] = throttle, float(brake)
        kb.step(ego, CFG.dt)
        speeds.append(float(ego.speed[0]) * 3.6)
        brakes.append(brake)
    return np.array(speeds), np.array(brakes)


@pytest.mark.parametrize("target", [20.0, 30.0, 50.0])
@pytest.mark.parametrize("from_above", [False, True])
def test_published_regression_holds_speed_on_the_egos_carla_law(target, from_above):
    # The ego follows PDM-Lite's CARLA Lincoln polynomials, so PDM-Lite's CARLA-fitted regression should track again:
    # measured, it settles within 0.75 / 1.2 / 2.4 s from rest (0.5 s from 15 km/h above) and then stays within
    # ±0.25 km/h without braking. Bounds: 3 s to settle within 1 km/h, ±0.3 km/h over the last 10 s, no brake there.
    speeds, brakes = _track(target, target + 15.0 if from_above else 0.0)
    error = speeds - target
    settled = next(k for k in range(len(error)) if np.all(np.abs(error[k:]) < 1.0))
    assert settled / 20.0 <= 3.0
    assert np.abs(error[-200:]).max() < 0.3
    assert not brakes[-200:].any()


# ------------------------------------------------------------------------------------------ lateral control
def _ray(angle_deg: float, n: int = 200) -> np.ndarray:
    """Route points 0.1 m apart from the origin along a ray (CARLA frame: positive angles turn right)."""
    a = math.radians(angle_deg)
    s = np.arange(n) * 0.1
    return np.stack([s * math.cos(a), s * math.sin(a), np.zeros(n)], axis=1)


def test_lookahead_index():
    assert lookahead_index(CFG, 0.0, 1000) == 24  # clip(1.915, 24, 105)
    assert lookahead_index(CFG, 10.0, 1000) == 37  # 0.97553·36 + 1.91529 = 37.03
    assert lookahead_index(CFG, 40.0, 1000) == 105
    assert lookahead_index(CFG, 40.0, 50) == 49  # never past the end of the route


def test_lateral_pid_on_known_heading_error():
    ctrl = LateralPIDController(CFG)
    # aim point 9° to the right: e = 9/90 = 0.1; first step: 3.1183572·0.1 + 0 + 0.6406068·0.1 = 0.3758964
    assert ctrl.step(_ray(9.0), 0.0, np.zeros(2), 0.0) == pytest.approx(0.3758964, abs=1e-6)
    # same error again: derivative 0, mean 0.1 → same steer
    assert ctrl.step(_ray(9.0), 0.0, np.zeros(2), 0.0) == pytest.approx(0.3758964, abs=1e-6)
    # e = 0.2: 0.6236714 + 1.3782509·0.1 + 0.6406068·(0.4/3) = 0.6236714 + 0.1378251 + 0.0854142 = 0.8469107
    assert ctrl.step(_ray(18.0), 0.0, np.zeros(2), 0.0) == pytest.approx(0.8469107, abs=1e-6)


def test_lateral_pid_left_is_negative_and_clipped():
    ctrl = LateralPIDController(CFG)
    assert ctrl.step(_ray(-80.0), 0.0, np.zeros(2), 0.0) == -1.0


def test_lateral_pid_state_save_and_load():
    ctrl = LateralPIDController(CFG)
    first = ctrl.step(_ray(9.0), 0.0, np.zeros(2), 0.0)
    ctrl.save_state()
    ctrl.step(_ray(-30.0), 0.0, np.zeros(2), 0.0)
    ctrl.load_state()
    assert ctrl.step(_ray(9.0), 0.0, np.zeros(2), 0.0) == pytest.approx(first)


# ------------------------------------------------------------------------------------- kinematic bicycle
def test_bicycle_step_straight():
    x, y, yaw, v = forecast_ego(CFG, 0.0, 0.0, 0.0, 10.0, 0.0, 0.0, False)
    assert (x, y, yaw, v) == pytest.approx((0.5, 0.0, 0.0, 10.0))


def test_bicycle_step_with_steer():
    # wheel = 0.36848336·0.5 = 0.18424168; tan = 0.186357; β = atan(1.4178275/1.3270585·0.186357) = 0.196542
    # x = 10·cos β·0.05 = 0.490375, y = 10·sin β·0.05 = 0.097634, ψ = 10/1.4178275·sin β·0.05 = 0.068862
    x, y, yaw = (float(a[0]) for a in forecast_other_vehicles(
        CFG, np.zeros(1), np.zeros(1), np.zeros(1), np.array([10.0]), np.array([0.5]), np.zeros(1), np.zeros(1))[:3])
    assert (x, y, yaw) == pytest.approx((0.490375, 0.097634, 0.068862), abs=2e-6)


def test_other_vehicle_speed_update():
    args = (CFG, np.zeros(1), np.zeros(1), np.zeros(1), np.array([10.0]), np.zeros(1), np.array([0.5]))
    # throttle 0.5: 10 + 0.05·0.5·0.5633837 = 10.014085
    assert forecast_other_vehicles(*args, np.zeros(1))[3][0] == pytest.approx(10.014085, abs=1e-6)
    # full brake: 10 − 0.05·4.952399 = 9.752380
    assert forecast_other_vehicles(*args, np.ones(1))[3][0] == pytest.approx(9.752380, abs=1e-6)
    # a partial brake reads as no brake (CARLA's unsigned-int cast)
    assert forecast_other_vehicles(*args, np.array([0.6]))[3][0] == pytest.approx(10.014085, abs=1e-6)


def test_ego_speed_polynomials():
    # small throttles keep the speed
    assert ego_next_speed(CFG, 10.0, 0.2, False) == 10.0
    # brake at 36 km/h: Σ c_k·36^k = 0.335416 + 106.397379 − 132.424857 + 85.087243 − 29.650026 + 5.320476
    # − 0.385067 = 34.680563 km/h
    v = 36.0
    expected = sum(c * v ** (k + 1) for k, c in enumerate(CFG.ego_brake_poly)) / 3.6
    assert ego_next_speed(CFG, 10.0, 0.0, True) == pytest.approx(expected)
    assert expected * 3.6 == pytest.approx(34.6806, abs=1e-3)
    # full throttle at 36 km/h gains 0.89 km/h in one step
    assert ego_next_speed(CFG, 10.0, 1.0, False) * 3.6 == pytest.approx(36.8926, abs=1e-3)
