"""The collection loop behind ``b2d-collect``: plan routes, run attempts until each scenario has its clips, resume.

:func:`plan_collection` resolves the town (a generated preset, an OpenDRIVE file, or a folder of them for a route
file), builds each scenario's route list (``placement.make_routes`` with an attempt budget, or the routes of a
route XML file) and derives every route's seed from ``--seed`` and the route id, so that the same seed gives the
same routes, the same runs and the same annotations. :func:`collect` launches attempts in route order, never more
than a scenario still needs (so the clips are the first ``n`` successes of its list, however many run in
parallel), appends each outcome to the run log, and writes ``summary.json``.

Crash safety: clips appear atomically (the writer renames a finished temporary folder); on ``resume`` stale
temporaries are removed, the run log and the files on disk are reconciled (a clip or a route record that reached
the disk just before a crash is adopted rather than run again) and every route with a finished attempt is skipped.
"""

from __future__ import annotations

import contextlib
import difflib
import fcntl
import json
import logging
import os
import re
import shutil
import time
import zlib
from collections import Counter, deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from b2d_data.collection import run_log as rl
from b2d_data.collection.job import (
    FAILED_DIR,
    RESULTS_DIR,
    STATUS_CLIP,
    STATUS_ERROR,
    STATUS_FAILED,
    CollectConfig,
    JobResult,
    exit_with_parent,
    move_to_failed,
    process_alive,
    run_route_job,
    shutdown_encoders,
    with_weather,
)
from b2d_data.collection.towns import (
    TOWNS_DIR,
    TownError,
    TownSource,
    default_preset,
    ensure_hdmap,
    load_map,
    preset_town_name,
    xodr_in_folder,
    xodr_source,
)
from b2d_data.format import leaderboard as lb
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipName, ClipNameError
from b2d_data.format.scenario_types import BY_CLIP_PREFIX, BY_XML_TYPE, NO_SCENARIO
from b2d_data.format.version import FORMAT_FILE
from b2d_data.format.weather import UnknownWeatherError, preset
from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

SUMMARY_FILE = "summary.json"
#: Where a generated collection saves its planned routes (one route file per scenario).
PLANNED_ROUTES_DIR = "routes"
#: The settings a resumed collection must share with the one it continues.
SETTINGS_FILE = "collect.json"
LOCK_FILE = ".b2d_collect.lock"
#: Seconds a starting collection waits for the writers of a killed one to exit.
LIVE_WRITER_WAIT = 10.0
#: Writers' temporaries: ``.<name>.tmp-<pid>-<hex>`` (clip_writer.py names them so).
_TEMP_RE = re.compile(r"^\.(?P<name>.+)\.(?:tmp|old)-(?P<pid>\d+)-[0-9a-f]+$")
#: Settings that change what a route produces; a resume with other values would mix incompatible clips.
_FIXED_SETTINGS = ("seed", "town", "xodr", "routes_file", "weathers", "width", "height", "lidar_azimuth_steps",
                   "format_version", "sensors")  # fmt: skip


class CollectError(Exception):
    """A problem the user can act on (bad option, unknown scenario or town, unreadable routes, busy folder)."""


# ------------------------------------------------------------------------------------------------ the plan


@dataclass(frozen=True)
class RouteTask:
    """One route to attempt: the route, its (file-backed) town, its scenario group and its seed."""

    route: Route
    town: TownSource
    scenario: str
    seed: int


@dataclass
class ScenarioPlan:
    """One scenario's routes in attempt order and its clip target."""

    scenario: str
    target: int
    tasks: list[RouteTask] = field(default_factory=list)
    #: Why the scenario has no routes (placement failed), if it has none.
    error: str | None = None


@dataclass
class CollectionPlan:
    """Every scenario's routes, the towns they use, and the settings that must not change on resume."""

    scenarios: list[ScenarioPlan]
    towns: list[TownSource]
    settings: dict[str, Any]
    skipped: list[str] = field(default_factory=list)


def route_seed(seed: int, route_id: str) -> int:
    """The seed of one route: a function of the collection seed and the route id only."""
    state = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, zlib.crc32(str(route_id).encode("utf-8"))])
    return int(state.generate_state(1)[0] & 0x7FFFFFFF)


def resolve_scenario(name: str) -> str:
    """The XML type of a scenario name (XML type or clip prefix); unknown names list close matches."""
    if name in BY_XML_TYPE:
        return name
    if name in BY_CLIP_PREFIX:
        return BY_CLIP_PREFIX[name].xml_type
    if name == NO_SCENARIO:
        return name
    close = difflib.get_close_matches(name, sorted(set(BY_XML_TYPE) | set(BY_CLIP_PREFIX)), n=3, cutoff=0.5)
    hint = f" Did you mean {' or '.join(close)}?" if close else ""
    raise CollectError(f"unknown scenario {name!r}.{hint} Known scenarios: {', '.join(sorted(BY_XML_TYPE))}")


