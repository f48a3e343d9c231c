"""One collection job: drive one route with the expert on the builtin simulator and write it as one clip.

:func:`run_route_job` wires the pieces together: the town's map (loaded once per process), a
:class:`~b2d_data.sim.builtin.world.BuiltinSimulator` seeded for the route, the leaderboard's dense route, the
privileged :class:`~b2d_data.expert.Expert`, the :class:`~b2d_data.collection.data_agent.DataAgent` and a
:class:`~b2d_data.writers.ClipWriter` whose temporary folder becomes the clip only when the expert finished the route
without infraction (min-speed aside). Whatever happens inside, the job returns a :class:`JobResult`; it never raises.

Order of the on-disk effects (what resume relies on): the route's Leaderboard record ``<out>/results/<clip>.json`` is
written first, then the clip is closed into ``<out>/<clip>`` (or moved to ``<out>/failed/<clip>`` with
``keep_failed``, or dropped), and only then does the driver append the attempt to the run log. A worker that dies
between the rename and the driver's log line leaves a complete clip and its success record that no log line counts:
the driver runs the route again, and that attempt adopts them (:func:`finished_clip`) instead of failing on the
existing folder or recording a crash over them; a resume adopts them the same way (``corpus.reconcile``).
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import multiprocessing.util
import os
import shutil
import signal
import socket
import threading
import time
import traceback
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, fields, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from b2d_data.collection.disk_space import DISK_FULL, is_disk_full
from b2d_data.collection.layout import worker_context
from b2d_data.collection.progress import FrameReporter
from b2d_data.collection.towns import TownSource, ensure_hdmap, load_map
from b2d_data.codecs.format_info import read_format_info
from b2d_data.format import leaderboard as lb
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipName, ClipNameError, canonical_clip_prefix
from b2d_data.format.scenario_types import NO_SCENARIO
from b2d_data.format.version import DEFAULT_FORMAT, FormatVersion
from b2d_data.format.weather import PRESETS, WeatherParameters, weather_id_of
from b2d_data.scenarios.framework import ScenarioSetupError
from b2d_data.scenarios.route_xml import Route
from b2d_data.sim.api import RigConfig

log = logging.getLogger(__name__)

#: Leaderboard records of every attempt, one file per clip name (``b2d-eval summary <out>/results`` reads them).
RESULTS_DIR = "results"
#: Clips of failed routes kept with ``keep_failed``.
FAILED_DIR = "failed"

STATUS_CLIP = "clip"  # the expert succeeded; with sensors, the clip is in place
STATUS_FAILED = "failed"  # the route ran but the expert did not succeed
STATUS_ERROR = "error"  # the job could not run the route (exception)


@dataclass(frozen=True)
class CollectConfig:
    """Everything that decides what a collection produces (the CLI's options)."""

    out: Path
    scenarios: tuple[str, ...] = ()
    n: int = 1
    town: str | None = None  # generated preset; None: the default preset (unless xodr/routes say otherwise)
    xodr: Path | None = None  # an OpenDRIVE file, or a folder of <Town>.xodr files
    routes_file: Path | None = None
    weathers: tuple[int, ...] = ()
    workers: int = 1
    seed: int = 0
    resume: bool = False
    keep_failed: bool = False
    width: int = 1600
    height: int = 900
    lidar_azimuth_steps: int = 1000
    format_version: FormatVersion = DEFAULT_FORMAT
    sensors: bool = True
    #: Encoder processes per clip writer; None: automatic (several when one route runs at a time, else 0).
    encode_workers: int | None = None
    #: Routes tried per requested clip before a scenario gives up.
    attempts_per_clip: int = 3
    #: Ray cluster address (``auto`` or ``host:port``); None runs on this machine.
    ray_address: str | None = None
    #: Parameter ranges of generated routes (``training`` or ``bench2drive220``, see scenarios.param_ranges).
    params: str = "training"
    #: A Bench2Drive-sized corpus (``mini``, ``base``, ``full``, ``uniform``; collection.presets) instead of scenarios.
    preset: str | None = None
    #: The preset's clips scaled by this factor (collection.presets.scale).
    n_scale: float = 1.0

    def rig(self) -> RigConfig:
        """The sensor rig of this collection (top-down camera at the surround cameras' size)."""
        return RigConfig(
            width=self.width, height=self.height, top_down_width=self.width, top_down_height=self.height,
            lidar_azimuth_steps=self.lidar_azimuth_steps,
            radar_v004_mounts=FormatVersion(self.format_version) is FormatVersion.V004,
            float_depth=FormatVersion(self.format_version).float_depth,  # else only the uint8 depth PNG is written
            jpeg_planes="gpu",  # colour is only written as JPEG: converted on a GPU, no RGB read back
            png_rows=True,  # the labels are only written as PNG: laid out as its scanlines on a GPU
        )  # fmt: skip

    def resolved_encode_workers(self) -> int:
        """Encoder processes per clip: explicit value, else up to 4 when routes run one at a time, else none."""
        if self.encode_workers is not None:
            return max(0, int(self.encode_workers))
        if not self.sensors or self.workers > 1 or self.ray_address is not None:
            return 0
        return max(1, min(4, os.cpu_count() or 1))


@dataclass
class JobResult:
    """The outcome of one attempt; :meth:`to_record` is its run-log line."""

    route_id: str
    scenario: str
    town: str
    weather_id: int | None
    seed: int
    status: str
    success: bool = False
    clip: str | None = None
    #: Where the clip ended up relative to the corpus root (``<clip>``, ``failed/<clip>``), None when not kept.
    clip_path: str | None = None
    route_status: str = ""
    infractions: dict[str, int] = field(default_factory=dict)
    score_composed: float = 0.0
    score_route: float = 0.0
    frames: int = 0
    #: Bytes the attempt's clip writer wrote (the clip's size when kept; up to the error otherwise).
    bytes_written: int = 0
    ticks: int = 0
    duration_game: float = 0.0
    duration: float = 0.0
    reason: str = ""
    started: str = ""
    finished: str = ""
    timings: dict[str, float] = field(default_factory=dict)
    host: str = ""
    pid: int = 0
    error: str | None = None
    note: str = ""

    def to_record(self) -> dict[str, Any]:
        """The run-log line of this attempt."""
        return {"event": "attempt", **asdict(self)}

    @classmethod
    def from_record(cls, record: Mapping[str, Any]) -> JobResult:
        """Rebuild from a run-log line (unknown keys ignored, missing ones defaulted)."""
        names = {f.name for f in fields(cls)}
        values = {k: v for k, v in record.items() if k in names}
        for required in ("route_id", "scenario", "town", "weather_id", "seed", "status"):
            values.setdefault(required, None)
        values["route_id"] = str(values["route_id"])
        return cls(**values)


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def process_alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie counts as dead)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat.rsplit(")", 1)[-1].split()[0] != "Z"


