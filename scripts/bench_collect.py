"""Per-frame cost of every collection stage, and the frames/s of the whole pipeline against its bound.

1. **Profile** (one process, every stage run serially so that CPU time is attributed cleanly): one route of a
   generated scenario run by the real collection job (expert, scenarios, background traffic, full rig, annotation,
   ClipWriter with inline encoding). Each stage is wrapped with a wall and process-CPU timer (exclusive of the
   stages nested in it): physics, expert, actor meshes and ray scenes, LiDAR, radar, draw + GPU wait, read-back,
   annotation, every encoder, file writes, and the rest of the route loop (scenarios, criteria). The first
   ``--warmup`` frames (shader compilation, static scene upload) are left out.
2. **Pipeline**: ``--routes`` routes of the same collection (or of a corpus preset, ``--preset``: many towns)
   through b2d-collect's own collection loop and process pool on ``--workers`` route processes (``auto``: the
   layout ``b2d-collect --workers auto`` picks), each route a target of one attempt; frames written over the wall
   time, route set-up included, the machine's CPU use (from /proc/stat), and where the route processes' time went
   (start-up, set-up of first and later routes, frame loops, the tail while the last routes finish).
   ``--town-affinity both`` runs it without and then with the loop's preference for a free worker's last town.

The bound is the frames/s the machine would reach if its busiest resource did nothing but the unavoidable
per-frame work measured in step 1: the CPU (cores / CPU-seconds per frame) or, with a hardware renderer, the GPU
(1 / seconds the CPU waited for the GPU per frame, as the GPU serves every process in turn).

    python scripts/bench_collect.py --frames 8 --routes 2 --workers 2       # the 2-core CPU machine
    python scripts/bench_collect.py --frames 60 --routes 32 --workers auto  # a GPU machine
    python scripts/bench_collect.py --preset base --n-scale 0.06 --routes 60 --frames 100 --skip-profile \
        --town-affinity both                                                # base's mix of towns

``--frames`` caps each route (0: run the routes to their end); capped routes end as TickRuntime failures and
their clips are dropped after being written, which costs the same encoding work.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import threading
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

# The profile runs the route in this process: like a route process of a collection (whose environment
# b2d_data.collection.layout.single_thread_environment sets), its BLAS pool must have one thread, and OpenBLAS reads
# this when numpy loads. With a pool per core, LiDAR's small matrix products spin idle threads: 13 of its 36 CPU ms
# per frame on the 2-core machine.
for _key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_key, "1")

from b2d_data.collection import job as job_module
from b2d_data.collection.layout import (
    auto_layout,
    count_gpus,
    single_thread_worker,
)
from b2d_data.collection.plan import plan_collection

#: Bench2Drive-full: 4.26 TB for about 2 million frames.
B2D_FULL_BYTES_PER_FRAME = 4.26e12 / 2.0e6

# ---------------------------------------------------------------------------------------------- the stage timer


def thread_cpu() -> dict[int, tuple[str, float]]:
    """CPU seconds so far of each thread of this process, with its name (Linux; empty elsewhere)."""
    out = {}
    tick = os.sysconf("SC_CLK_TCK")
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tids:
        try:
            stat = Path(f"/proc/self/task/{tid}/stat").read_text()
        except OSError:
            continue
        name, fields = stat[stat.index("(") + 1 : stat.rindex(")")], stat.rsplit(")", 1)[1].split()
        out[int(tid)] = (name, (int(fields[11]) + int(fields[12])) / tick)
    return out


class StageTimer:
    """Wall and process-CPU seconds per named stage, each exclusive of the timed stages nested inside it."""

    def __init__(self) -> None:
        self.wall: dict[str, float] = defaultdict(float)
        self.cpu: dict[str, float] = defaultdict(float)
        self.calls: Counter[str] = Counter()
        self.bytes: Counter[str] = Counter()  # what the encoders report as written
        self._stack: list[list[float]] = []
        self.threads_at_start = thread_cpu()
        self.started_wall = time.perf_counter()
        self.started_cpu = time.process_time()

    def reset(self) -> None:
        """Forget everything measured so far (call between stages, with nothing on the stack)."""
        self.wall.clear()
        self.cpu.clear()
        self.calls.clear()
        self.bytes.clear()
        self.threads_at_start = thread_cpu()
        self.started_wall = time.perf_counter()
        self.started_cpu = time.process_time()

    @property
    def depth(self) -> int:
        """Timed calls currently running."""
        return len(self._stack)

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` timed as stage ``name``."""

        def timed(*args: Any, **kwargs: Any) -> Any:
            children = [0.0, 0.0]
            self._stack.append(children)
            w0, c0 = time.perf_counter(), time.process_time()
            try:
                out = fn(*args, **kwargs)
                if name.startswith("encode") and isinstance(out, int):
                    self.bytes[name] += out
                return out
            finally:
                dw, dc = time.perf_counter() - w0, time.process_time() - c0
                self._stack.pop()
                self.wall[name] += dw - children[0]
                self.cpu[name] += dc - children[1]
                self.calls[name] += 1
                if self._stack:
                    self._stack[-1][0] += dw
                    self._stack[-1][1] += dc

        return timed

    def patch(self, owner: Any, attr: str, name: str) -> None:
        """Replace ``owner.attr`` by its timed version."""
        setattr(owner, attr, self.wrap(name, getattr(owner, attr)))