def implemented_scenarios() -> list[str]:
    """XML types that have both a behaviour and a placement rule (what a generated collection can hold)."""
    from b2d_data.scenarios import placement
    from b2d_data.scenarios.framework import SCENARIO_CLASSES, scenario_class

    with contextlib.suppress(Exception):
        scenario_class(next(iter(placement.LAYOUTS)))  # imports the catalog, filling the registry
    return sorted(t for t in placement.LAYOUTS if t in SCENARIO_CLASSES)


def _check_generated_scenario(name: str) -> str:
    xml_type = resolve_scenario(name)
    known = implemented_scenarios()
    if xml_type not in known:
        raise CollectError(
            f"scenario {xml_type!r} cannot be generated yet (no behaviour or placement rule); "
            f"implemented: {', '.join(known)}"
        )
    return xml_type


def _check_weathers(weathers: Sequence[int]) -> tuple[int, ...]:
    try:
        for w in weathers:
            preset(w)
    except UnknownWeatherError as exc:
        raise CollectError(str(exc.args[0] if exc.args else exc)) from None
    return tuple(int(w) for w in weathers)


def settings_of(config: CollectConfig) -> dict[str, Any]:
    """The settings recorded in ``collect.json`` (JSON-friendly)."""
    values = asdict(config)
    out: dict[str, Any] = {}
    for key in _FIXED_SETTINGS:
        value = values[key]
        if isinstance(value, Path):
            value = str(value.resolve())
        elif isinstance(value, tuple):
            value = list(value)
        elif hasattr(value, "value"):
            value = value.value
        out[key] = value
    return out


def _generated_plan(config: CollectConfig) -> CollectionPlan:
    from b2d_data.scenarios import placement

    scenarios = list(dict.fromkeys(_check_generated_scenario(s) for s in config.scenarios))
    if config.xodr is not None:
        town = xodr_source(config.xodr)
    else:
        town = TownSource(preset=config.town or default_preset())
    town = _materialise(town, config.out)
    world_map = load_map(town)
    weathers = list(config.weathers) or None
    budget = max(1, config.attempts_per_clip) * config.n
    plans = []
    for scenario in scenarios:
        plan = ScenarioPlan(scenario, config.n)
        saved = config.out / PLANNED_ROUTES_DIR / f"{scenario}.xml"
        routes = _saved_routes(saved, budget, world_map.name) if config.resume else []
        # The list for the full budget; a town with fewer places still gets the routes the target needs.
        for count in dict.fromkeys((budget, config.n)) if not routes else ():
            try:
                routes = placement.make_routes(world_map, scenario, count, config.seed, weathers)
                _save_routes(routes, saved)
                break
            except placement.PlacementError as exc:
                plan.error = str(exc)
        if routes:
            plan.error = None
        plan.tasks = [RouteTask(r, town, scenario, route_seed(config.seed, r.id)) for r in routes]
        if plan.error:
            log.warning("%s: %s", scenario, plan.error)
        plans.append(plan)
    return CollectionPlan(plans, [town], settings_of(config))


def _saved_routes(path: Path, budget: int, town: str) -> list[Route]:
    """The routes planned by an earlier session (so that a resume never depends on a re-run of the placement)."""
    if not path.is_file():
        return []
    try:
        routes = _read_route_file(path)
    except CollectError as exc:
        log.warning("ignoring the saved route list: %s", exc)
        return []
    if len(routes) < budget or any(r.town != town for r in routes):
        return []
    log.info("using the %d routes planned earlier in %s", len(routes), path)
    return routes


def _save_routes(routes: Sequence[Route], path: Path) -> None:
    from b2d_data.scenarios.route_xml import write_routes

    path.parent.mkdir(parents=True, exist_ok=True)
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}-000000")
    write_routes(routes, temp)
    os.replace(temp, path)


def _materialise(town: TownSource, out: Path) -> TownSource:
    try:
        return town.materialise(out)
    except TownError as exc:
        raise CollectError(str(exc)) from None


def _read_route_file(path: Path) -> list[Route]:
    from b2d_data.scenarios.route_xml import read_routes

    try:
        return read_routes(path)
    except B2DFormatError as exc:
        raise CollectError(f"cannot read route file: {exc}") from None
    except OSError as exc:
        raise CollectError(f"cannot read route file {path}: {exc}") from None


