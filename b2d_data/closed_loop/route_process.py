"""One route of ``b2d-eval run``, in a process of its own.

:func:`route_main` is the process's entry: it sends the process's output to the route's log file, puts the stand-in
``carla`` / ``leaderboard`` / ``srunner`` / ``agents`` modules first on ``sys.path``, runs :func:`run_route` and
reports the outcome to the evaluator. :func:`run_route` runs the route on the builtin simulator with the route
runner that collection uses too, the agent wrapped by :class:`~b2d_data.closed_loop.leaderboard_agent.LeaderboardAgent`,
and writes the route's files. What a finished route leaves, in this order (the record last: it is the mark of a
finished route that ``--resume`` trusts):

- ``<out>/metric_info/<save_name>/metric_info.json``: the hero's motion per step (Bench2Drive's comfort input);
- ``<out>/records/RouteScenario_<id>_rep<k>.json``: a one-route Leaderboard checkpoint file.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from b2d_data.closed_loop import SHIM_DIR
from b2d_data.closed_loop.leaderboard_agent import AgentSettings, LeaderboardAgent
from b2d_data.collection.progress import FrameReporter, set_frame_sink
from b2d_data.collection.towns import TownSource, load_map
from b2d_data.format import leaderboard as lb
from b2d_data.scenarios import statistics
from b2d_data.scenarios.criteria import CriteriaResult
from b2d_data.scenarios.route_runner import MAX_TICKS, RouteRunner
from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

RECORDS_DIR = "records"
METRIC_DIR = "metric_info"
LOGS_DIR = "logs"
METRIC_FILE = "metric_info.json"
#: The ``extra`` key of the records ``b2d-eval run`` writes (seed and why the route failed, if it did).
EVAL_EXTRA = "b2d_eval"


@dataclass(frozen=True)
class RouteSettings:
    """What every route of one evaluation shares."""

    out: Path
    agent: AgentSettings
    routes_file: Path
    max_ticks: int = MAX_TICKS
    #: The evaluator's environment when the evaluation started: route processes start from a fork server that
    #: captured the environment of its own start, and agents read theirs (SAVE_PATH, IS_BENCH2DRIVE, ...).
    environ: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class RouteTask:
    """One route repetition to run: the route, its (file-backed) town, its position and its seed."""

    route: Route
    town: TownSource
    repetition: int
    index: int
    seed: int

    @property
    def key(self) -> str:
        """``RouteScenario_<id>_rep<k>``: the record's route id and the name of the route's files."""
        return lb.record_route_id(self.route.id, self.repetition)


@dataclass
class RouteOutcome:
    """What a route process reports besides its record: how long the parts took and why it ended."""

    key: str
    status: str = ""
    score_composed: float = 0.0
    score_route: float = 0.0
    ticks: int = 0
    duration_game: float = 0.0
    wall: float = 0.0
    detail: str = ""
    timings: dict[str, float] = field(default_factory=dict)


def record_path(out: Path, key: str) -> Path:
    """Where the record of route ``key`` goes."""
    return out / RECORDS_DIR / f"{key}.json"


def log_path(out: Path, key: str) -> Path:
    """Where the output of route ``key``'s process goes."""
    return out / LOGS_DIR / f"{key}.log"


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        temp.write_text(text, encoding="utf-8")
        os.replace(temp, path)
    finally:
        temp.unlink(missing_ok=True)


def write_record(out: Path, key: str, record: lb.RouteRecord) -> Path:
    """The route's one-record Leaderboard checkpoint file (written atomically)."""
    results = statistics.checkpoint_results([record], total_routes=1)
    path = record_path(out, key)
    _write_atomic(path, json.dumps(results.to_dict(), indent=4))
    return path


def crash_record(task: RouteTask, message: str, detail: str = "") -> lb.RouteRecord:
    """The record of a route whose process could not run it (the Leaderboard's ``Failed - <message>``)."""
    record = statistics.route_record(
        task.route, CriteriaResult(0.0, ()), 0.0, 0.0, 0.0, failure_message=message, index=task.index,
        repetition=task.repetition, town_name=task.town.name,
    )  # fmt: skip
    record.extra[EVAL_EXTRA] = {"seed": task.seed, "detail": detail}
    return record