class _InlineExecutor:
    """Runs submitted work at once, so that the ray casting does not overlap (and blur) the rendering."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future, as a pool would
            future.set_exception(exc)
        return future

    def shutdown(self, wait: bool = True) -> None:
        pass


def _cap_ticks(max_ticks: int) -> None:
    """Make every RouteRunner of this process stop after ``max_ticks`` ticks (0: no cap)."""
    if max_ticks <= 0:
        return
    from b2d_data.scenarios import route_runner

    class CappedRunner(route_runner.RouteRunner):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            kwargs["max_ticks"] = max_ticks
            super().__init__(*args, **kwargs)

    route_runner.RouteRunner = CappedRunner  # type: ignore[misc]


def instrument(timer: StageTimer, warmup: int) -> dict[str, int]:
    """Wrap every stage of the collection job in this process; returns a counter of timed frames."""
    from b2d_data.codecs import _source, depth, expert_npz, jpeg, labels_png, laz
    from b2d_data.collection.data_agent import DataAgent
    from b2d_data.expert import Expert
    from b2d_data.sim.builtin import world
    from b2d_data.sim.builtin.sensors import lidar, radar, renderer, suite
    from b2d_data.writers import clip_writer, frame_jobs

    state = {"frames": 0, "seen": 0, "reset_pending": 0}

    # Physics: the world tick; a pending reset happens here, at the top of the route loop (nothing is timed then).
    tick = timer.wrap("physics: world tick + traffic", world.BuiltinSimulator.tick)

    def tick_and_reset(self: Any) -> Any:
        if state["reset_pending"] and timer.depth == 0:
            timer.reset()
            state["reset_pending"] = 0
            state["frames"] = 0
        return tick(self)

    world.BuiltinSimulator.tick = tick_and_reset  # type: ignore[method-assign]
    timer.patch(Expert, "run_step", "expert")
    suite.ThreadPoolExecutor = _InlineExecutor  # type: ignore[misc,assignment]
    timer.patch(suite.SensorSuite, "capture", "sensors: actor meshes, ray scene, IMU/GNSS")
    timer.patch(lidar.Lidar, "scan", "sensors: LiDAR rays")
    timer.patch(radar.Radar, "scan", "sensors: radar rays")
    # On a hardware GPU the rays go to the GPU caster instead (RigConfig.gpu_rays): started before the draws,
    # collected (hits turned into points and detections) after the read-back.
    timer.patch(suite.SensorSuite, "_submit_rays", "sensors: LiDAR + radar rays, GPU submit")
    timer.patch(suite.SensorSuite, "_collect_rays", "sensors: LiDAR + radar rays, GPU collect")
    timer.patch(renderer.Renderer, "render", "render: colour planes + read-back")
    draw = timer.wrap("render: draw calls (CPU)", renderer.Renderer._draw)
    gpu_wait = timer.wrap("render: GPU wait (glFinish)", lambda ctx: ctx.finish())

    def draw_and_finish(self: Any, *args: Any, **kwargs: Any) -> Any:
        targets = draw(self, *args, **kwargs)
        gpu_wait(self.ctx)
        return targets

    renderer.Renderer._draw = draw_and_finish  # type: ignore[method-assign]
    make_record = timer.wrap("annotation", DataAgent.make_record)

    def record_and_count(self: Any, index: int, *args: Any, **kwargs: Any) -> Any:
        out = make_record(self, index, *args, **kwargs)
        state["seen"] += 1
        state["frames"] += 1
        if state["seen"] == warmup:
            state["reset_pending"] = 1
        return out

    DataAgent.make_record = record_and_count  # type: ignore[method-assign]
    timer.patch(clip_writer.ClipWriter, "write", "writer: checks + jobs")
    timer.patch(clip_writer.ClipWriter, "abort", "writer: close / abort")
    timer.patch(clip_writer.ClipWriter, "close", "writer: close / abort")
    encoders = {
        "write_jpeg": "encode: RGB JPEG x7", "write_jpeg_planes": "encode: RGB JPEG x7", "write_depth_png": "encode: depth PNG x6",
        "write_semantic_png": "encode: semantic PNG x6", "write_instance_png": "encode: instance PNG x6",
        "write_laz": "encode: LiDAR LAZ", "write_radar": "encode+write: radar h5",
        "write_anno": "encode+write: annotation json.gz", "write_expert": "encode: expert npz",
    }  # fmt: skip
    for attr, name in encoders.items():
        if hasattr(frame_jobs, attr):
            timer.patch(frame_jobs, attr, name)
    writes = timer.wrap("file writes", _source.write_bytes)
    for module in (jpeg, depth, labels_png, laz, expert_npz):
        module.write_bytes = writes  # type: ignore[attr-defined]
    return state


# ---------------------------------------------------------------------------------------------- the two runs


def profile(config: Any, task: Any, frames: int, warmup: int) -> tuple[StageTimer, int, Any]:
    """Run one route with every stage timed; returns the timer, the frames timed and the job result."""
    single_thread_worker()  # as in a route process of a parallel collection: CPU figures of one thread each
    timer = StageTimer()
    state = instrument(timer, warmup)
    _cap_ticks(2 * (frames + warmup) if frames > 0 else 0)
    cfg = replace(config, encode_workers=0)
    result = job_module.run_route_job(task.route, task.town, config.out, cfg, task.seed)
    wall, cpu = time.perf_counter() - timer.started_wall, time.process_time() - timer.started_cpu
    timer.wall["route loop: scenarios, criteria, rest"] = wall - sum(timer.wall.values())
    timer.cpu["route loop: scenarios, criteria, rest"] = cpu - sum(timer.cpu.values())
    return timer, state["frames"], result


_worker_ready = False


@dataclass(frozen=True)
class CappedRouteJob:
    """The pipeline's route job: b2d-collect's, with the ticks capped at ``max_ticks`` (0: none) and, with ``pin``,
    the process pinned to one core (so that every thread pool sizes itself to one core), from a process's first
    route on. Handed to the pool with every task, as the job always is."""

    max_ticks: int
    pin: bool = False

    def __call__(self, route: Any, town: Any, out: Path, config: Any, seed: int) -> Any:
        global _worker_ready
        if not _worker_ready:
            _cap_ticks(self.max_ticks)
            if self.pin:
                cores = sorted(os.sched_getaffinity(0))
                os.sched_setaffinity(0, {cores[os.getpid() % len(cores)]})
            _worker_ready = True
        return job_module.run_route_job(route, town, out, config, seed)


def _busy_jiffies() -> tuple[int, int]:
    """(busy, total) CPU jiffies of the whole machine."""
    fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = fields[3] + fields[4]
    return sum(fields) - idle, sum(fields)


def pipeline(
    config: Any, tasks: list[Any], workers: int, frames: int, pin: bool = False, town_affinity: bool = True
) -> tuple[int, float, float, list[Any]]:
    """Run ``tasks`` through b2d-collect's collection loop and process pool on ``workers`` processes, each task a
    target of one attempt; returns (frames, wall seconds, busy cores on average, results)."""
    from b2d_data.collection import run_log as rl
    from b2d_data.collection import runner
    from b2d_data.collection.backends import ProcessPoolBackend
    from b2d_data.collection.job import JobResult
    from b2d_data.collection.plan import CollectionPlan, ScenarioPlan

    targets = [ScenarioPlan(t.scenario, 1, [replace(t, group=f"#{i}")], group=f"#{i}") for i, t in enumerate(tasks)]
    out = Path(config.out)
    session = runner._Session(CollectionPlan(targets, towns=[], settings={}), out, config,
                              rl.RunLog(out / rl.LOG_FILE), [], None)  # fmt: skip
    lookahead = runner.TOWN_LOOKAHEAD
    runner.TOWN_LOOKAHEAD = lookahead if town_affinity else 0
    busy0, total0 = _busy_jiffies()
    t0 = time.perf_counter()
    try:
        session.run(ProcessPoolBackend(out, config, workers, job=CappedRouteJob(2 * max(frames, 0), pin)))
    finally:
        runner.TOWN_LOOKAHEAD = lookahead
    wall = time.perf_counter() - t0
    ended = datetime.now(timezone.utc)
    busy1, total1 = _busy_jiffies()
    cores = os.cpu_count() or 1
    busy_cores = cores * (busy1 - busy0) / max(1, total1 - total0)
    results = [JobResult.from_record(r) for r in session.records if r.get("event") == "attempt"]
    for r in results:  # seconds from the pool's start to the route's start and end, for the timeline
        r.timings["t_start"] = (datetime.fromisoformat(r.started) - ended).total_seconds() + wall
        r.timings["t_end"] = (datetime.fromisoformat(r.finished) - ended).total_seconds() + wall
    return sum(r.frames for r in results), wall, busy_cores, results


def route_setup_s(result: Any) -> float:
    """A route's set-up in seconds (map, scene, scenario placement, mounting the rig): its time outside the frames."""
    return result.timings.get("setup", 0.0) + result.timings.get("attach_rig", 0.0)