def exit_with_parent(pid: int, interval: float = 0.5) -> None:
    """Kill this process soon after process ``pid`` dies, so that no worker outlives a killed collection.

    Pool workers started through a fork server are not children of the collection's process, so the kernel's
    parent-death signal does not reach them; a daemon thread watches the owner instead.
    """

    def watch() -> None:
        while True:
            time.sleep(interval)
            if not process_alive(pid):
                os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="b2d-owner-watch", daemon=True).start()


def ignore_interrupts() -> None:
    """Helper processes leave Ctrl-C to the collection's driver, which stops them (no traceback from each)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _encoder_init(owner_pid: int) -> None:
    from b2d_data.writers.frame_jobs import init_worker

    ignore_interrupts()
    init_worker()
    exit_with_parent(owner_pid)


_ENCODERS: dict[int, ProcessPoolExecutor] = {}
#: What an encoder process needs (a route process's own fork server would otherwise import the whole route's modules).
ENCODER_PRELOAD = ("b2d_data.writers.frame_jobs",)


def encoder_pool(workers: int) -> ProcessPoolExecutor | None:
    """This process's encoder pool for clip writers (kept across clips; its workers die with this process)."""
    if workers <= 0:
        return None
    pool = _ENCODERS.get(workers)
    if pool is not None and getattr(pool, "_broken", False):
        pool.shutdown(wait=False, cancel_futures=True)
        pool = None
    if pool is None:
        pool = ProcessPoolExecutor(
            workers, mp_context=worker_context(ENCODER_PRELOAD), initializer=_encoder_init, initargs=(os.getpid(),)
        )
        _ENCODERS[workers] = pool
        # When this process is itself a pool worker, its exit joins its children; the encoders live until their owner
        # dies, so that join would never return (a route pool with encoders hung at shutdown). Stop them first, and
        # before the exit closes the pool's call queue (its finalizers have priority 10): the stop travels on it.
        multiprocessing.util.Finalize(pool, pool.shutdown, kwargs={"wait": True, "cancel_futures": True},
                                      exitpriority=100)  # fmt: skip
    return pool