def _file_plan(config: CollectConfig) -> CollectionPlan:
    assert config.routes_file is not None
    routes = _read_route_file(config.routes_file)
    if not routes:
        raise CollectError(f"{config.routes_file} holds no route")
    bad = [r.id for r in routes if not str(r.id).isdigit()]
    if bad:
        raise CollectError(f"{config.routes_file}: route ids must be integers for clip names; got {bad[:5]}")
    if config.scenarios:
        wanted = {resolve_scenario(s) for s in config.scenarios}
        routes = [r for r in routes if (r.scenario_type or NO_SCENARIO) in wanted]
        if not routes:
            raise CollectError(f"{config.routes_file} has no route of scenario {', '.join(sorted(wanted))}")
    weathers = _check_weathers(config.weathers)
    towns: dict[str, TownSource | None] = {}
    skipped: list[str] = []
    for name in dict.fromkeys(r.town for r in routes):
        towns[name] = _town_for(config, name)
    missing = sorted(name for name, source in towns.items() if source is None)
    if missing:
        held = [r for r in routes if towns[r.town] is None]
        if config.xodr is None:
            where = "no --xodr was given"
        elif config.xodr.is_dir():
            where = f"{config.xodr} has no <Town>.xodr for them"
        else:
            where = f"--xodr gives the map {config.xodr.stem}"
        if len(held) == len(routes):
            raise CollectError(
                f"none of the {len(routes)} selected routes of {config.routes_file} can run: they are on "
                f"{', '.join(missing)} but {where}; pass --xodr with that town's file or a folder of <Town>.xodr"
            )
        log.warning("skipping %d route(s) on %s: no map for them (%s)", len(held), ", ".join(missing), where)
        skipped = [r.id for r in held]
        routes = [r for r in routes if towns[r.town] is not None]
    materialised = {name: _materialise(s, config.out) for name, s in towns.items() if s is not None}
    groups: dict[str, list[Route]] = {}
    for r in routes:
        if weathers:
            r = with_weather(r, weathers[route_seed(config.seed, r.id) % len(weathers)])
        groups.setdefault(r.scenario_type or NO_SCENARIO, []).append(r)
    plans = []
    for scenario, group in groups.items():
        target = len(group) if config.n is None else min(config.n, len(group))
        tasks = [RouteTask(r, materialised[r.town], scenario, route_seed(config.seed, r.id)) for r in group]
        plans.append(ScenarioPlan(scenario, target, tasks))
    return CollectionPlan(plans, list(materialised.values()), settings_of(config), skipped)


def _town_for(config: CollectConfig, town: str) -> TownSource | None:
    """The source of a route file's town: the --xodr file or folder, else a generated preset of that name."""
    try:
        if config.xodr is not None:
            if config.xodr.is_dir():
                return xodr_in_folder(config.xodr, town)
            source = xodr_source(config.xodr)
            return source if source.name == town else None
        from b2d_data.maps import towngen

        presets = {p.town: p.name for p in towngen.TOWN_PRESETS.values()}
        if config.town is not None:
            return TownSource(preset=config.town) if presets.get(town) == config.town else None
        return TownSource(preset=presets[town]) if town in presets else None
    except TownError as exc:
        raise CollectError(str(exc)) from None


def validate_config(config: CollectConfig) -> None:
    """Check the options before anything touches the disk (raises :class:`CollectError` naming the problem)."""
    if config.n is not None and config.n < 1:
        raise CollectError(f"--n must be at least 1, got {config.n}")
    if config.workers < 1:
        raise CollectError(f"--workers must be at least 1, got {config.workers}")
    if config.town is not None and config.xodr is not None:
        raise CollectError("give either --town PRESET or --xodr FILE, not both")
    _check_weathers(config.weathers)
    try:
        if config.town is not None:
            preset_town_name(config.town)
        if config.xodr is not None and not config.xodr.is_dir():
            xodr_source(config.xodr)
    except TownError as exc:
        raise CollectError(str(exc)) from None
    if config.ray_address is not None:
        from b2d_data.collection.ray_backend import RayUnavailableError, require_ray

        try:
            require_ray()
        except RayUnavailableError as exc:
            raise CollectError(str(exc)) from None
    if config.xodr is not None and config.xodr.is_dir() and config.routes_file is None:
        raise CollectError(f"--xodr {config.xodr} is a folder; without --routes give one OpenDRIVE file")
    if config.routes_file is not None:
        for name in config.scenarios:
            resolve_scenario(name)
        _read_route_file(config.routes_file)
    else:
        if not config.scenarios:
            raise CollectError("give at least one --scenario NAME (or a route file with --routes)")
        for name in config.scenarios:
            _check_generated_scenario(name)


