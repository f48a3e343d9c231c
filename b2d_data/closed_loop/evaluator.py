"""``b2d-eval run``: a Leaderboard agent over the routes of a route file, each route in a process of its own.

:func:`plan_evaluation` selects the routes (``--route-id``), finds each route's town (shipped CARLA towns, generated
towns, ``--xodr`` files or folders; routes on other towns are skipped with the reason) and lists one task per route
and repetition. :func:`run_evaluation` runs the tasks on ``workers`` processes at a time
(:func:`~b2d_data.closed_loop.route_process.route_main`), keeps going past any route that fails, and writes what
Bench2Drive's evaluator and tools write, in the output folder:

- ``records/RouteScenario_<id>_rep<k>.json``: one Leaderboard checkpoint file per route (the record is the mark of a
  finished route: ``--resume`` runs every route without one, and the routes whose process died);
- ``metric_info/<save_name>/metric_info.json``: the hero's motion per step (Bench2Drive's comfort metric input);
- ``results.json``: the Leaderboard checkpoint of the whole run (every record, ``global_record``, ``progress``,
  ``entry_status``, ``values``, ``labels``) and ``merged.json`` as ``tools/merge_route_json.py`` writes it;
- ``eval.json`` (the settings a resume must share), ``routes.xml`` (the routes that run), ``run_log.jsonl``,
  ``logs/<route>.log`` (each route process's output: the agent's prints land there).

``b2d-eval summary <out>`` reads the folder (records, routes.xml, metric_info) and gives every Bench2Drive figure.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import signal
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from b2d_data.closed_loop.leaderboard_agent import AgentSettings
from b2d_data.closed_loop.route_process import (
    EVAL_EXTRA,
    RECORDS_DIR,
    RouteOutcome,
    RouteSettings,
    RouteTask,
    crash_record,
    log_path,
    record_path,
    route_main,
    write_record,
)
from b2d_data.collection import run_log as rl
from b2d_data.collection.corpus import corpus_lock
from b2d_data.collection.layout import worker_context
from b2d_data.collection.plan import route_seed
from b2d_data.collection.progress import FrameReport, ProgressState
from b2d_data.collection.towns import TownError, TownSource, route_town
from b2d_data.data import shipped_or_given
from b2d_data.format import leaderboard as lb
from b2d_data.format.errors import B2DFormatError
from b2d_data.scenarios import statistics
from b2d_data.scenarios.route_runner import MAX_TICKS
from b2d_data.scenarios.route_xml import Route, read_route_argument, write_routes

#: What an evaluation's fork server imports once for all its route processes.
EVAL_PRELOAD = ("b2d_data.closed_loop.route_process", "b2d_data.sim.builtin.world")

log = logging.getLogger(__name__)

SETTINGS_FILE = "eval.json"
ROUTES_FILE = "routes.xml"
RESULTS_FILE = "results.json"
MERGED_FILE = "merged.json"
LOCK_FILE = ".b2d_eval.lock"
#: What ``eval.json`` says it is (``b2d-eval summary`` recognises an evaluation folder by it).
SETTINGS_FORMAT = "b2d-eval-run"
#: Settings a ``--resume`` must share with the run it continues.
FIXED_SETTINGS = ("agent", "agent_config", "routes_file", "xodr", "repetitions", "seed", "route_ids", "track",
                  "max_ticks")  # fmt: skip
#: Seconds an interrupted evaluation gives its route processes to stop before killing them.
STOP_GRACE = 10.0


class EvalError(Exception):
    """A problem the user can act on (bad option, unreadable route file, no route that can run, busy folder)."""


class EvalInterrupted(Exception):
    """Ctrl-C or SIGTERM stopped the evaluation; the finished routes are kept for ``--resume``."""


@dataclass(frozen=True)
class EvalConfig:
    """The options of ``b2d-eval run``."""

    agent: Path
    routes_file: Path
    out: Path
    agent_config: str = ""
    xodr: Path | None = None
    workers: int = 1
    resume: bool = False
    repetitions: int = 1
    seed: int = 0
    route_ids: tuple[str, ...] = ()
    track: str = "SENSORS"
    step_timeout: float = 600.0
    setup_timeout: float = 600.0
    max_ticks: int = MAX_TICKS

    def settings(self) -> dict[str, Any]:
        """The JSON form of the settings that fix the results (``eval.json``)."""
        values = asdict(self)
        out: dict[str, Any] = {"format": SETTINGS_FORMAT}
        for key in FIXED_SETTINGS:
            value = values[key]
            if isinstance(value, Path):
                value = str(value.resolve())
            elif isinstance(value, tuple):
                value = list(value)
            out[key] = value
        return out


@dataclass(frozen=True)
class SkippedRoute:
    """A route of the file that does not run, and why."""

    route_id: str
    town: str
    reason: str


@dataclass
class EvalPlan:
    """The routes that run (with their towns), one task per route and repetition, and the routes skipped."""

    routes: list[Route]
    tasks: list[RouteTask]
    skipped: list[SkippedRoute] = field(default_factory=list)


@dataclass
class EvalResult:
    """What :func:`run_evaluation` did: every task's record, this session's outcomes, the files it wrote."""

    out: Path
    plan: EvalPlan
    records: list[lb.RouteRecord]
    outcomes: dict[str, RouteOutcome]
    resumed: int = 0
    wall_seconds: float = 0.0

    @property
    def total(self) -> int:
        """Routes × repetitions that the driving score is averaged over."""
        return len(self.plan.tasks)


@dataclass
class EvalProgress:
    """A snapshot for the progress display: routes done of all, the running ones, the time left."""

    done: int
    total: int
    running: tuple[Any, ...]
    elapsed: float
    eta: float | None
    failed: int


def _read_route_file(path: Path) -> list[Route]:
    try:
        return read_route_argument(path)
    except B2DFormatError as exc:
        raise EvalError(f"cannot read route file: {exc}") from None


def _check_config(config: EvalConfig) -> None:
    if not config.agent.is_file():
        raise EvalError(f"agent file {config.agent} does not exist")
    if config.agent.suffix != ".py":
        raise EvalError(f"agent file {config.agent} is not a Python file (.py)")
    if config.repetitions < 1:
        raise EvalError(f"--repetitions must be at least 1, got {config.repetitions}")
    if config.workers < 1:
        raise EvalError(f"--workers must be at least 1, got {config.workers}")
    if config.track not in ("SENSORS", "MAP", "SENSORS_QUALIFIER", "MAP_QUALIFIER"):
        raise EvalError(f"--track must be SENSORS, MAP, SENSORS_QUALIFIER or MAP_QUALIFIER, got {config.track!r}")
    for name in ("step_timeout", "setup_timeout"):
        if getattr(config, name) <= 0:
            raise EvalError(f"--{name.replace('_', '-')} must be positive")
    if config.xodr is not None and not config.xodr.exists():
        raise EvalError(f"--xodr {config.xodr} does not exist")


def task_seed(seed: int, route_id: str, repetition: int) -> int:
    """A route repetition's simulator seed: collection's route seed for the first, a fresh one for each other."""
    return route_seed(seed, route_id if repetition == 0 else f"{route_id}_rep{repetition}")


def plan_evaluation(config: EvalConfig) -> EvalPlan:
    """Select the routes, find their towns and list the tasks (raises :class:`EvalError` naming the problem)."""
    _check_config(config)
    routes = _read_route_file(config.routes_file)
    if not routes:
        raise EvalError(f"{config.routes_file} holds no route")
    if config.route_ids:
        by_id = {r.id: r for r in routes}
        unknown = [i for i in config.route_ids if i not in by_id]
        if unknown:
            shown = ", ".join(list(by_id)[:8]) + (" ..." if len(by_id) > 8 else "")
            raise EvalError(f"{config.routes_file} has no route with id {', '.join(unknown)} (its ids: {shown})")
        routes = [by_id[i] for i in dict.fromkeys(config.route_ids)]
    towns: dict[str, TownSource | None] = {}
    reasons: dict[str, str] = {}
    for name in dict.fromkeys(r.town for r in routes):
        try:
            source = route_town(name, config.xodr)
            towns[name] = source.materialise(config.out) if source is not None else None
        except TownError as exc:
            towns[name], reasons[name] = None, str(exc)
        if towns[name] is None and name not in reasons:
            where = (f"{config.xodr} has no {name}.xodr" if config.xodr is not None and config.xodr.is_dir()
                     else "it is neither a shipped CARLA town nor a generated one")  # fmt: skip
            reasons[name] = f"no map for {name}: {where} (give it with --xodr FILE or a folder of <Town>.xodr)"
    skipped = [SkippedRoute(r.id, r.town, reasons[r.town]) for r in routes if towns[r.town] is None]
    runnable = [r for r in routes if towns[r.town] is not None]
    if not runnable:
        detail = "; ".join(sorted(set(reasons.values())))
        raise EvalError(f"none of the {len(routes)} selected routes of {config.routes_file} can run: {detail}")
    tasks = []
    for repetition in range(config.repetitions):
        for route in runnable:
            town = towns[route.town]
            assert town is not None
            tasks.append(RouteTask(route, town, repetition, len(tasks), task_seed(config.seed, route.id, repetition)))
    return EvalPlan(runnable, tasks, skipped)


def _prepare_folder(config: EvalConfig, plan: EvalPlan) -> None:
    """Check or write ``eval.json`` and write ``routes.xml``; a second run into a used folder needs ``--resume``."""
    path = config.out / SETTINGS_FILE
    settings = config.settings()
    if path.is_file():
        if not config.resume:
            raise EvalError(f"{config.out} already holds an evaluation ({path}); continue it with --resume or give "
                            "another --out")  # fmt: skip
        try:
            previous = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise EvalError(f"{path} is unreadable ({exc}); cannot check that the resume matches") from None
        changed = [k for k in FIXED_SETTINGS if previous.get(k) != settings.get(k)]
        if changed:
            detail = "; ".join(f"{k}: was {previous.get(k)!r}, now {settings.get(k)!r}" for k in changed)
            raise EvalError(f"--resume with other settings than the evaluation in {config.out}: {detail}")
    else:
        settings["expected_routes"] = len(plan.tasks)
        settings["skipped_routes"] = [asdict(s) for s in plan.skipped]
        _write_json(path, settings)
    routes_xml = config.out / ROUTES_FILE
    temp = routes_xml.with_name(f".{routes_xml.name}.tmp-{os.getpid()}")
    write_routes(plan.routes, temp)
    os.replace(temp, routes_xml)


def _write_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        temp.write_text(json.dumps(data, indent=4), encoding="utf-8")
        os.replace(temp, path)
    finally:
        temp.unlink(missing_ok=True)


def _finished_record(out: Path, task: RouteTask) -> lb.RouteRecord | None:
    """The task's record when it finished (a crashed simulation is run again by a resume), else None."""
    path = record_path(out, task.key)
    if not path.is_file():
        return None
    try:
        records = lb.read_results(path).records
    except B2DFormatError as exc:
        log.warning("%s: ignoring an unreadable record (%s); the route runs again", path, exc)
        return None
    if len(records) != 1 or records[0].route_id != task.key:
        log.warning("%s does not hold the record of %s; the route runs again", path, task.key)
        return None
    if statistics.SIMULATION_CRASHED_FAILURE in records[0].status:
        return None
    return records[0]