def shutdown_encoders() -> None:
    """Stop this process's encoder pools."""
    for pool in _ENCODERS.values():
        pool.shutdown(wait=True, cancel_futures=True)
    _ENCODERS.clear()


def clip_weather_id(route: Route) -> int:
    """The weather id in the clip name: the route's preset, else the closest preset (format.md §7.2)."""
    weather_id = route.weather_id
    if weather_id is not None:
        return weather_id
    first = route.weathers[0][1] if route.weathers else None
    return closest_weather_id(first) if first is not None else 26


def closest_weather_id(weather: WeatherParameters) -> int:
    """The preset whose weather.xml attributes are nearest to ``weather`` (exact match first)."""
    exact = weather_id_of(weather)
    if exact is not None:
        return exact
    attributes = {k: float(v) for k, v in weather.to_xml_attributes().items()}

    def distance(wid: int) -> float:
        other = PRESETS[wid].to_xml_attributes()
        return sum((attributes[k] - float(other[k])) ** 2 for k in attributes)

    return min(sorted(PRESETS), key=distance)


def clip_name_of(route: Route, town: str) -> ClipName:
    """``<Scenario>_<Town>_Route<id>_Weather<w>`` of a route; the route id must be an integer."""
    if not str(route.id).isdigit():
        raise ValueError(f"route id {route.id!r} is not a non-negative integer, which clip names need")
    scenario = canonical_clip_prefix(route.scenario_type) if route.scenario_type else NO_SCENARIO
    return ClipName(scenario, town, int(route.id), clip_weather_id(route))


def _reason_of(record: lb.RouteRecord) -> str:
    """Why a route is not a success: the failure message, else the infraction kinds."""
    if record.status.startswith(lb.STATUS_FAILED):
        _, _, message = record.status.partition(" - ")
        return message or record.status
    kinds = [k for k, v in record.infractions.items() if v and k != lb.MIN_SPEED_INFRACTIONS]
    return ", ".join(kinds) if kinds else record.status


def _write_json_atomic(results: lb.LeaderboardResults, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    temp = target.with_name(f".{target.name}.tmp-{os.getpid()}-{time.monotonic_ns() & 0xFFFFFF:06x}")
    try:
        lb.write_results(results, temp)
        os.replace(temp, target)
    finally:
        temp.unlink(missing_ok=True)


def write_route_results(out_root: Path, clip: str, record: lb.RouteRecord) -> Path:
    """``<out>/results/<clip>.json``: a one-route Leaderboard checkpoint file (written atomically)."""
    results = lb.LeaderboardResults(records=[record], progress=[1, 1])
    lb.finalize(results, 1)
    target = out_root / RESULTS_DIR / f"{clip}.json"
    _write_json_atomic(results, target)
    return target


def _crash_record(route: Route, town: str, message: str) -> lb.RouteRecord:
    """The record of a route that could not be run at all (the leaderboard's 'Simulation crashed')."""
    from b2d_data.scenarios import statistics

    return lb.RouteRecord(
        route_id=lb.record_route_id(route.id), scenario_name=statistics.scenario_name_of(route),
        weather_id=statistics.weather_id_of_route(route), status=f"{lb.STATUS_FAILED} - {message}",
        town_name=town, index=0,
    )  # fmt: skip


def recovered_result(path: Path, note: str = "recovered from results/ after an interruption") -> JobResult | None:
    """The attempt that a route record ``results/<clip>.json`` holds a verdict of; None for a crash record (no
    verdict on the route) or an unreadable file."""
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
        reason="" if success else record.status, note=note,
    )  # fmt: skip


