"""``b2d-eval run`` end to end: route processes, records, statuses, summary, determinism, kill -9 and resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from b2d_data.cli import eval as eval_cli
from b2d_data.closed_loop import REFERENCE_AGENTS
from b2d_data.closed_loop.evaluator import EvalConfig, EvalError, plan_evaluation, run_evaluation, task_seed
from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.scenarios.route_xml import Route, ScenarioConfig, write_routes

from ..conftest import assert_all_exit, descendants, sigint_default
from .conftest import BEHAVIOUR_AGENT, STRAIGHT, short_routes


def _records(out: Path) -> dict[str, dict]:
    return {p.stem: json.loads(p.read_text())["_checkpoint"]["records"][0] for p in (out / "records").glob("*.json")}


def test_the_plan_skips_routes_without_a_map_and_lists_a_task_per_repetition(route_file, tmp_path):
    plan = plan_evaluation(EvalConfig(agent=BEHAVIOUR_AGENT, routes_file=route_file, out=tmp_path / "o",
                                      repetitions=2, seed=7))  # fmt: skip
    assert [t.key for t in plan.tasks] == ["RouteScenario_1_rep0", "RouteScenario_2_rep0", "RouteScenario_1_rep1",
                                          "RouteScenario_2_rep1"]  # fmt: skip
    assert [t.index for t in plan.tasks] == [0, 1, 2, 3]
    assert [(s.route_id, s.town) for s in plan.skipped] == [("999", "Town02")]
    assert "--xodr" in plan.skipped[0].reason
    # each repetition has its own seed, a function of --seed and the route only
    assert plan.tasks[0].seed == task_seed(7, "1", 0) != plan.tasks[2].seed == task_seed(7, "1", 1)


def test_bad_options_name_the_problem(route_file, tmp_path):
    with pytest.raises(EvalError, match="no route with id 42"):
        plan_evaluation(EvalConfig(agent=BEHAVIOUR_AGENT, routes_file=route_file, out=tmp_path, route_ids=("42",)))
    with pytest.raises(EvalError, match="does not exist"):
        plan_evaluation(EvalConfig(agent=tmp_path / "nope.py", routes_file=route_file, out=tmp_path))
    only_missing = short_routes(tmp_path / "m.xml", [], missing_town="Town02")
    with pytest.raises(EvalError, match="none of the 1 selected routes"):
        plan_evaluation(EvalConfig(agent=BEHAVIOUR_AGENT, routes_file=only_missing, out=tmp_path))


@pytest.fixture(scope="module")
def expert_run(tmp_path_factory):
    """The expert agent over two short routes (and one on a town without a map)."""
    tmp = tmp_path_factory.mktemp("expert")
    routes = short_routes(tmp / "routes.xml", ["1", "2"], missing_town="Town02")
    out = tmp / "out"
    result = run_evaluation(EvalConfig(agent=REFERENCE_AGENTS["expert"], routes_file=routes, out=out, workers=2))
    return out, result


def test_the_expert_completes_both_routes_and_the_folder_holds_the_leaderboard_files(expert_run):
    out, result = expert_run
    assert [s.route_id for s in result.plan.skipped] == ["999"]
    records = _records(out)
    assert sorted(records) == ["RouteScenario_1_rep0", "RouteScenario_2_rep0"]
    for key, record in records.items():
        assert record["route_id"] == key
        assert record["status"] == "Completed"  # finished; min-speed messages make it Completed, not Perfect
        assert list(record["infractions"]) == list(lb.INFRACTION_KEYS)
        assert record["scores"]["score_composed"] == 100.0
        assert record["town_name"] == "Town01"
        assert record["save_name"].startswith(f"{key}_Town01_None_1_")
        steps = json.loads((out / "metric_info" / record["save_name"] / "metric_info.json").read_text())
        assert list(steps)[:3] == ["0", "1", "2"]
        assert set(steps["0"]) == {"acceleration", "angular_velocity", "forward_vector", "right_vector", "location",
                                   "rotation"}  # fmt: skip
    checkpoint = json.loads((out / "results.json").read_text())
    assert checkpoint["_checkpoint"]["progress"] == [2, 2]
    assert checkpoint["entry_status"] == "Finished"
    merged = json.loads((out / "merged.json").read_text())
    # two routes of 100 each over the two routes that ran
    assert merged["driving score"] == 100.0 and merged["success rate"] == 1.0 and merged["eval num"] == 2
    assert [r["route_id"] for r in merged["_checkpoint"]["records"]] == ["RouteScenario_2_rep0",
                                                                         "RouteScenario_1_rep0"]  # fmt: skip


def test_summary_reads_an_evaluation_folder(expert_run, tmp_path):
    out, _ = expert_run
    target = tmp_path / "summary.json"
    assert eval_cli.main(["summary", str(out), "--out", str(target)]) == 0
    summary = json.loads(target.read_text())["result_sets"][0]
    assert summary["expected_routes"] == 2 and summary["driving_score"] == 100.0 and summary["success_rate"] == 100.0
    assert summary["smoothness"] is not None and summary["smoothness"]["routes"] == 2  # metric_info was found
    assert summary["efficiency"]["value"] is not None


def test_a_second_run_into_the_folder_needs_resume_and_the_same_settings(expert_run):
    out, _ = expert_run
    routes = out / "routes.xml"
    with pytest.raises(EvalError, match="already holds an evaluation"):
        run_evaluation(EvalConfig(agent=REFERENCE_AGENTS["expert"], routes_file=routes, out=out))
    with pytest.raises(EvalError, match="other settings"):
        run_evaluation(EvalConfig(agent=REFERENCE_AGENTS["expert"], routes_file=routes, out=out, resume=True, seed=3))


#: Per route id: the behaviour agent's options and the status and entry status the Leaderboard gives.
FAILURES = {
    "1": ("raise_at=3", "Failed - Agent crashed", "Finished"),
    "2": ("setup_error", "Failed - Agent couldn't be set up", "Finished"),
    "3": ("sensor=radius", "Failed - Agent's sensors were invalid", "Rejected"),
    "4": ("sensor=duplicate", "Failed - Agent's sensors were invalid", "Rejected"),
    "5": ("sensor=too_many", "Failed - Agent's sensors were invalid", "Rejected"),
    "6": ("sensor=opendrive", "Failed - Agent's sensors were invalid", "Rejected"),
    "7": ("sleep_at=2:30", "Failed - Agent crashed", "Finished"),
    "8": ("segfault_at=2", "Failed - Simulation crashed", "Crashed"),
    "9": ("return_none", "Failed - Agent crashed", "Finished"),
    "10": ("nan_steer", "Failed - Agent crashed", "Finished"),
    "11": ("", "Completed", "Finished"),
}


def test_every_failure_gets_the_leaderboards_status_and_the_evaluation_goes_on(tmp_path):
    routes = short_routes(tmp_path / "routes.xml", list(FAILURES))
    config_string = ";".join(f"{rid}:{opts}" for rid, (opts, _, _) in FAILURES.items())
    started = time.monotonic()
    result = run_evaluation(EvalConfig(agent=BEHAVIOUR_AGENT, agent_config=config_string, routes_file=routes,
                                       out=tmp_path / "out", workers=2, step_timeout=1.0))  # fmt: skip
    # the sleeping agent is abandoned after its 1 s step limit, not waited for (it sleeps 30 s)
    assert time.monotonic() - started < 25
    records = {r.route_number: r for r in result.records}
    for rid, (opts, status, entry) in FAILURES.items():
        assert records[rid].status == status, (opts, records[rid].extra)
        assert lb.entry_status_of([records[rid]]) == entry
    assert "step at tick 3 took longer than 1 s" in records["7"].extra["b2d_eval"]["detail"]
    assert "SIGSEGV" in records["8"].extra["b2d_eval"]["detail"]
    # a crash is logged with its traceback in the route's own log file
    log_text = (tmp_path / "out" / "logs" / "RouteScenario_1_rep0.log").read_text()
    assert "run_step failed on purpose at step 3" in log_text and "Traceback" in log_text
    # the run's checkpoint takes the Leaderboard's entry status of the worst route
    assert json.loads((tmp_path / "out" / "results.json").read_text())["entry_status"] == "Crashed"


def _comparable(record: dict) -> dict:
    """A record without its two wall-clock values (the Leaderboard's duration_system and save_name's time stamp)."""
    record = json.loads(json.dumps(record))
    record["meta"].pop("duration_system")
    record["save_name"] = record["save_name"].rsplit("_", 5)[0]
    return record


def test_the_same_seed_gives_the_same_records(tmp_path, b2d_data_dir):
    # route 24841 (ControlLoss, Town01): a scenario with random steering perturbations and background traffic
    config = {"agent": REFERENCE_AGENTS["expert"], "routes_file": b2d_data_dir / "bench2drive220.xml",
              "route_ids": ("24841",), "seed": 5, "workers": 1}
    first = run_evaluation(EvalConfig(out=tmp_path / "a", **config))
    run_evaluation(EvalConfig(out=tmp_path / "b", **config))
    a = _records(tmp_path / "a")["RouteScenario_24841_rep0"]
    b = _records(tmp_path / "b")["RouteScenario_24841_rep0"]
    assert first.records[0].status.startswith(("Completed", "Perfect"))
    assert json.dumps(_comparable(a)) == json.dumps(_comparable(b))
    assert a["meta"]["duration_game"] > 10.0  # a real drive, not a route that ended at once


def test_kill_9_then_resume_runs_every_route_exactly_once(tmp_path):
    routes = short_routes(tmp_path / "routes.xml", ["1", "2", "3"])
    out = tmp_path / "out"
    # each step sleeps a little so that the run can be killed while route 2 or 3 is still driving
    command = [sys.executable, "-m", "b2d_data.cli.eval", "run", "--agent", str(BEHAVIOUR_AGENT), "--agent-config",
               "1:;2:sleep_at=5:3;3:sleep_at=5:3", "--routes", str(routes), "--out", str(out), "--workers", "1",
               "--no-progress"]  # fmt: skip
    driver = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while not (out / "records" / "RouteScenario_1_rep0.json").is_file() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert (out / "records" / "RouteScenario_1_rep0.json").is_file(), "the first route never finished"
    time.sleep(1.0)  # route 2 is running now
    os.kill(driver.pid, signal.SIGKILL)
    driver.wait(timeout=10)
    killed_at = set(_records(out))
    assert "RouteScenario_3_rep0" not in killed_at
    resumed = subprocess.run([*command, "--resume"], capture_output=True, text=True, timeout=120, check=False)
    assert resumed.returncode == 0, resumed.stderr
    records = _records(out)
    assert sorted(records) == ["RouteScenario_1_rep0", "RouteScenario_2_rep0", "RouteScenario_3_rep0"]
    assert all(r["status"] == "Completed" for r in records.values())
    attempts = [json.loads(line) for line in (out / "run_log.jsonl").read_text().splitlines()]
    finished = [a["route_id"] for a in attempts if a["event"] == "attempt"]
    # route 1 finished before the kill and is not run again; the others finish once, after the resume
    assert sorted(finished) == ["RouteScenario_1_rep0", "RouteScenario_2_rep0", "RouteScenario_3_rep0"]
    assert json.loads((out / "results.json").read_text())["_checkpoint"]["progress"] == [3, 3]


def test_every_sensor_type_reaches_the_agent_in_the_leaderboards_form(tmp_path, monkeypatch):
    routes = short_routes(tmp_path / "routes.xml", ["1"])
    monkeypatch.setenv("SAVE_PATH", str(tmp_path))
    # the agent stops the route at step 4 on purpose: the sensors of four steps are all this test needs
    result = run_evaluation(EvalConfig(agent=BEHAVIOUR_AGENT, agent_config="sensor=full,dump,raise_at=4",
                                       routes_file=routes, out=tmp_path / "out"))  # fmt: skip
    (record,) = result.records
    assert record.status == "Failed - Agent crashed"
    dump = json.loads((tmp_path / f"{record.save_name}_inputs.json").read_text())
    inputs = dump["inputs"]
    assert dump["timestamp"] == pytest.approx(0.2)  # the fourth step: four ticks of 0.05 s
    assert len({entry["frame"] for entry in inputs.values()}) == 1  # every sensor's data is of this tick's frame
    assert inputs["CAM"]["shape"] == [24, 32, 4] and inputs["CAM"]["dtype"] == "uint8"  # BGRA
    lidar_n, lidar_c = inputs["LIDAR"]["shape"]
    # half a turn per tick of 64 channels × round(600000 · 0.05 / 64) = 469 rays, 45 % dropped before casting,
    # the sky above the horizon never hit: between a few thousand points and the 30016 rays
    assert lidar_c == 4 and 3000 < lidar_n < 64 * 469 and inputs["LIDAR"]["dtype"] == "float32"
    assert inputs["RADAR"]["shape"][1] == 4 and inputs["RADAR"]["dtype"] == "float32"
    assert inputs["GPS"]["shape"] == [3] and inputs["GPS"]["dtype"] == "float64"
    assert inputs["IMU"]["shape"] == [7] and inputs["IMU"]["dtype"] == "float64"
    assert inputs["SPEED"]["type"] == "dict" and inputs["SPEED"]["keys"] == ["speed"]


def test_a_route_over_its_tick_limit_ends_as_tick_runtime(tmp_path):
    routes = short_routes(tmp_path / "routes.xml", ["1"])
    # Bench2Drive stops a route after 4000 ticks; a limit of 30 ticks lets a standing agent reach it in 1.5 s of
    # game time, long before the 60 s the blocked test needs
    result = run_evaluation(EvalConfig(agent=BEHAVIOUR_AGENT, agent_config="stand", routes_file=routes,
                                       out=tmp_path / "out", max_ticks=30))  # fmt: skip
    (record,) = result.records
    assert record.status == "Failed - TickRuntime"
    # as Bench2Drive's scenario manager (tick_count > 4000), the tick after the limit ends the route: 31 ticks
    assert record.meta.duration_game == pytest.approx(31 * 0.05)


def test_a_scenario_that_cannot_be_spawned_is_skipped_and_the_route_goes_on(tmp_path):
    # OppositeVehicleRunningRedLight on a 30 m junction-free stretch of Town01: no junction to run the light at. The
    # Leaderboard's build_scenarios skips a scenario it cannot build; the expert then drives the plain route to its end.
    scenario = ScenarioConfig("OppositeVehicleRunningRedLight_1", "OppositeVehicleRunningRedLight",
                              Transform(STRAIGHT[0] + Location(2.0, 0.0, 0.0), Rotation(yaw=0.0)),
                              {"direction": {"value": "right"}})  # fmt: skip
    routes = tmp_path / "routes.xml"
    write_routes([Route(id="1", town="Town01", waypoints=STRAIGHT, scenarios=(scenario,))], routes)
    result = run_evaluation(EvalConfig(agent=REFERENCE_AGENTS["expert"], routes_file=routes, out=tmp_path / "out"))
    (record,) = result.records
    assert record.status == lb.STATUS_COMPLETED
    detail = record.extra["b2d_eval"]["detail"]
    assert "skipped scenario OppositeVehicleRunningRedLight_1" in detail and "enters no junction" in detail


@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_interrupting_ends_quietly_stops_every_route_process_and_keeps_the_log(tmp_path, how):
    routes = short_routes(tmp_path / "routes.xml", ["1", "2"])
    out = tmp_path / "out"
    command = [sys.executable, "-m", "b2d_data.cli.eval", "run", "--agent", str(BEHAVIOUR_AGENT), "--agent-config",
               "sleep_at=3:60", "--routes", str(routes), "--out", str(out), "--workers", "2", "--no-progress"]
    stderr_path = tmp_path / "stderr.txt"
    with open(stderr_path, "wb") as stderr:
        # Ctrl-C reaches the terminal's whole process group; SIGTERM (a batch scheduler) only the driver
        proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=stderr, start_new_session=True,
                                preexec_fn=sigint_default)  # noqa: PLW1509 - the child starts no thread before exec
        helpers: set[int] = set()
        try:
            deadline = time.monotonic() + 60
            # both routes are inside their agents' 60 s sleep once both logs say the agent's sensors are mounted
            while time.monotonic() < deadline and proc.poll() is None:
                helpers |= descendants(proc.pid)
                logs = list((out / "logs").glob("*.log")) if (out / "logs").is_dir() else []
                if len(logs) == 2 and all("agent sensors" in p.read_text() for p in logs):
                    break
                time.sleep(0.1)
            time.sleep(0.5)
            helpers |= descendants(proc.pid)
            assert proc.poll() is None, "the evaluation ended before it could be interrupted"
            if how == "ctrl-c":
                os.killpg(proc.pid, signal.SIGINT)
            else:
                os.kill(proc.pid, signal.SIGTERM)
            assert proc.wait(timeout=30) == 130
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    err = stderr_path.read_text()
    assert "Traceback" not in err, err
    assert "interrupted: 0 of 2 routes have their record" in err and "--resume" in err
    assert_all_exit(helpers)
    events = [json.loads(line) for line in (out / "run_log.jsonl").read_text().splitlines()]
    assert sorted(e["route_id"] for e in events if e["event"] == "interrupted") == ["RouteScenario_1_rep0",
                                                                                    "RouteScenario_2_rep0"]
    assert not (out / "records").exists() or not list((out / "records").glob("*.json"))


def test_repetitions_are_separate_runs_with_their_own_records(tmp_path):
    routes = short_routes(tmp_path / "routes.xml", ["1"])
    out = tmp_path / "out"
    result = run_evaluation(EvalConfig(agent=BEHAVIOUR_AGENT, routes_file=routes, out=out, repetitions=2, workers=2))
    assert sorted(r.route_id for r in result.records) == ["RouteScenario_1_rep0", "RouteScenario_1_rep1"]
    target = tmp_path / "summary.json"
    assert eval_cli.main(["summary", str(out), "--out", str(target)]) == 0
    summary = json.loads(target.read_text())["result_sets"][0]
    # one route × two repetitions: two records over two expected runs, neither dropped as a duplicate
    assert summary["records"] == 2 and summary["expected_routes"] == 2 and summary["duplicates"] == []
