"""Driving score, success rate and efficiency: the real VAD result and the synthetic run."""

from __future__ import annotations

import pytest

from b2d_data.eval.driving_score import driving_scores
from b2d_data.eval.efficiency import driving_efficiency, route_efficiency
from b2d_data.eval.results import load_result_set
from b2d_data.format import leaderboard as lb


def test_vad_reproduces_bench2drive(b2d_data_dir):
    records = lb.read_results(b2d_data_dir / "VAD_merged_results.json").records
    scores = driving_scores(records, 220)
    # Bench2Drive's published VAD row: DS 42.35, SR 15.00, efficiency 157.94 (tools print more digits).
    assert scores.num_records == 213 and scores.missing == 7
    assert round(scores.driving_score, 2) == 42.35
    assert round(scores.success_rate, 2) == 15.00 and scores.num_success == 33
    efficiency = driving_efficiency(records)
    assert efficiency.value == pytest.approx(157.9, abs=0.05)
    assert efficiency.routes == 197  # the 16 routes without any min-speed message are left out


def test_synthetic_scores_by_hand(synthetic_run):
    records = load_result_set(synthetic_run.files, "s").records
    scores = driving_scores(records, 8)
    # score_composed: 101 100, 102 100, 103 60, 104 20, 105 100 × 0.7 = 70, 106 100, 108 50 → 500 / 8 routes.
    assert scores.driving_score == pytest.approx(62.5)
    # Successes 101, 102, 106 (min-speed messages do not count); 105 is Completed but ran a red light.
    assert scores.num_success == 3 and scores.success_rate == pytest.approx(37.5)
    # score_route: 100 + 100 + 60 + 20 + 100 + 100 + 50 = 530 → 66.25; penalties 6 × 1 + 0.7 = 6.7 → 83.75 %.
    assert scores.route_completion == pytest.approx(66.25)
    assert scores.infraction_penalty == pytest.approx(83.75)


def test_synthetic_efficiency_by_hand(synthetic_run):
    records = synthetic_run.records
    # 101: (80 + 120) / 2 = 100; 102: 1500 % is an outlier, leaving 50; 106: the int-valued "100%" message.
    assert route_efficiency(records["101"]) == 100.0
    assert route_efficiency(records["102"]) == 50.0
    assert route_efficiency(records["106"]) == 100.0
    assert route_efficiency(records["104"]) is None
    efficiency = driving_efficiency(list(records.values()))
    assert efficiency.routes == 3 and efficiency.value == pytest.approx(250 / 3)


def test_route_with_only_outliers_is_reported_not_divided_by_zero():
    record = lb.RouteRecord(route_id="RouteScenario_1_rep0")
    record.add_infraction(lb.MIN_SPEED_INFRACTIONS, lb.min_speed_message(3306.64))
    efficiency = driving_efficiency([record])
    assert efficiency.value is None and efficiency.all_outliers == ("RouteScenario_1_rep0",)


def test_num_routes_must_be_positive():
    with pytest.raises(ValueError, match="at least 1"):
        driving_scores([], 0)