class _Pool:
    """At most ``workers`` route processes at a time, each started fresh for one route."""

    def __init__(self, workers: int, settings: RouteSettings) -> None:
        self.workers = workers
        self.settings = settings
        # A route process starts from a fork server with the simulator's modules loaded once. Several of them share
        # the cores: one BLAS/OpenMP thread each; a single one keeps the library defaults for the agent's model.
        self.context = worker_context(EVAL_PRELOAD, single_thread=workers > 1)
        self.reports = self.context.Queue()
        self.running: dict[str, tuple[Any, RouteTask, float]] = {}

    def start(self, task: RouteTask) -> None:
        """Start ``task``'s route process."""
        process = self.context.Process(
            target=route_main, name=f"b2d-eval {task.key}",
            args=(task, self.settings, self.reports, os.getpid(), logging.getLogger().getEffectiveLevel()),
        )  # fmt: skip
        process.start()
        self.running[task.key] = (process, task, time.monotonic())

    def messages(self, timeout: float) -> list[Any]:
        """Reports of the route processes (waits up to ``timeout`` s for the first)."""
        out: list[Any] = []
        try:
            out.append(self.reports.get(timeout=timeout))
            while True:
                out.append(self.reports.get_nowait())
        except queue.Empty:
            pass
        except (EOFError, OSError, ValueError):  # a report cut short by a killed process
            log.debug("lost a route process report", exc_info=True)
        return out

    def ended(self) -> list[tuple[RouteTask, int]]:
        """Tasks whose process has ended, with its exit code (removed from the running set)."""
        done = []
        for key, (process, task, _) in list(self.running.items()):
            if process.exitcode is not None:
                process.join()
                del self.running[key]
                done.append((task, int(process.exitcode)))
        return done

    def stop(self) -> None:
        """Stop every route process: SIGTERM, then SIGKILL after :data:`STOP_GRACE` seconds."""
        processes = [p for p, _, _ in self.running.values()]
        for process in processes:
            if process.exitcode is None:
                process.terminate()
        deadline = time.monotonic() + STOP_GRACE
        for process in processes:
            process.join(timeout=max(deadline - time.monotonic(), 0.0))
            if process.exitcode is None:
                process.kill()
                process.join(timeout=5.0)
        self.running.clear()