def loop_s(result: Any) -> float:
    """A route's frame loop in seconds: its time less its set-up."""
    return max(0.0, result.duration - route_setup_s(result))


def timeline(results: list[Any], wall: float, workers: int) -> dict[str, float]:
    """Where the route processes' time went, as shares of workers × wall: start-up before each process's first
    route, the routes' set-up (first route of a process apart), their frame loops, and the tail after its last."""
    by_pid: dict[int, list[Any]] = {}
    for r in sorted(results, key=lambda r: r.timings["t_start"]):
        by_pid.setdefault(r.pid, []).append(r)
    total = workers * wall
    first = [route_setup_s(rs[0]) for rs in by_pid.values()]
    later = sum(map(route_setup_s, results)) - sum(first)
    return {
        "start_up": sum(rs[0].timings["t_start"] for rs in by_pid.values()) / total,
        "tail": (sum(wall - rs[-1].timings["t_end"] for rs in by_pid.values())
                 + wall * max(0, workers - len(by_pid))) / total,  # fmt: skip
        "setup_first_routes": sum(first) / total,
        "setup_later_routes": later / total,
        "loops": sum(map(loop_s, results)) / total,
        "first_route_setup_s": sum(first) / max(1, len(first)),
        "later_route_setup_s": later / max(1, len(results) - len(first)),
    }