def plan_collection(config: CollectConfig) -> CollectionPlan:
    """Resolve towns and scenarios and list every route to attempt, in order (raises :class:`CollectError`)."""
    validate_config(config)
    if config.routes_file is not None:
        return _file_plan(config)
    if config.n is None:
        config = replace(config, n=1)
    return _generated_plan(config)


# ------------------------------------------------------------------------------------------------ backends


class Backend(Protocol):
    """Runs route tasks somewhere; ``wait`` returns at least one finished task while any is running."""

    capacity: int

    def submit(self, task: RouteTask) -> None:
        """Start a task."""
        ...

    def wait(self) -> list[tuple[RouteTask, JobResult]]:
        """Block until at least one task finished; return the finished ones."""
        ...

    def running(self) -> int:
        """Tasks started and not yet returned by ``wait``."""
        ...

    def close(self) -> None:
        """Stop; tasks still running are abandoned."""
        ...


def error_result(task: RouteTask, reason: str) -> JobResult:
    """The result of a task whose worker died or could not be reached."""
    now = datetime.now(timezone.utc).isoformat(timespec="milliseconds")
    return JobResult(
        route_id=str(task.route.id),
        scenario=task.scenario,
        town=task.town.name,
        weather_id=None,
        seed=task.seed,
        status=STATUS_ERROR,
        reason=reason,
        started=now,
        finished=now,
    )


class InlineBackend:
    """Runs each task in this process, one at a time."""

    capacity = 1

    def __init__(self, out: Path, config: CollectConfig) -> None:
        self.out, self.config = out, config
        self._queue: deque[RouteTask] = deque()

    def submit(self, task: RouteTask) -> None:
        """Queue the task; it runs in :meth:`wait`."""
        self._queue.append(task)

    def wait(self) -> list[tuple[RouteTask, JobResult]]:
        """Run the oldest queued task."""
        task = self._queue.popleft()
        return [(task, run_route_job(task.route, task.town, self.out, self.config, task.seed))]

    def running(self) -> int:
        """Queued tasks."""
        return len(self._queue)

    def close(self) -> None:
        """Drop queued tasks and stop this process's encoder pool."""
        self._queue.clear()
        shutdown_encoders()


def _worker_init(log_level: int, driver_pid: int) -> None:
    """Pool worker set-up: die with the driver (no orphan finishing a route after a kill), quiet logging."""
    exit_with_parent(driver_pid)
    logging.basicConfig(level=log_level, format="%(levelname)s %(name)s [%(process)d]: %(message)s")
    logging.getLogger().setLevel(log_level)


class ProcessPoolBackend:
    """Runs tasks in ``workers`` processes of this machine; each process owns its simulator and map cache."""

    def __init__(self, out: Path, config: CollectConfig, workers: int) -> None:
        self.out, self.config, self.capacity = out, config, workers
        self._futures: dict[Future[JobResult], RouteTask] = {}
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        import multiprocessing

        # spawn/forkserver: a worker never inherits the driver's threads (tqdm, GL) mid-state.
        method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
        return ProcessPoolExecutor(
            self.capacity,
            mp_context=multiprocessing.get_context(method),
            initializer=_worker_init,
            initargs=(logging.getLogger().getEffectiveLevel(), os.getpid()),
        )

    def submit(self, task: RouteTask) -> None:
        """Start the task in a worker."""
        try:
            future = self._pool.submit(run_route_job, task.route, task.town, self.out, self.config, task.seed)
        except BrokenProcessPool:
            self._pool = self._new_pool()
            future = self._pool.submit(run_route_job, task.route, task.town, self.out, self.config, task.seed)
        self._futures[future] = task

    def wait(self) -> list[tuple[RouteTask, JobResult]]:
        """Results of the tasks that finished (a dead worker fails its tasks, and the pool is rebuilt)."""
        done, _ = wait_futures(list(self._futures), return_when=FIRST_COMPLETED)
        out: list[tuple[RouteTask, JobResult]] = []
        broken = False
        for future in done:
            task = self._futures.pop(future)
            try:
                out.append((task, future.result()))
            except BrokenProcessPool:
                broken = True
                out.append((task, error_result(task, "worker process died (killed or crashed)")))
            except Exception as exc:  # noqa: BLE001 - a failed task is an error result, not a failed collection
                out.append((task, error_result(task, f"{type(exc).__name__}: {exc}")))
        if broken:
            log.warning("a worker process died; starting a new pool")
            self._pool.shutdown(wait=False, cancel_futures=True)
            # The other tasks of a broken pool fail too; they are reported, not lost.
            for future, task in list(self._futures.items()):
                del self._futures[future]
                out.append((task, error_result(task, "worker pool broke while the route was queued or running")))
            self._pool = self._new_pool()
        return out

    def running(self) -> int:
        """Tasks in flight."""
        return len(self._futures)

    def close(self) -> None:
        """Shut the pool down (running tasks are cancelled where possible)."""
        self._pool.shutdown(wait=True, cancel_futures=True)