def _describe_exit(code: int) -> str:
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"the route process was killed by {name}"
    return f"the route process exited with status {code} before writing its record"


def run_evaluation(
    config: EvalConfig, progress: Callable[[EvalProgress], None] | None = None
) -> EvalResult:
    """Run every task of the plan that has no record yet and write the result files (see the module docstring)."""
    # a bare shipped name (bench2drive220.xml) is the package's file: eval.json and the agents' ROUTES say which
    config = replace(config, routes_file=shipped_or_given(config.routes_file))
    plan = plan_evaluation(config)
    out = config.out
    with corpus_lock(out, LOCK_FILE, "b2d-eval run", EvalError):
        _prepare_folder(config, plan)
        return _run(config, plan, progress)


def _run(config: EvalConfig, plan: EvalPlan, progress: Callable[[EvalProgress], None] | None) -> EvalResult:
    out = config.out
    started = time.monotonic()
    run_log = rl.RunLog(out / rl.LOG_FILE)
    records: dict[str, lb.RouteRecord] = {}
    pending: deque[RouteTask] = deque()
    for task in plan.tasks:
        record = _finished_record(out, task) if config.resume else None
        if record is not None:
            records[task.key] = record
        else:
            pending.append(task)
    resumed = len(records)
    if resumed:
        log.info("resuming: %d of %d routes already have their record", resumed, len(plan.tasks))
    for skipped in plan.skipped:
        log.warning("route %s skipped: %s", skipped.route_id, skipped.reason)
    settings = RouteSettings(
        out=out.resolve(),
        agent=AgentSettings(path=config.agent.resolve(), config=config.agent_config, track=config.track,
                            setup_timeout=config.setup_timeout, step_timeout=config.step_timeout),
        routes_file=config.routes_file.resolve(), max_ticks=config.max_ticks, environ=tuple(sorted(os.environ.items())),
    )  # fmt: skip
    state = ProgressState(requested=len(plan.tasks), clips=resumed)
    outcomes: dict[str, RouteOutcome] = {}
    pool = _Pool(min(config.workers, max(len(pending), 1)), settings)
    last_progress = 0.0
    try:
        while pending or pool.running:
            while pending and len(pool.running) < pool.workers:
                task = pending.popleft()
                record_path(out, task.key).unlink(missing_ok=True)  # a crashed attempt's record is replaced
                pool.start(task)
                state.route_started(task.key, task.route.scenario_type or "NoScenario")
                run_log.append({"event": rl.EVENT_START, "route_id": task.key, "seed": task.seed,
                                "town": task.town.name, "time": _now()})  # fmt: skip
            for message in pool.messages(timeout=0.25):
                if isinstance(message, FrameReport):
                    state.frames_reported(message)
                elif isinstance(message, tuple) and message and message[0] == "done":
                    outcomes[message[1].key] = message[1]
            for task, code in pool.ended():
                record = _collect(out, task, code, outcomes)
                records[task.key] = record
                outcome = outcomes.get(task.key, RouteOutcome(task.key))
                state.route_finished(task.key, outcome.ticks, clip=True)
                if record.status.startswith(lb.STATUS_FAILED):
                    state.failed += 1
                entry = {**asdict(outcome), "status": record.status, "score_composed": record.scores.score_composed}
                run_log.append({"event": rl.EVENT_ATTEMPT, "route_id": task.key, "seed": task.seed,
                                "exit_code": code, **entry, "time": _now()})  # fmt: skip
                log.info("%s: %s (driving score %.2f)", task.key, record.status, record.scores.score_composed)
            now = time.monotonic()
            if progress is not None and now - last_progress >= 1.0:
                last_progress = now
                progress(_progress_of(state))
    except BaseException as exc:
        interrupted = [t.key for _, t, _ in pool.running.values()]
        pool.stop()
        for key in interrupted:
            run_log.append({"event": rl.EVENT_INTERRUPTED, "route_id": key, "time": _now()})
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise EvalInterrupted(
                f"interrupted: {len(records)} of {len(plan.tasks)} routes have their record in {out / RECORDS_DIR}; "
                "the same command with --resume runs the others"
            ) from None
        raise
    finally:
        pool.reports.close()
    if progress is not None:
        progress(_progress_of(state))
    ordered = [records[t.key] for t in plan.tasks if t.key in records]
    write_results(out, ordered, len(plan.tasks))
    return EvalResult(out, plan, ordered, outcomes, resumed, round(time.monotonic() - started, 3))