#: ``JobResult.note`` of an attempt that found its route's clip finished by an earlier attempt and adopted it.
ADOPTED = "adopted the complete clip of an earlier attempt whose worker was lost"


def finished_clip(out: Path, route: Route, town: str) -> JobResult | None:
    """The attempt whose complete clip and success record are both in ``out`` (an earlier attempt of the route
    whose worker died after renaming the clip, before the driver heard of it); None when either is missing."""
    name = clip_name_of(route, town)
    try:
        info = read_format_info(out / str(name))
    except (B2DFormatError, OSError):
        return None
    if info is None:
        return None  # no clip, or a folder without b2d_format.json: never a finished clip
    result = recovered_result(out / RESULTS_DIR / f"{name}.json", note=ADOPTED)
    if result is None or not result.success:
        return None
    result.clip_path = str(name)
    result.frames = int(info.frames)
    return result


class _FrameSink:
    """The route runner's frame callback: read the sensors, build the record, hand it to the writer.

    Unless every failed clip is kept, the clip is dropped at the first ego collision the route criteria are bound
    to count (a moving ego hitting a vehicle, walker or layout object): the route can no longer succeed, so the
    rest of the run is physics only, which is all its record needs.
    """

    def __init__(self, sim: Any, agent: Any, expert: Any, writer: Any, keep_failed: bool) -> None:
        self.sim, self.agent, self.expert, self.writer = sim, agent, expert, writer
        self.keep_failed = keep_failed
        self.frames = 0
        self.dropped_at: int | None = None
        self.sensor_time = self.anno_time = self.write_time = 0.0

    def __call__(self, snapshot: Any, info: Any) -> None:
        if self.dropped_at is not None:
            return
        if not self.keep_failed and _counted_collision(snapshot, info.ego_id):
            self.writer.abort()
            self.dropped_at = info.frame_index
            log.info(
                "frame %d: the ego collided; the clip is dropped, the route runs on without sensors", info.frame_index
            )
            return
        t0 = time.perf_counter()
        sensors = self.sim.read_sensors()
        t1 = time.perf_counter()
        record = self.agent.make_record(info.frame_index, snapshot, sensors, info.ego_id, self.expert.state)
        t2 = time.perf_counter()
        self.writer.write(record)
        t3 = time.perf_counter()
        self.frames += 1
        self.sensor_time += t1 - t0
        self.anno_time += t2 - t1
        self.write_time += t3 - t2


def _reporting(sink: _FrameSink | None, reporter: FrameReporter) -> Any:
    """The frame callback: report the route's progress to the driver, then record the frame (if sensors)."""

    def on_frame(snapshot: Any, info: Any) -> None:
        reporter(info.frame_index + 1, info.score_route)
        if sink is not None:
            sink(snapshot, info)

    return on_frame


def _counted_collision(snapshot: Any, ego_id: int) -> bool:
    """An ego collision that CollisionTest always counts when it is the first one (so the route fails)."""
    ego = snapshot.actors.get(ego_id)
    if ego is None:
        return False
    speed = math.hypot(ego.velocity.x, ego.velocity.y)
    return any(
        c.actor_id == ego_id and lb.collision_key(c.other_type_id) is not None and speed >= 0.1
        for c in snapshot.collisions
    )


class _StrictScenarios:
    """The route runner's default scenario manager, refusing to drop any of the route's scenarios.

    The leaderboard drops a scenario that cannot be set up and drives the route without it; a clip named after that
    scenario would then not show it, so here the route stops at once (the runner turns the error into a crashed
    route) and the job reports why.
    """

    def __init__(self) -> None:
        self.problem: str | None = None

    def __call__(self, setup: Any) -> Any:
        from b2d_data.scenarios.route_runner import default_scenario_manager

        manager = default_scenario_manager(setup)
        wanted = [c.name for c in setup.route.scenarios]
        running = [s.name for s in getattr(manager, "scenarios", ())]
        if len(running) < len(wanted):
            missing = [name for name in wanted if name not in running] or wanted
            self.problem = (
                f"scenario(s) {', '.join(missing)} could not be set up on route {setup.route.id} "
                "(see the warnings above)"
            )
            manager.cleanup(None)
            raise ScenarioSetupError(self.problem)
        return manager