def make_backend(out: Path, config: CollectConfig) -> Backend:
    """Ray with ``ray_address``, a process pool with several workers, else this process."""
    if config.ray_address is not None:
        from b2d_data.collection.ray_backend import RayBackend, RayUnavailableError

        try:
            return RayBackend(out, config, config.ray_address)
        except RayUnavailableError as exc:
            raise CollectError(str(exc)) from None
    if config.workers > 1:
        return ProcessPoolBackend(out, config, config.workers)
    return InlineBackend(out, config)


# ------------------------------------------------------------------------------------------------ corpus state


@contextlib.contextmanager
def corpus_lock(out: Path) -> Iterator[None]:
    """Hold ``<out>/.b2d_collect.lock`` so that two collections never write one folder (released on any exit)."""
    out.mkdir(parents=True, exist_ok=True)
    with open(out / LOCK_FILE, "a+") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise CollectError(f"another b2d-collect is writing {out} (it holds {out / LOCK_FILE})") from None
        try:
            yield
        finally:
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def _check_settings(out: Path, settings: dict[str, Any], resume: bool) -> None:
    path = out / SETTINGS_FILE
    if resume and path.is_file():
        try:
            previous = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise CollectError(f"{path} is unreadable ({exc}); cannot check that the resume matches") from None
        changed = [k for k in _FIXED_SETTINGS if k in previous and previous[k] != settings.get(k)]
        if changed:
            detail = "; ".join(f"{k}: was {previous[k]!r}, now {settings.get(k)!r}" for k in changed)
            raise CollectError(f"--resume with other settings than the collection in {out}: {detail}")
        return
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}-000000")
    temp.write_text(json.dumps(settings, indent=2), encoding="utf-8")
    os.replace(temp, path)


def remove_temporaries(out: Path) -> list[Path]:
    """Remove what crashed writers left in the corpus (clip, map, town, record and route-list temporaries)."""
    from b2d_data.writers import remove_stale_temporaries

    removed: list[Path] = []
    for folder in (out, out / TOWNS_DIR, out / RESULTS_DIR, out / FAILED_DIR, out / PLANNED_ROUTES_DIR):
        removed += remove_stale_temporaries(folder)
        # The writers' rule keeps a zombie's temporaries (a killed worker nobody reaped); they are dead too.
        for sub in (folder, folder / "maps"):
            for entry in sorted(sub.iterdir()) if sub.is_dir() else []:
                match = _TEMP_RE.match(entry.name)
                if match is None or process_alive(int(match["pid"])):
                    continue
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry, ignore_errors=True)
                else:
                    entry.unlink(missing_ok=True)
                removed.append(entry)
    return removed


def _live_temporaries(out: Path) -> list[tuple[Path, int]]:
    """Clip temporaries in the corpus whose writing process is still alive."""
    found = []
    if out.is_dir():
        for entry in out.iterdir():
            match = _TEMP_RE.match(entry.name)
            if match is not None and process_alive(int(match["pid"])):
                found.append((entry, int(match["pid"])))
    return found


def _clips_on_disk(out: Path) -> dict[str, Path]:
    """Complete clips at the top of the corpus, keyed by route id."""
    found: dict[str, Path] = {}
    if not out.is_dir():
        return found
    for entry in sorted(out.iterdir()):
        if entry.name.startswith(".") or not entry.is_dir() or not (entry / FORMAT_FILE).is_file():
            continue
        try:
            name = ClipName.parse(entry.name)
        except ClipNameError:
            continue
        found[str(name.route_id)] = entry
    return found