def _collect(out: Path, task: RouteTask, code: int, outcomes: dict[str, RouteOutcome]) -> lb.RouteRecord:
    """The record a finished route process left; a process that died without one gets a crash record."""
    path = record_path(out, task.key)
    if path.is_file():
        try:
            return lb.read_results(path).records[0]
        except (B2DFormatError, IndexError) as exc:
            log.error("%s: unreadable record (%s)", path, exc)
    detail = f"{_describe_exit(code)}; see {log_path(out, task.key)}"
    log.error("route %s: %s", task.key, detail)
    outcomes[task.key] = RouteOutcome(task.key, status=f"{lb.STATUS_FAILED} - Simulation crashed", detail=detail)
    record = crash_record(task, statistics.SIMULATION_CRASHED_FAILURE, detail)
    write_record(out, task.key, record)
    return record


def _progress_of(state: ProgressState) -> EvalProgress:
    return EvalProgress(done=state.clips, total=state.requested, running=state.routes(), elapsed=state.elapsed(),
                        eta=state.eta(), failed=state.failed)  # fmt: skip


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def write_results(out: Path, records: Sequence[lb.RouteRecord], total: int) -> None:
    """``results.json`` (the Leaderboard checkpoint of every record) and ``merged.json`` (the merge tool's file)."""
    checkpoint = statistics.checkpoint_results(list(records), total_routes=total)
    _write_json(out / RESULTS_FILE, checkpoint.to_dict())
    merged_records = []
    for record in records:
        entry = record.to_dict()
        entry.pop("index", None)
        entry.pop(EVAL_EXTRA, None)
        merged_records.append(entry)
    successes = sum(1 for r in records if r.success)
    # the merge tool sorts the records by route id, as strings, descending
    merged_records.sort(key=lambda entry: str(entry["route_id"]), reverse=True)
    merged = {
        "_checkpoint": {"records": merged_records},
        "driving score": sum(r.scores.score_composed for r in records) / max(total, 1),
        "success rate": successes / max(total, 1),
        "eval num": len(records),
    }
    _write_json(out / MERGED_FILE, merged)


def read_settings(folder: Path) -> dict[str, Any] | None:
    """``eval.json`` of a ``b2d-eval run`` folder, or None when ``folder`` is not one."""
    path = Path(folder) / SETTINGS_FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return None
    return data if isinstance(data, dict) and data.get("format") == SETTINGS_FORMAT else None
