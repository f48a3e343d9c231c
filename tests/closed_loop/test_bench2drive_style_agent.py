"""An agent written as Bench2DriveZoo's are runs unchanged, and what it perceives matches the truth."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from b2d_data.closed_loop.evaluator import EvalConfig, run_evaluation
from b2d_data.format import leaderboard as lb

from .conftest import B2D_STYLE_AGENT, short_routes

#: GNSS noise the Leaderboard forces: 5e-6 degrees of latitude and longitude, ~0.557 m per axis at the equator.
GNSS_SIGMA_M = 5e-6 * math.pi / 180.0 * 6378137.0
#: The agent's GNSS mount: 1.4 m behind the ego origin.
GNSS_X = -1.4


@pytest.fixture(scope="module")
def b2d_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("b2d_style")
    routes = short_routes(tmp / "routes.xml", ["7"])
    save = tmp / "save"
    save.mkdir()
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("IS_BENCH2DRIVE", "True")
        mp.setenv("SAVE_PATH", str(save))  # Bench2Drive allows sensors up to 100 m away with SAVE_PATH (the bev camera)
        result = run_evaluation(EvalConfig(agent=B2D_STYLE_AGENT, agent_config="cfg.py+model.pth", routes_file=routes,
                                           out=tmp / "out"))  # fmt: skip
    return tmp / "out", save, result


def _metas(folder: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((folder / "meta").glob("*.json"))]


def test_the_route_completes_and_the_record_is_the_leaderboards(b2d_run):
    _, save, result = b2d_run
    (record,) = result.records
    assert record.route_id == "RouteScenario_7_rep0"
    assert record.status == lb.STATUS_COMPLETED
    assert list(record.infractions) == list(lb.INFRACTION_KEYS)
    # the agent got "<config>+<save_name>" and made its folder from the part after the last '+'
    assert (save / record.save_name / "meta").is_dir()


def test_the_agents_metric_info_equals_the_evaluators(b2d_run):
    out, save, result = b2d_run
    save_name = result.records[0].save_name
    ours = json.loads((out / "metric_info" / save_name / "metric_info.json").read_text())
    theirs = json.loads((save / save_name / "metric_info.json").read_text())
    assert len(theirs) > 50
    # get_metric_info reads the hero in the agent's step; the evaluator records it just before that step
    assert theirs == ours


def test_sensor_formats_reach_the_agent_as_carla_delivers_them(b2d_run):
    _, save, result = b2d_run
    metas = _metas(save / result.records[0].save_name)
    first = metas[0]
    assert first["sensors"] == ["CAM_FRONT", "GPS", "IMU", "SPEED", "bev"]
    assert first["image_shape"] == [36, 64, 4] and first["image_dtype"] == "uint8" and first["alpha"] == 255
    assert first["bev_shape"] == [64, 64, 4]
    frames = [m["frame"] for m in metas]
    assert frames == list(range(frames[0], frames[0] + len(frames)))  # one sensor frame per 20 Hz step
    # GameTime: 0.05 s at the first step, then one tick per step
    assert [m["timestamp"] for m in metas[:3]] == pytest.approx([0.05, 0.10, 0.15])


def test_gnss_and_compass_give_the_true_pose(b2d_run):
    _, save, result = b2d_run
    errors = []
    for meta in _metas(save / result.records[0].save_name):
        yaw = math.radians(meta["true_yaw"])
        # the GNSS sits 1.4 m behind the ego origin; the agent converts its fix through the plan's geo-reference
        expected = np.array(meta["true_xy"]) + GNSS_X * np.array([math.cos(yaw), math.sin(yaw)])
        errors.append(float(np.linalg.norm(np.array(meta["gps_xy"]) - expected)))
        # compass − 90° is the yaw (CARLA's compass has no noise)
        assert meta["compass_yaw"] == pytest.approx(meta["true_yaw"], abs=1e-6)
    # two independent N(0, σ) axes: the mean distance is σ·sqrt(π/2) ≈ 0.70 m
    assert np.mean(errors) == pytest.approx(GNSS_SIGMA_M * math.sqrt(math.pi / 2.0), rel=0.25)
    assert max(errors) < 5.0 * GNSS_SIGMA_M


def test_without_save_path_the_bev_camera_is_too_far_and_the_sensors_are_rejected(tmp_path, monkeypatch):
    routes = short_routes(tmp_path / "routes.xml", ["7"])
    monkeypatch.setenv("IS_BENCH2DRIVE", "True")
    monkeypatch.delenv("SAVE_PATH", raising=False)
    result = run_evaluation(EvalConfig(agent=B2D_STYLE_AGENT, routes_file=routes, out=tmp_path / "out"))
    (record,) = result.records
    assert record.status == "Failed - Agent's sensors were invalid"
    assert "Max allowed radius is 3.0m" in record.extra["b2d_eval"]["detail"]