def _recovered(path: Path) -> JobResult | None:
    """A run-log record rebuilt from a route's result file written just before a crash."""
    try:
        results = lb.read_results(path)
        name = ClipName.parse(path.stem)
    except (B2DFormatError, ClipNameError, OSError):
        return None
    if not results.records:
        return None
    record = results.records[0]
    extra = record.extra.get("b2d_collect")
    if not isinstance(extra, dict):
        return None  # the record of a job that crashed: no verdict on the route, run it again
    success = bool(extra.get("success", record.success))
    kinds = {k: len(v) for k, v in record.infractions.items() if v}
    return JobResult(
        route_id=str(name.route_id), scenario=name.xml_type, town=name.town, weather_id=name.weather_id,
        seed=int(extra.get("seed", 0)), status=STATUS_CLIP if success else STATUS_FAILED, success=success,
        clip=str(name), route_status=record.status, infractions=kinds,
        score_composed=float(record.scores.score_composed), score_route=float(record.scores.score_route),
        duration_game=float(record.meta.duration_game), duration=float(record.meta.duration_system),
        reason="" if success else record.status, note="recovered from results/ after an interruption",
    )  # fmt: skip


def reconcile(out: Path, records: list[dict[str, Any]], config: CollectConfig, run_log: rl.RunLog) -> None:
    """Adopt what reached the disk before a crash but not the run log: clips and route records."""
    finished = {str(r.get("route_id")) for r in rl.final_records(records)}
    clips = _clips_on_disk(out)
    results_dir = out / RESULTS_DIR
    for path in sorted(results_dir.glob("*.json")) if results_dir.is_dir() else []:
        recovered = _recovered(path)
        if recovered is None or recovered.route_id in finished:
            continue
        clip_dir = clips.get(recovered.route_id)
        if recovered.success:
            if config.sensors and clip_dir is None:
                continue  # killed between the record and the clip: run the route again
            recovered.clip_path = clip_dir.name if clip_dir is not None else None
        elif clip_dir is not None:
            # Killed between closing a failed clip and moving it (keep_failed): finish the move.
            recovered.clip_path = move_to_failed(out, clip_dir.name)
        log.info("adopting the finished attempt of route %s from %s", recovered.route_id, path)
        run_log.append(recovered.to_record())
        records.append(recovered.to_record())
        finished.add(recovered.route_id)
    for route_id, clip_dir in clips.items():
        if route_id not in finished:
            # A complete clip without any record cannot be vouched for: keep it aside, never count it.
            log.warning("clip %s has no route record; moving it to %s/", clip_dir.name, FAILED_DIR)
            move_to_failed(out, clip_dir.name)


# ------------------------------------------------------------------------------------------------ the loop


@dataclass
class ScenarioSummary:
    """One scenario's outcome over the whole corpus (every session of a resumed collection)."""

    scenario: str
    requested: int
    attempts: int = 0
    clips: int = 0
    failed: int = 0
    errors: int = 0
    routes_planned: int = 0
    reasons: dict[str, int] = field(default_factory=dict)
    note: str = ""

    @property
    def success_rate(self) -> float:
        """Successful attempts over attempts (0 without attempts)."""
        return self.clips / self.attempts if self.attempts else 0.0

    @property
    def complete(self) -> bool:
        """Whether the target was met."""
        return self.clips >= self.requested

    def to_dict(self) -> dict[str, Any]:
        """JSON form (with the success rate)."""
        return {**asdict(self), "success_rate": round(self.success_rate, 4), "complete": self.complete}


@dataclass
class CollectSummary:
    """What :func:`collect` returns and writes to ``summary.json``."""

    out: str
    scenarios: list[ScenarioSummary]
    attempts_this_run: int = 0
    clips_this_run: int = 0
    wall_seconds: float = 0.0
    skipped_routes: list[str] = field(default_factory=list)
    sensors: bool = True

    @property
    def complete(self) -> bool:
        """Whether every scenario reached its target."""
        return all(s.complete for s in self.scenarios)

    @property
    def seconds_per_clip(self) -> float | None:
        """Wall-clock seconds per clip made in this run (None when none was made)."""
        return self.wall_seconds / self.clips_this_run if self.clips_this_run else None

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {
            "out": self.out, "complete": self.complete, "sensors": self.sensors,
            "attempts_this_run": self.attempts_this_run, "clips_this_run": self.clips_this_run,
            "wall_seconds": round(self.wall_seconds, 3),
            "seconds_per_clip": None if self.seconds_per_clip is None else round(self.seconds_per_clip, 3),
            "skipped_routes": self.skipped_routes,
            "scenarios": [s.to_dict() for s in self.scenarios],
        }  # fmt: skip


@dataclass(frozen=True)
class Progress:
    """A progress report for the CLI's bar: clips so far over the target, attempts, the last result."""

    clips: int
    requested: int
    attempts: int
    result: JobResult | None = None


def _is_clip(record: dict[str, Any], out: Path, sensors: bool) -> bool:
    if record.get("status") != STATUS_CLIP:
        return False
    return not sensors or (out / str(record.get("clip"))).is_dir()