# ---------------------------------------------------------------------------------------------- main


def _tasks(config: Any, count: int) -> list[Any]:
    """The first ``count`` planned routes, round robin over the scenarios."""
    plan = plan_collection(config)
    lists = [list(sp.tasks) for sp in plan.scenarios if sp.tasks]
    out: list[Any] = []
    while len(out) < count and any(lists):
        for tasks in lists:
            if tasks and len(out) < count:
                out.append(tasks.pop(0))
    if len(out) < count:
        raise SystemExit(f"only {len(out)} routes planned; raise --n or add scenarios")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", action="append", default=[], help="scenario (repeatable; default HardBreakRoute)")
    parser.add_argument("--frames", type=int, default=8, help="frames per route (0: whole routes)")
    parser.add_argument("--warmup", type=int, default=3, help="profiled frames left out at the start")
    parser.add_argument("--profile-frames", type=int, default=None, help="frames profiled (default: --frames, or 40)")
    parser.add_argument("--routes", type=int, default=2, help="routes in the pipeline run")
    parser.add_argument("--workers", default="auto", help="route processes in the pipeline run, or auto")
    parser.add_argument("--encode-workers", type=int, default=None, help="encoder processes per route process")
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=900)
    parser.add_argument("--town", default=None, help="generated town preset (default: the collection default)")
    parser.add_argument("--preset", default=None, help="take the routes of a corpus preset instead (e.g. base; many "
                        "towns), first attempts first")  # fmt: skip
    parser.add_argument("--n-scale", type=float, default=1.0, help="with --preset: its share of the clips")
    parser.add_argument("--town-affinity", choices=("on", "off", "both"), default="on",
                        help="free workers take routes on their last town first, as b2d-collect does (both: a run "
                        "without, then one with, in this call)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--pin", action="store_true", help="pin each route process to one core (experiment)")
    parser.add_argument("--profile-route", type=int, default=0,
                        help="which of the pipeline's routes the profile runs (index; each has its own weather)")
    parser.add_argument("--skip-profile", action="store_true")
    parser.add_argument("--skip-pipeline", action="store_true")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures to this file")
    parser.add_argument("--out", type=Path, default=None,
                        help="where the scratch folder goes (default: the system's temporary folder)")
    args = parser.parse_args()

    cores = os.cpu_count() or 1
    gpus = count_gpus()
    layout = auto_layout(cores, gpus)
    workers = layout.workers if args.workers == "auto" else int(args.workers)
    encode_workers = args.encode_workers if args.encode_workers is not None else (
        layout.encode_workers if args.workers == "auto" else None)  # fmt: skip
    scenarios = tuple(args.scenario) or ("HardBreakRoute",)
    figures: dict[str, Any] = {"cores": cores, "gpus": gpus, "width": args.width, "height": args.height}
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=args.out) as scratch:
        from b2d_data.collection.job import CollectConfig
        from b2d_data.collection.towns import ensure_hdmap, load_map

        n = max(1, (args.routes + len(scenarios) - 1) // len(scenarios))
        base = CollectConfig(out=Path(scratch), scenarios=scenarios, n=n, town=args.town, width=args.width,
                             height=args.height, seed=args.seed, workers=max(1, workers),
                             encode_workers=encode_workers)  # fmt: skip
        if args.preset is not None:
            base = replace(base, scenarios=(), n=None, preset=args.preset, n_scale=args.n_scale)
        planned = _tasks(base, max(1, args.routes, args.profile_route + 1))
        tasks = planned[: max(1, args.routes)]
        profile_config = replace(base, out=base.out / "profile")  # the profiled route may also have made a clip
        modes = {"on": (True,), "off": (False,), "both": (False, True)}[args.town_affinity]
        runs = {affinity: replace(base, out=base.out / f"pipeline-{'on' if affinity else 'off'}") for affinity in modes}
        for town in dict.fromkeys(t.town for t in planned):
            for config in (profile_config, *runs.values()):
                ensure_hdmap(load_map(town), config.out)
        if not args.skip_pipeline:
            towns = len({t.town.name for t in tasks})
            for affinity, config in runs.items():
                print(f"pipeline: {len(tasks)} routes on {towns} town(s) × ≤{args.frames or 'all'} frames on {workers} "
                      f"route processes (encoders per process: {base.resolved_encode_workers()}), {cores} cores, "
                      f"{gpus} GPU(s), town affinity {'on' if affinity else 'off'} ...", flush=True)  # fmt: skip
                run = pipeline(config, tasks, workers, args.frames, args.pin, affinity)
                if len(modes) > 1 and not affinity:
                    figures["without_town_affinity"] = {**_pipeline_figures(*run, workers),
                                                        "encode_workers": base.resolved_encode_workers()}
                    _report_pipeline(figures["without_town_affinity"], cores)
            figures.update(_pipeline_figures(*run, workers), encode_workers=base.resolved_encode_workers())
        if not args.skip_profile:
            profiled = args.profile_frames if args.profile_frames is not None else (args.frames or 40)
            print("profile: one route, every stage serial ...", flush=True)
            timer, timed, result = profile(profile_config, planned[args.profile_route], profiled, args.warmup)
            if result.status == "error":
                raise SystemExit(f"the profiled route failed: {result.reason}\n{result.error}")
            figures.update(_report_profile(timer, timed, result))
    _report(figures)
    if args.json is not None:
        args.json.write_text(json.dumps(figures, indent=2, default=float))


def _pipeline_figures(frames: int, wall: float, busy: float, results: list[Any], workers: int) -> dict[str, Any]:
    """The pipeline's figures: frames/s over the wall and in the frame loops, where the route processes' time went."""
    f: dict[str, Any] = {}
    errors = [r.reason for r in results if r.status == "error"]
    loops = sum(map(loop_s, results))  # the frame loops alone
    f["loop_fps"] = frames / (loops / workers) if loops > 0 else 0.0
    # Where a route process's time went, per frame written (wall ms), and its set-up per route (s).
    parts = {k: sum(r.timings.get(k, 0.0) for r in results) for k in ("sensors", "anno", "write")}
    f["pipeline_ms_per_frame"] = {
        **{k: round(1e3 * v / max(1, frames), 1) for k, v in parts.items()},
        "rest of the loop": round(1e3 * (loops - sum(parts.values())) / max(1, frames), 1),
    }
    # Route-process time outside any route: pool start-up, and the last routes' tail while others idle.
    f["route_share_of_wall"] = round(sum(r.duration for r in results) / (workers * wall), 3)
    f["timeline"] = {k: round(v, 3) for k, v in timeline(results, wall, workers).items()}
    f["setup_s_per_route"] = round(sum(map(route_setup_s, results)) / len(results), 2)
    f["rig_s_per_route"] = round(sum(r.timings.get("attach_rig", 0.0) for r in results) / len(results), 2)
    # The first route of a process builds the town's scene, later ones of the same town reuse it: the first
    # quartile shows what mounting costs without the build.
    f["rig_s_first_quartile"] = round(sorted(r.timings.get("attach_rig", 0.0) for r in results)[len(results) // 4], 2)
    f.update(pipeline_frames=frames, pipeline_wall_s=round(wall, 2), pipeline_fps=frames / wall,
             busy_cores=round(busy, 2), workers=workers, errors=errors)  # fmt: skip
    return f


def _report_profile(timer: StageTimer, frames: int, result: Any) -> dict[str, Any]:
    if frames == 0:
        raise SystemExit("no frame was profiled after the warm-up; raise --frames")
    print(f"\nPer-frame cost, one process, {frames} frames after warm-up (route {result.route_id}, "
          f"{result.scenario}, weather {result.weather_id}):")  # fmt: skip
    print(f"| {'stage':<44} | wall ms | CPU ms | calls/frame |")
    print(f"|{'-' * 46}|--------:|-------:|------------:|")
    stages = {}
    for name in sorted(timer.wall, key=lambda k: -timer.cpu[k]):
        wall, cpu = 1e3 * timer.wall[name] / frames, 1e3 * timer.cpu[name] / frames
        stages[name] = {"wall_ms": round(wall, 2), "cpu_ms": round(cpu, 2)}
        print(f"| {name:<44} | {wall:7.1f} | {cpu:6.1f} | {timer.calls[name] / frames:11.1f} |")
    wall = 1e3 * sum(timer.wall.values()) / frames
    cpu = 1e3 * sum(timer.cpu.values()) / frames
    print(f"| {'total':<44} | {wall:7.1f} | {cpu:6.1f} |             |")
    by_name: Counter[str] = Counter()
    for tid, (name, cpu_s) in thread_cpu().items():
        by_name[name] += cpu_s - timer.threads_at_start.get(tid, (name, 0.0))[1]
    main_tid = threading.get_native_id()
    print("CPU ms per frame by thread name (the stage table counts all threads of the process):")
    print("  " + ", ".join(f"{n}{' (main)' if n == thread_cpu().get(main_tid, ('',))[0] else ''}: "
                           f"{1e3 * c / frames:.1f}" for n, c in by_name.most_common(8) if c > 0))  # fmt: skip
    disk = {name: n / frames for name, n in timer.bytes.items()}
    total = sum(disk.values())
    print(
        f"\nDisk per frame: {total / 1e6:.3f} MB ({total / B2D_FULL_BYTES_PER_FRAME:.2f}x Bench2Drive-full's "
        f"{B2D_FULL_BYTES_PER_FRAME / 1e6:.1f} MB: 4.26 TB / ~2 M frames)"
    )
    for name, n in sorted(disk.items(), key=lambda kv: -kv[1]):
        print(f"  {name.split(': ', 1)[1]:<28} {n / 1e3:8.1f} KB")
    render = ("render: GPU wait (glFinish)",)
    gpu_ms = sum(max(0.0, stages[s]["wall_ms"] - stages[s]["cpu_ms"]) for s in render if s in stages)
    return {"profile_frames": frames, "stages": stages, "disk_bytes_per_frame": total, "disk": disk, "cpu_ms_per_frame": cpu, "wall_ms_per_frame": wall,
            "gpu_wait_ms_per_frame": gpu_ms}  # fmt: skip


def _report_pipeline(f: dict[str, Any], cores: int) -> None:
    print(
        f"pipeline: {f['pipeline_frames']} frames in {f['pipeline_wall_s']:.1f} s = "
        f"{f['pipeline_fps']:.2f} frames/s on {f['workers']} route processes "
        f"(encoders each: {f['encode_workers']}); {f['busy_cores']:.1f} of {cores} cores busy on average"
    )
    print(f"  frame loops alone (route set-up left out): {f['loop_fps']:.2f} frames/s")
    per_frame = ", ".join(f"{k} {v:.1f}" for k, v in f["pipeline_ms_per_frame"].items())
    print(f"  route process wall ms per frame: {per_frame}; set-up {f['setup_s_per_route']:.1f} s per route, "
          f"of which mounting the rig {f['rig_s_per_route']:.2f} s (first quartile {f['rig_s_first_quartile']:.2f} s)")
    print(f"  route processes spent {100 * f['route_share_of_wall']:.0f} % of the wall in routes (the rest: "
          "pool start-up, and the tail while the last routes finish)")
    t = f["timeline"]
    print(f"  route processes' time: start-up {100 * t['start_up']:.1f} %, set-up of first routes "
          f"{100 * t['setup_first_routes']:.1f} % ({t['first_route_setup_s']:.2f} s each), of later routes "
          f"{100 * t['setup_later_routes']:.1f} % ({t['later_route_setup_s']:.2f} s each), frame loops "
          f"{100 * t['loops']:.1f} %, tail {100 * t['tail']:.1f} %")
    if f["errors"]:
        print(f"  {len(f['errors'])} route(s) failed with an error: {f['errors'][:3]}")


def _report(f: dict[str, Any]) -> None:
    from b2d_data.sim.builtin.sensors.renderer import create_gl_context

    print()
    cores = f["cores"]
    if "cpu_ms_per_frame" in f:
        ctx = create_gl_context()
        gl = ctx.info.get("GL_RENDERER", "?")
        ctx.release()
        hardware = not any(s in gl.lower() for s in ("llvmpipe", "softpipe", "swrast", "software"))
        cpu_bound = cores / (f["cpu_ms_per_frame"] / 1e3)
        bound, why = cpu_bound, f"CPU: {cores} cores / {f['cpu_ms_per_frame'] / 1e3:.3f} CPU-s per frame"
        if hardware and f["gpu_wait_ms_per_frame"] > 0:
            gpu_bound = 1e3 / f["gpu_wait_ms_per_frame"]
            if gpu_bound < bound:
                bound, why = gpu_bound, f"GPU: 1 / {f['gpu_wait_ms_per_frame'] / 1e3:.4f} s GPU wait per frame"
        f.update(renderer=gl, bound_fps=bound, bound_reason=why)
        print(f"renderer: {gl}")
        print(f"bound: {bound:.1f} frames/s ({why})")
    if "pipeline_fps" in f:
        if "without_town_affinity" in f:
            ratio = f["pipeline_fps"] / f["without_town_affinity"]["pipeline_fps"]
            f["town_affinity_ratio"] = ratio
            print(f"town affinity: {f['without_town_affinity']['pipeline_fps']:.2f} → {f['pipeline_fps']:.2f} frames/s "
                  f"(×{ratio:.3f})")
        _report_pipeline(f, cores)
        if "bound_fps" in f:
            f["ratio"] = f["pipeline_fps"] / f["bound_fps"]
            print(f"ratio to the bound: {f['ratio']:.2f} (route set-up included)")


if __name__ == "__main__":
    main()