def run_route_job(
    route: Route, town: TownSource, out_root: str | os.PathLike[str], config: CollectConfig, seed: int
) -> JobResult:
    """Run one route into one clip (or, without sensors, into its record only); never raises."""
    out = Path(out_root)
    t_start = time.monotonic()
    result = JobResult(
        route_id=str(route.id), scenario=route.scenario_type or NO_SCENARIO, town=town.name,
        weather_id=None, seed=int(seed), status=STATUS_ERROR, started=_now(), host=socket.gethostname(),
        pid=os.getpid(),
    )  # fmt: skip
    try:
        result.weather_id = clip_weather_id(route)
        # A retry after a lost worker: that worker may have finished the clip before it died.
        adopted = finished_clip(out, route, town.name)
        if adopted is None:
            _run(route, town, out, config, int(seed), result)
    except Exception as exc:  # noqa: BLE001 - one bad route is a logged attempt, never a crashed collection
        # e.g. the clip appeared while this attempt ran: the lost worker was still finishing it
        adopted = _finished_clip_or_none(out, route, town.name)
        if adopted is None:
            _record_crash(route, town, out, result, exc)
    if adopted is not None:
        log.warning("route %s: %s (%s)", route.id, ADOPTED, adopted.clip)
        result = replace(adopted, started=result.started, host=result.host, pid=result.pid)
    result.duration = round(time.monotonic() - t_start, 3)
    result.finished = _now()
    return result


def _finished_clip_or_none(out: Path, route: Route, town: str) -> JobResult | None:
    try:
        return finished_clip(out, route, town)
    except Exception:  # noqa: BLE001 - e.g. a route id that makes no clip name: nothing to adopt
        return None


def _record_crash(route: Route, town: TownSource, out: Path, result: JobResult, exc: Exception) -> None:
    """Fill ``result`` with the error and write the route's 'Simulation crashed' record."""
    result.status = STATUS_ERROR
    result.success = False
    result.reason = f"{type(exc).__name__}: {exc}"
    if is_disk_full(exc):
        result.note = DISK_FULL  # the driver starts no new route
    result.error = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)[-12:])
    log.warning("route %s: job failed: %s", route.id, result.reason)
    log.debug("route %s traceback:\n%s", route.id, result.error)
    try:
        clip = str(clip_name_of(route, town.name))
        write_route_results(out, clip, _crash_record(route, town.name, "Simulation crashed"))
    except Exception:
        log.debug("route %s: no record written for the failed job", route.id, exc_info=True)