def summarise(plan: CollectionPlan, records: list[dict[str, Any]], out: Path, sensors: bool) -> list[ScenarioSummary]:
    """Per-scenario attempts, clips, failures and their main reasons, from the run log's finished attempts."""
    finals = rl.final_records(records)
    out_list = []
    for sp in plan.scenarios:
        ids = {str(t.route.id) for t in sp.tasks}
        mine = [r for r in finals if str(r.get("route_id")) in ids]
        s = ScenarioSummary(sp.scenario, sp.target, routes_planned=len(sp.tasks), note=sp.error or "")
        reasons: Counter[str] = Counter()
        for r in mine:
            s.attempts += 1
            if _is_clip(r, out, sensors):
                s.clips += 1
            elif r.get("status") == STATUS_ERROR:
                s.errors += 1
                reasons[f"error: {str(r.get('reason', ''))[:80]}"] += 1
            else:
                s.failed += 1
                reasons[str(r.get("reason") or r.get("route_status") or "failed")] += 1
        s.reasons = dict(reasons.most_common())
        out_list.append(s)
    return out_list


def _write_summary(out: Path, summary: CollectSummary) -> None:
    target = out / SUMMARY_FILE
    temp = target.with_name(f".{target.name}.tmp-{os.getpid()}-000000")
    temp.write_text(json.dumps(summary.to_dict(), indent=2), encoding="utf-8")
    os.replace(temp, target)


def prepare_corpus(out: Path, config: CollectConfig) -> None:
    """Refuse to reuse a collection folder without ``resume``; remove what dead writers left behind."""
    log_path = out / rl.LOG_FILE
    if log_path.exists() and not config.resume:
        raise CollectError(
            f"{out} already holds a collection ({rl.LOG_FILE}); pass --resume to continue it, or choose another --out"
        )
    # Leftovers of dead processes only (the lock keeps other collections out; live writers' files are kept).
    removed = remove_temporaries(out)
    # Workers of a killed collection exit within a second (exit_with_parent); never run beside one.
    deadline = time.monotonic() + LIVE_WRITER_WAIT
    while (live := _live_temporaries(out)) and time.monotonic() < deadline:
        time.sleep(0.2)
        removed += remove_temporaries(out)
    if live:
        pids = ", ".join(sorted({str(pid) for _, pid in live}))
        raise CollectError(f"process(es) {pids} still write into {out} ({live[0][0].name}); stop them first")
    if removed:
        log.info("removed %d stale temporary file(s)/folder(s)", len(removed))


def collect(config: CollectConfig, progress: Callable[[Progress], None] | None = None) -> CollectSummary:
    """Run a collection to its targets (or until the routes run out); raises :class:`CollectError` on bad input."""
    t0 = time.monotonic()
    out = Path(config.out)
    if out.exists() and not out.is_dir():
        raise CollectError(f"--out {out} is a file, not a folder")
    validate_config(config)
    if (out / rl.LOG_FILE).exists() and not config.resume:
        raise CollectError(
            f"{out} already holds a collection ({rl.LOG_FILE}); pass --resume to continue it, or choose another --out"
        )
    with corpus_lock(out):
        prepare_corpus(out, config)
        plan = plan_collection(config)
        _check_settings(out, plan.settings, config.resume)
        if config.sensors:
            for town in plan.towns:
                ensure_hdmap(load_map(town), out)
        run_log = rl.RunLog(out / rl.LOG_FILE)
        records = rl.read_run_log(run_log.path)
        if config.resume:
            reconcile(out, records, config, run_log)
            interrupted = rl.interrupted_routes(records)
            if interrupted:
                log.info("%d route(s) were interrupted and run again: %s", len(interrupted), ", ".join(interrupted))
        session = _Session(plan, out, config, run_log, records, progress)
        attempts, clips = session.run()
        summary = CollectSummary(
            str(out),
            summarise(plan, records, out, config.sensors),
            attempts,
            clips,
            time.monotonic() - t0,
            list(plan.skipped),
            config.sensors,
        )
        _write_summary(out, summary)
        return summary


