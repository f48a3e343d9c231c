"""``b2d-eval summary OUT/results`` on a b2d-collect collection scores it over the collection's routes, not 220."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from b2d_data.cli.eval import main
from b2d_data.collection import run_log as rl
from b2d_data.collection.job import write_route_results
from b2d_data.format import leaderboard as lb

#: route id → (status, score_route, penalty, collided): two perfect routes and one blocked after 80 % with a crash.
ROUTES = {1: ("Perfect", 100.0, 1.0, False), 2: ("Perfect", 100.0, 1.0, False),
          3: ("Failed - Agent got blocked", 80.0, 0.5, True)}  # fmt: skip


@pytest.fixture
def tiny_collection(tmp_path) -> Path:
    """A b2d-collect corpus: the three routes above finished, a fourth was interrupted (no record, not counted)."""
    out = tmp_path / "data"
    log = rl.RunLog(out / rl.LOG_FILE)
    for route_id, (status, score_route, penalty, collided) in ROUTES.items():
        clip = f"Accident_Town100_Route{route_id}_Weather3"
        record = lb.RouteRecord(route_id=lb.record_route_id(route_id), status=status, town_name="Town100", index=0,
                                scores=lb.Scores.compose(score_route, penalty))  # fmt: skip
        if collided:
            record.add_infraction(lb.COLLISIONS_VEHICLE, "Agent collided against object with type=vehicle.tesla")
        record.extra["b2d_collect"] = {"seed": route_id, "clip": clip, "success": record.success}
        log.append({"event": "start", "route_id": str(route_id)})
        write_route_results(out, clip, record)
        log.append({"event": "attempt", "route_id": str(route_id), "status": "clip" if record.success else "failed"})
    log.append({"event": "start", "route_id": "4"})
    log.append({"event": "interrupted", "route_id": "4"})
    return out


def _summary(args: list[str], tmp_path: Path, capsys) -> tuple[dict, str]:
    out = tmp_path / "summary.json"
    assert main(["summary", *args, "--out", str(out)]) == 0
    return json.loads(out.read_text())["result_sets"][0], capsys.readouterr().out


def test_a_collection_is_scored_over_its_own_routes(tiny_collection, tmp_path, capsys):
    data, printed = _summary([str(tiny_collection / "results")], tmp_path, capsys)
    # By hand: DS = (100 + 100 + 80 x 0.5) / 3 = 80; SR = 2 / 3; completion = (100 + 100 + 80) / 3.
    assert data["expected_routes"] == 3 and data["records"] == 3
    assert data["driving_score"] == pytest.approx(80.0)
    assert data["success_rate"] == pytest.approx(200 / 3)
    assert data["route_completion"] == pytest.approx(280 / 3)
    assert "Driving score" in printed and "80.00" in printed and "66.67" in printed
    reason = f"b2d-collect collection {tiny_collection.resolve()}: 3 route(s) with a finished attempt in run_log.jsonl"
    assert data["expected_routes_reason"] == reason
    assert f"[results] 3: {reason}" in printed
    assert "missing route(s) count 0" not in printed


def test_collection_records_without_their_run_log_count_one_route_each(tiny_collection, tmp_path, capsys):
    copy = tmp_path / "copied"
    shutil.copytree(tiny_collection / "results", copy)
    data, printed = _summary([str(copy)], tmp_path, capsys)
    assert data["expected_routes"] == 3 and data["driving_score"] == pytest.approx(80.0)
    assert "b2d-collect records without their run_log.jsonl: one route per record" in printed


def test_num_routes_still_overrides_the_collection(tiny_collection, tmp_path, capsys):
    data, printed = _summary([str(tiny_collection / "results"), "--num-routes", "10"], tmp_path, capsys)
    # 240 points over 10 routes; the 7 routes without a record count 0.
    assert data["expected_routes"] == 10 and data["driving_score"] == pytest.approx(24.0)
    assert "[results] 10: --num-routes" in printed and "7 missing route(s) count 0" in printed


def test_a_crashed_jobs_record_still_counts_in_its_collection(tiny_collection, tmp_path, capsys):
    """The record of a job that crashed carries no b2d_collect key; the collection is found from its folder."""
    crashed = lb.RouteRecord(route_id=lb.record_route_id(5), status="Failed - Simulation crashed", index=0)
    write_route_results(tiny_collection, "Accident_Town100_Route5_Weather3", crashed)
    rl.RunLog(tiny_collection / rl.LOG_FILE).append({"event": "attempt", "route_id": "5", "status": "error"})
    data, printed = _summary([str(tiny_collection / "results")], tmp_path, capsys)
    # By hand: (100 + 100 + 40 + 0) / 4 routes.
    assert data["expected_routes"] == 4 and data["driving_score"] == pytest.approx(60.0)
    assert data["success_rate"] == pytest.approx(50.0)
    assert "4 route(s) with a finished attempt" in printed


def _write_planned_routes(collection: Path, n: int) -> Path:
    """routes/Accident.xml as b2d-collect writes it: every planned attempt (ids 1..n), run or not."""
    from b2d_data.format.transform import Location, Rotation, Transform
    from b2d_data.scenarios.route_xml import Route, ScenarioConfig, write_routes

    trigger = Transform(Location(0.0, 0.0, 0.0), Rotation())
    routes = [
        Route(str(i), "Town100", (Location(0.0, 0.0, 0.0),), (ScenarioConfig(f"Accident_{i}", "Accident", trigger),))
        for i in range(1, n + 1)
    ]
    path = collection / "routes" / "Accident.xml"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_routes(routes, path)
    return path


def test_the_collection_route_file_does_not_change_the_count(tiny_collection, tmp_path, capsys):
    # --n 2 with 3 attempts per clip plans 6 routes; 3 ran (routes 1-3), one was interrupted, two never started.
    planned = _write_planned_routes(tiny_collection, 6)
    data, printed = _summary([str(tiny_collection / "results"), "--routes", str(planned)], tmp_path, capsys)
    # Still DS (100 + 100 + 40) / 3 = 80 and SR 2 / 3 (the old count was the file's 6 routes: DS 40, SR 33.3).
    assert data["expected_routes"] == 3 and data["driving_score"] == pytest.approx(80.0)
    assert data["success_rate"] == pytest.approx(200 / 3)
    assert data["expected_routes_reason"].endswith(
        f"3 route(s) with a finished attempt in run_log.jsonl (not the 6 route(s) of {planned}: a collection's route "
        "file lists every planned attempt)"
    )
    # The planned routes that never ran are neither missing nor crashed.
    assert data["missing_routes"] == [] and data["abilities"]["crashed"] == []
    assert "missing route(s) count 0" not in printed


def test_the_abilities_hint_of_a_collection_names_its_route_file(tiny_collection, tmp_path, capsys):
    planned = _write_planned_routes(tiny_collection, 6)
    _, printed = _summary([str(tiny_collection / "results")], tmp_path, capsys)
    assert (
        f"No abilities (and no bar chart): add --routes {planned} for them (the driving score stays over the routes "
        "the collection ran)"
    ) in printed


def test_the_summary_goes_beside_the_results_not_into_the_current_folder(tiny_collection, tmp_path, monkeypatch):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["summary", str(tiny_collection / "results")]) == 0
    # OUT/results → OUT/results_summary.json (not into results/, which holds one record file per route).
    data = json.loads((tiny_collection / "results_summary.json").read_text())
    assert data["result_sets"][0]["driving_score"] == pytest.approx(80.0)
    # A result file → <stem>_summary.json beside it; with routes the chart goes beside the JSON.
    planned = _write_planned_routes(tiny_collection, 3)
    record = tmp_path / "runs" / "eval_0.json"
    record.parent.mkdir()
    shutil.copy(tiny_collection / "results" / "Accident_Town100_Route1_Weather3.json", record)
    assert main(["summary", str(record), "--routes", str(planned), "--num-routes", "1"]) == 0
    assert sorted(p.name for p in record.parent.iterdir()) == [
        "eval_0.json", "eval_0_summary.json", "eval_0_summary_abilities.png"]  # fmt: skip
    assert list(elsewhere.iterdir()) == []


def test_a_shipped_file_by_name_is_summarised_into_the_current_folder(tmp_path, monkeypatch):
    from b2d_data import data

    monkeypatch.chdir(tmp_path)
    shipped = sorted(p.name for p in data.bench2drive_dir().iterdir())
    assert main(["summary", "VAD_merged_results.json"]) == 0
    # Not into the installed package's data folder, which it would be "beside".
    assert sorted(p.name for p in data.bench2drive_dir().iterdir()) == shipped
    assert [p.name for p in tmp_path.iterdir()] == ["VAD_merged_results_summary.json"]