def _run(route: Route, town: TownSource, out: Path, config: CollectConfig, seed: int, result: JobResult) -> None:
    """The body of :func:`run_route_job`; fills ``result`` and raises on any error."""
    from b2d_data.expert import Expert, ExpertConfig
    from b2d_data.scenarios.junction_signals import with_scenario_lights
    from b2d_data.scenarios.route import DenseRoute
    from b2d_data.scenarios.route_runner import RouteRunner
    from b2d_data.sim.builtin.world import BuiltinSimulator

    t0 = time.perf_counter()
    town_map = load_map(town)
    if route.town != town_map.name:
        raise ValueError(f"route {route.id} is on {route.town} but the map is {town_map.name}")
    # CARLA's level has lights at some junctions its OpenDRIVE file leaves without (Town04, route 26944)
    world_map = with_scenario_lights(town_map, route)
    name = clip_name_of(route, world_map.name)
    result.clip = str(name)
    if (out / str(name)).exists():
        raise FileExistsError(f"clip {out / str(name)} already exists; a route id is never used for two clips")
    sim = BuiltinSimulator(world_map, seed=seed, weather=route.weather_at(0.0))
    writer = None
    try:
        dense = DenseRoute.from_route(world_map, route)
        expert = Expert(world_map, dense, ExpertConfig.for_builtin(), seed=seed)
        t_setup = time.perf_counter() - t0
        sink: _FrameSink | None = None
        on_start = None
        if config.sensors:
            from b2d_data.collection.data_agent import DataAgent
            from b2d_data.format.expert_feature import layout_record
            from b2d_data.writers import ClipWriter

            rig = config.rig()
            # the corpus's one HD map per town is the file's, whichever route happens to export it first
            hdmap = ensure_hdmap(town_map, out)
            agent = DataAgent(world_map, dense, rig)
            writer = ClipWriter(
                out, name, FormatVersion(config.format_version), hdmap=hdmap,
                executor=encoder_pool(config.resolved_encode_workers()),
                extra={"route_id": str(route.id), "seed": seed, "scenario": result.scenario,
                       "collector": "b2d-collect"},
                expert_feature=layout_record(),
            )  # fmt: skip
            sink = _FrameSink(sim, agent, expert, writer, config.keep_failed)

            def on_start(ego_id: int) -> None:
                t = time.perf_counter()
                sim.attach_rig(ego_id, rig)
                result.timings["attach_rig"] = round(time.perf_counter() - t, 3)

        scenarios = _StrictScenarios()
        runner = RouteRunner(
            sim,
            route,
            expert,
            seed=seed,
            record_every=2,
            on_frame=_reporting(sink, FrameReporter(str(route.id), str(name))),
            on_start=on_start,
            dense_route=dense,
            scenario_manager_factory=scenarios,
        )
        run = runner.run()
        record = run.record
        if scenarios.problem is not None:
            raise ScenarioSetupError(scenarios.problem)
        success = bool(run.success)
        if success and sink is not None and sink.dropped_at is not None:
            # Cannot happen while _counted_collision matches the criteria; never publish a clip with a hole.
            log.error("route %s succeeded although its clip was dropped at frame %d", route.id, sink.dropped_at)
            success = False
        record.extra["b2d_collect"] = {"seed": seed, "clip": str(name), "success": success}
        result.success = success
        result.route_status = record.status
        result.infractions = {k: len(v) for k, v in record.infractions.items() if v}
        result.score_composed = float(record.scores.score_composed)
        result.score_route = float(record.scores.score_route)
        result.frames = sink.frames if sink is not None else 0
        result.ticks = run.ticks
        result.duration_game = float(run.duration_game)
        result.reason = "" if success else _reason_of(record) if not run.success else "clip dropped early"
        if run.detail:
            result.reason = f"{result.reason}: {run.detail}"
        result.timings["setup"] = round(t_setup, 3)
        if sink is not None:
            result.timings.update(
                sensors=round(sink.sensor_time, 3), anno=round(sink.anno_time, 3), write=round(sink.write_time, 3)
            )
        # The record goes to disk before the clip appears: resume trusts a clip only with its record.
        write_route_results(out, str(name), record)
        result.status = STATUS_CLIP if success else STATUS_FAILED
        if writer is not None:
            t = time.perf_counter()
            if success:
                writer.close()
                result.clip_path = str(name)
            elif config.keep_failed and sink is not None and sink.frames > 0:
                writer.close()
                result.clip_path = move_to_failed(out, str(name))
            else:
                writer.abort()  # a no-op when the clip was already dropped
            result.bytes_written = writer.bytes_written
            result.timings["close"] = round(time.perf_counter() - t, 3)
            writer = None
    finally:
        if writer is not None:
            # What the attempt wrote before its error (a full disk's estimate of the space needed uses it).
            result.frames, result.bytes_written = writer.frames_written, writer.bytes_written
            writer.abort()
        sim.close()


def move_to_failed(out: Path, clip: str) -> str:
    """Move ``<out>/<clip>`` to ``<out>/failed/<clip>`` (replacing an older copy); returns the relative path."""
    target = out / FAILED_DIR / clip
    target.parent.mkdir(parents=True, exist_ok=True)
    if target.exists():
        shutil.rmtree(target)
    os.rename(out / clip, target)
    return f"{FAILED_DIR}/{clip}"


def with_weather(route: Route, weather_id: int) -> Route:
    """The route with its weathers replaced by one preset (at 0 and 100 %, as the generated routes have)."""
    weather = PRESETS[int(weather_id)]
    return replace(route, weathers=((0.0, weather), (100.0, weather)))