class _Session:
    """The launch loop of one ``collect`` call."""

    def __init__(
        self,
        plan: CollectionPlan,
        out: Path,
        config: CollectConfig,
        run_log: rl.RunLog,
        records: list[dict[str, Any]],
        progress: Callable[[Progress], None] | None,
    ) -> None:
        self.plan, self.out, self.config, self.run_log, self.records = plan, out, config, run_log, records
        self.progress = progress
        finals = rl.final_records(records)
        # A route whose attempts all ended in an error (a crash, not a verdict on the route) is tried again.
        attempted = {str(r.get("route_id")) for r in finals if r.get("status") != STATUS_ERROR}
        self.pending = {sp.scenario: deque(t for t in sp.tasks if str(t.route.id) not in attempted)
                        for sp in plan.scenarios}  # fmt: skip
        ids_of = {sp.scenario: {str(t.route.id) for t in sp.tasks} for sp in plan.scenarios}
        self.done = {sp.scenario: sum(1 for r in finals if str(r.get("route_id")) in ids_of[sp.scenario]
                                      and _is_clip(r, out, config.sensors)) for sp in plan.scenarios}  # fmt: skip
        self.attempts_before = sum(1 for r in finals if any(str(r.get("route_id")) in ids for ids in ids_of.values()))
        self.target = {sp.scenario: sp.target for sp in plan.scenarios}
        self.in_flight = {sp.scenario: 0 for sp in plan.scenarios}
        self.requested = sum(self.target.values())

    def _clips(self) -> int:
        return sum(min(self.done[s], self.target[s]) for s in self.done)

    def _next_task(self, order: deque[str]) -> RouteTask | None:
        """Round robin over scenarios that still need clips and have routes left."""
        for _ in range(len(order)):
            scenario = order[0]
            order.rotate(-1)
            need = self.target[scenario] - self.done[scenario] - self.in_flight[scenario]
            if need > 0 and self.pending[scenario]:
                return self.pending[scenario].popleft()
        return None

    def run(self) -> tuple[int, int]:
        """Launch and collect attempts until nothing is left to do; returns (attempts, clips) of this run."""
        attempts = clips = 0
        if self.progress is not None:
            self.progress(Progress(self._clips(), self.requested, self.attempts_before))
        backend = make_backend(self.out, self.config)
        order = deque(self.target)
        try:
            while True:
                while backend.running() < backend.capacity:
                    task = self._next_task(order)
                    if task is None:
                        break
                    self._launch(backend, task)
                if backend.running() == 0:
                    break
                for task, result in backend.wait():
                    self.in_flight[task.scenario] -= 1
                    attempts += 1
                    if result.status == STATUS_CLIP:
                        self.done[task.scenario] += 1
                        clips += 1
                    record = result.to_record()
                    self.run_log.append(record)
                    self.records.append(record)
                    if self.progress is not None:
                        self.progress(Progress(self._clips(), self.requested, self.attempts_before + attempts, result))
        finally:
            backend.close()
        return attempts, clips

    def _launch(self, backend: Backend, task: RouteTask) -> None:
        start = {"event": rl.EVENT_START, "route_id": str(task.route.id), "scenario": task.scenario,
                 "town": task.town.name, "seed": task.seed,
                 "time": datetime.now(timezone.utc).isoformat(timespec="milliseconds")}  # fmt: skip
        self.run_log.append(start)
        self.records.append(start)
        self.in_flight[task.scenario] += 1
        backend.submit(task)


def run_tasks(
    tasks: Sequence[RouteTask],
    out: str | os.PathLike[str],
    config: CollectConfig,
    on_result: Callable[[RouteTask, JobResult], None] | None = None,
) -> list[JobResult]:
    """Run every task once (no target, no resume) and log each attempt in ``<out>/run_log.jsonl``.

    For fixed route sets such as an expert success table; results come back in task order.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    run_log = rl.RunLog(out / rl.LOG_FILE)
    results: dict[int, JobResult] = {}
    index_of = {id(t): i for i, t in enumerate(tasks)}
    queue = deque(tasks)
    with corpus_lock(out):
        if config.sensors:
            for town in dict.fromkeys(t.town for t in tasks):
                ensure_hdmap(load_map(town), out)
        backend = make_backend(out, config)
        try:
            while queue or backend.running():
                while queue and backend.running() < backend.capacity:
                    backend.submit(queue.popleft())
                for task, result in backend.wait():
                    run_log.append(result.to_record())
                    results[index_of[id(task)]] = result
                    if on_result is not None:
                        on_result(task, result)
        finally:
            backend.close()
    return [results[i] for i in range(len(tasks))]


def summary_table(summary: CollectSummary) -> str:
    """The end-of-run table: per scenario attempts, clips, success rate and main failure reasons."""
    head = ("scenario", "clips", "attempts", "success", "main failure reasons")
    rows = []
    for s in summary.scenarios:
        reasons = "; ".join(f"{k} ×{v}" for k, v in list(s.reasons.items())[:3]) or ("—" if not s.note else s.note)
        rows.append(
            (s.scenario, f"{s.clips}/{s.requested}", str(s.attempts), f"{100 * s.success_rate:.0f}%", reasons[:90])
        )
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(head, widths)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
    return "\n".join(lines)