def run_route(task: RouteTask, settings: RouteSettings) -> RouteOutcome:
    """Run one route with the agent and write its metric info and record; returns how it went."""
    from b2d_data.scenarios.junction_signals import with_scenario_lights
    from b2d_data.scenarios.route import DenseRoute
    from b2d_data.sim.builtin.world import BuiltinSimulator

    t0 = time.monotonic()
    outcome = RouteOutcome(task.key)
    route = task.route
    # CARLA's level has lights at some junctions its OpenDRIVE file leaves without (Town04, route 26944)
    world_map = with_scenario_lights(load_map(task.town), route)
    sim = BuiltinSimulator(world_map, seed=task.seed, weather=route.weather_at(0.0))
    agent: LeaderboardAgent | None = None
    try:
        dense = DenseRoute.from_route(world_map, route)
        save_name = lb.make_save_name(task.key, world_map.name, str(statistics.scenario_name_of(route)),
                                      statistics.weather_id_of_route(route), datetime.now())  # fmt: skip
        agent = LeaderboardAgent(settings.agent, sim, save_name, route=dense)
        reporter = FrameReporter(task.key, save_name)

        def on_tick(snapshot: Any, info: Any) -> None:
            reporter(info.tick, info.score_route)

        runner = RouteRunner(
            sim, route, agent, seed=task.seed, record_every=1, on_frame=on_tick, on_start=agent.start,
            dense_route=dense, index=task.index, repetition=task.repetition, max_ticks=settings.max_ticks,
            skip_failed_scenarios=True,  # the Leaderboard drives a route on without a scenario it cannot spawn
        )  # fmt: skip
        result = runner.run()
        record = result.record
        record.save_name = save_name
        record.town_name = world_map.name
        outcome.detail = "; ".join([result.detail] * bool(result.detail)
                                   + [f"skipped scenario {name}: {why}" for name, why in result.skipped_scenarios])
        outcome.ticks = result.ticks
        timings = agent.timings
        outcome.timings = {"setup": round(timings.setup, 3), "warmup": round(timings.warmup, 3),
                           "agent": round(timings.steps, 3), "sensors": round(timings.sensors, 3)}  # fmt: skip
    except Exception as exc:
        log.exception("route %s: the simulation failed", task.key)
        outcome.detail = f"{type(exc).__name__}: {exc}"
        record = crash_record(task, statistics.SIMULATION_CRASHED_FAILURE, outcome.detail)
        save_name = None
    finally:
        if agent is not None:
            agent.close()
        sim.close()
    record.extra[EVAL_EXTRA] = {"seed": task.seed, "detail": outcome.detail}
    if agent is not None and agent.metric_info and save_name is not None:
        steps = {str(k): v for k, v in sorted(agent.metric_info.items())}
        _write_atomic(settings.out / METRIC_DIR / save_name / METRIC_FILE, json.dumps(steps))
    write_record(settings.out, task.key, record)
    outcome.status = record.status
    outcome.score_composed = float(record.scores.score_composed)
    outcome.score_route = float(record.scores.score_route)
    outcome.duration_game = float(record.meta.duration_game)
    outcome.wall = round(time.monotonic() - t0, 3)
    if agent is not None and agent.stuck:
        outcome.timings["stuck"] = 1.0
    return outcome


def _redirect_output(path: Path) -> None:
    """Send this process's stdout and stderr (Python's and the C libraries') to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    sys.stdout.flush()
    sys.stderr.flush()
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    sys.stdout = open(1, "w", buffering=1, encoding="utf-8", errors="replace", closefd=False)  # noqa: SIM115
    sys.stderr = open(2, "w", buffering=1, encoding="utf-8", errors="replace", closefd=False)  # noqa: SIM115


def _leave(signum: int, frame: object) -> None:
    """SIGTERM from the evaluator (it was interrupted): unwind and exit, no record."""
    raise SystemExit(143)


def route_main(task: RouteTask, settings: RouteSettings, reports: Any, parent_pid: int, log_level: int) -> None:
    """Entry of a route process: isolate, run the route, report its outcome on ``reports``, exit."""
    from b2d_data.collection.job import exit_with_parent, ignore_interrupts

    exit_with_parent(parent_pid)
    ignore_interrupts()  # Ctrl-C goes to the evaluator, which stops the routes
    signal.signal(signal.SIGTERM, _leave)
    _redirect_output(log_path(settings.out, task.key))
    # The route's log file is what a user reads when a route fails: it always holds the INFO lines.
    logging.basicConfig(level=min(log_level, logging.INFO), format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        force=True)  # fmt: skip
    # The agent imports carla, leaderboard, srunner and agents: here they are the builtin simulator's stand-ins.
    sys.path.insert(0, str(SHIM_DIR))
    if settings.environ:
        os.environ.clear()
        os.environ.update(dict(settings.environ))
    # What Bench2Drive's run_evaluation.sh exports for its agents (values the user set are kept).
    os.environ.setdefault("ROUTES", str(settings.routes_file))
    os.environ.setdefault("CHALLENGE_TRACK_CODENAME", settings.agent.track)
    set_frame_sink(reports.put_nowait)
    log.info("route %s (seed %d) on %s with agent %s", task.key, task.seed, task.town.name, settings.agent.path)
    outcome = run_route(task, settings)
    log.info("route %s: %s, driving score %.3f after %d ticks", task.key, outcome.status, outcome.score_composed,
             outcome.ticks)  # fmt: skip
    reports.put(("done", outcome))
    reports.close()
    reports.join_thread()  # the outcome reaches the evaluator before this process ends
    if outcome.timings.get("stuck"):
        # The agent thread is still inside a call that timed out: nothing can stop it, so leave without it.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
