"""Smoothness: Bench2Drive's quirky computation and the corrected-units option, on hand-made motions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.eval.smoothness import (
    MotionSeries,
    comfort_checks,
    driving_smoothness,
    phase_unwrap,
    read_metric_info,
    route_smoothness,
)
from b2d_data.format.errors import B2DFormatError


def _series(accs, yaw_rates_deg):
    n = len(accs)
    acc = np.zeros((n, 3))
    acc[:, 0] = accs
    ang = np.zeros((n, 3))
    ang[:, 2] = yaw_rates_deg
    return MotionSeries(acc, ang, np.tile([1.0, 0.0, 0.0], (n, 1)), np.tile([0.0, 1.0, 0.0], (n, 1)))


# Savitzky–Golay with polynomial order 2 reproduces constants and straight lines exactly, so each chunk's
# smoothed values and derivatives can be read off by hand (forward = +x, right = +y, lat acceleration 0).


def test_calm_and_hard_acceleration_chunks():
    assert all(comfort_checks(_series([1.0] * 20, [0.0] * 20)).values())
    checks = comfort_checks(_series([3.0] * 20, [0.0] * 20))
    assert checks["lon_accel"] is False  # 3.0 m/s² is above the 2.40 bound
    assert all(v for k, v in checks.items() if k != "lon_accel")


def test_ramp_passes_with_bench2drive_dt_and_fails_with_the_real_one():
    ramp = _series([-4.0 + 0.21 * k for k in range(20)], [0.0] * 20)
    # lon acceleration rises 0.21 m/s² per step: jerk 0.21 / 0.1 = 2.1 m/s³ with Bench2Drive's Δt (< 4.13),
    # 0.21 / 0.05 = 4.2 m/s³ with the real 20 Hz step (> 4.13).
    assert all(comfort_checks(ramp).values())
    corrected = comfort_checks(ramp, corrected=True)
    assert corrected["lon_jerk"] is False and corrected["jerk"] is True  # |jerk| 4.2 < 8.37


def test_turn_rate_units():
    # 30 deg/s: Bench2Drive compares 30 with the 0.95 rad/s bound (fails); in rad/s it is 0.524 (passes).
    turn = _series([0.5] * 15, [30.0] * 15)
    assert comfort_checks(turn)["yaw_rate"] is False and comfort_checks(turn)["yaw_accel"] is False
    assert all(comfort_checks(turn, corrected=True).values())


def test_phase_unwrap_of_deg_values():
    # A jump of 7 > π is shifted by one 2π turn: 7 − 2π = 0.7168.
    assert phase_unwrap(np.array([0.0, 7.0])) == pytest.approx([0.0, 7.0 - 2 * math.pi])


def test_chunks_drop_the_incomplete_tail():
    route = _series([1.0] * 20 + [3.0] * 20 + [50.0] * 5, [0.0] * 40 + [500.0] * 5)
    result = route_smoothness(route)
    assert (result.chunks, result.passed) == (2, 1)  # the 5 wild steps at the end are never checked
    assert route_smoothness(_series([1.0, 1.0], [0.0, 0.0])) is None  # too short to smooth


def test_synthetic_run_smoothness(synthetic_run):
    records = list(synthetic_run.records.values())
    b2d = driving_smoothness(records, synthetic_run.metric_dir)
    # Route 101: calm chunk passes, 3 m/s² chunk fails → 0.5. Route 102: the ramp and the 0.5 deg/s turn both
    # pass → 1.0. Route 106 (15 steps, one chunk): 30 deg/s fails → 0. Mean (0.5 + 1 + 0) / 3 = 50 %.
    assert b2d.per_route == {
        "RouteScenario_101_rep0": 0.5,
        "RouteScenario_102_rep0": 1.0,
        "RouteScenario_106_rep0": 0.0,
    }
    assert b2d.value == pytest.approx(50.0) and b2d.mode == "bench2drive" and b2d.time_step == 0.1
    assert len(b2d.missing_files) == 4  # 103, 104, 105, 108 have no metric_info.json
    corrected = driving_smoothness(records, synthetic_run.metric_dir, corrected=True)
    # Corrected: 101 still 0.5; 102's ramp now fails (4.2 m/s³) → 0.5; 106's 0.524 rad/s passes → 1.
    assert corrected.value == pytest.approx(100 * (0.5 + 0.5 + 1.0) / 3) and corrected.time_step == 0.05


def test_malformed_metric_file_is_named(tmp_path):
    path = tmp_path / "metric_info.json"
    path.write_text('{"0": {"acceleration": [0, 0, 0]}}')
    with pytest.raises(B2DFormatError, match="metric_info.json: step 0: 'angular_velocity'"):
        read_metric_info(path)


def test_save_name_climbing_out_of_the_metric_dir_is_not_read(tmp_path):
    from b2d_data.format.leaderboard import RouteRecord

    from .conftest import write_metric_info

    metric_dir = tmp_path / "metric"
    metric_dir.mkdir()
    # A calm run (0 m/s² and 0 °/s for 40 steps passes every comfort check → smoothness 1) placed one level above
    # metric_dir, where save_name "../outside" points.
    write_metric_info(tmp_path / "outside" / "metric_info.json", [(0.0, 0.0)] * 40)
    result = driving_smoothness([RouteRecord("RouteScenario_1_rep0", save_name="../outside")], metric_dir)
    assert result.per_route == {} and result.value is None
    assert result.missing_files == (
        f"{metric_dir}/'../outside' (route RouteScenario_1_rep0: save_name is not a plain name)",
    )
