"""The collection loop behind ``b2d-collect``: run attempts until each scenario has its clips, resume, summarise.

:func:`collect` plans the routes (``plan.py``), launches attempts in route order on a backend (``backends.py``),
never more than a scenario still needs (so the clips are the first ``n`` successes of its list, however many run
in parallel), appends each outcome to the run log, and writes ``summary.json``. ``corpus.py`` holds the folder's
lock and what a resume needs to recover after a crash.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from itertools import islice
from pathlib import Path
from typing import Any

from b2d_data.collection import run_log as rl
from b2d_data.collection.backends import WORKER_LOST, Backend, make_backend
from b2d_data.collection.disk_space import DISK_FULL, SpaceNeeded, space_needed
from b2d_data.collection.corpus import (
    ResumeReport,
    check_settings,
    corpus_lock,
    prepare_corpus,
    reconcile,
    record_discarded,
    record_interrupted,
    remove_temporaries,
)
from b2d_data.collection.job import (
    STATUS_CLIP,
    STATUS_ERROR,
    CollectConfig,
    JobResult,
)
from b2d_data.collection.plan import (
    CollectError,
    CollectionPlan,
    RouteTask,
    plan_collection,
    validate_config,
)
from b2d_data.collection.progress import (
    REFRESH_SECONDS,
    FrameReport,
    ProgressState,
    RouteProgress,
    describe_routes,
    format_seconds,
    frames_of,
)
from b2d_data.collection.towns import (
    ensure_hdmap,
    load_map,
)

log = logging.getLogger(__name__)

SUMMARY_FILE = "summary.json"
#: Targets looked at for a route on the town that a free worker has just left (see ``_Session._next_task``).
TOWN_LOOKAHEAD = 64
#: Times in a row a target may be passed over for a route on a free worker's town.
TOWN_PASSES = 64
#: Times a route whose worker died (killed, node lost) is run again in the same session before it counts as tried.
LOST_WORKER_RETRIES = 2


@dataclass
class ScenarioSummary:
    """One scenario's outcome over the whole corpus (every session of a resumed collection)."""

    scenario: str
    requested: int
    #: Attempts that tried the route: clips, failures and route errors (not ``lost``).
    attempts: int = 0
    clips: int = 0
    failed: int = 0
    errors: int = 0
    #: Attempts lost to the infrastructure (their worker died, a Ray node went away): no verdict on the route,
    #: which ran again; they count in neither ``attempts`` nor the success rate.
    lost: int = 0
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
    #: Attempts of this run that tried their route (lost ones apart, see ``ScenarioSummary.lost``).
    attempts_this_run: int = 0
    clips_this_run: int = 0
    wall_seconds: float = 0.0
    skipped_routes: list[str] = field(default_factory=list)
    sensors: bool = True
    lost_this_run: int = 0
    #: Set when a full disk stopped the run: the space the missing clips need.
    disk_full: SpaceNeeded | None = None
    #: A preset's split manifest and its clips per part (train, val); None for other collections.
    manifest: str | None = None
    manifest_clips: tuple[int, int] = (0, 0)
    #: A preset's official-list entries that have no clip slot, by reason (unknown scenario types ...).
    left_out: dict[str, int] = field(default_factory=dict)

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
            "lost_this_run": self.lost_this_run,
            "disk_full": None if self.disk_full is None else self.disk_full.to_dict(),
            "wall_seconds": round(self.wall_seconds, 3),
            "seconds_per_clip": None if self.seconds_per_clip is None else round(self.seconds_per_clip, 3),
            "skipped_routes": self.skipped_routes,
            **({"manifest": self.manifest, "manifest_clips": list(self.manifest_clips), "left_out": self.left_out}
               if self.manifest is not None else {}),
            "scenarios": [s.to_dict() for s in self.scenarios],
        }  # fmt: skip


@dataclass(frozen=True)
class Progress:
    """A progress report for the CLI: clips so far over the target, attempts, the last result (when one just
    finished), the running routes' frames, this session's elapsed time, its frame-based ETA, and on the first
    report of a resume what the resume kept and discarded. Sent at least every ``REFRESH_SECONDS`` while routes
    run (inline: with each frame report)."""

    clips: int
    requested: int
    attempts: int
    result: JobResult | None = None
    elapsed: float = 0.0
    #: Seconds left (None until a route length in frames can be estimated).
    eta: float | None = None
    routes: tuple[RouteProgress, ...] = ()
    #: Frames of a typical route of this collection (None before any estimate).
    typical_frames: float | None = None
    #: Frames recorded in this session.
    frames: int = 0
    resumed: ResumeReport | None = None

    def describe(self) -> str:
        """``Route12 Accident 123/~310 fr; Route14 ... | ETA 12:34`` for a progress line."""
        routes = describe_routes(self.routes, self.typical_frames)
        return f"{routes + ' | ' if routes else ''}ETA {format_seconds(self.eta)}"


#: ``JobResult.note`` of attempts lost to the infrastructure (a dead worker, a full disk), not run to a verdict.
LOST_NOTES = frozenset({WORKER_LOST, DISK_FULL})


def is_lost(record: dict[str, Any]) -> bool:
    """Whether a run-log attempt was lost to the infrastructure (its worker died, its disk was full) rather than
    run to its end."""
    return record.get("note") in LOST_NOTES


def _is_clip(record: dict[str, Any], out: Path, sensors: bool) -> bool:
    if record.get("status") != STATUS_CLIP:
        return False
    return not sensors or (out / str(record.get("clip"))).is_dir()


def summarise(plan: CollectionPlan, records: list[dict[str, Any]], out: Path, sensors: bool) -> list[ScenarioSummary]:
    """Per-scenario attempts, clips, failures and their main reasons, and the attempts lost with their worker,
    from the run log's finished attempts (the plans of one scenario, e.g. a preset's one per copied clip, add up to
    one row)."""
    by_route: dict[str, list[dict[str, Any]]] = {}
    for r in rl.final_records(records):
        by_route.setdefault(str(r.get("route_id")), []).append(r)
    rows: dict[str, ScenarioSummary] = {}
    reasons: dict[str, Counter[str]] = {}
    for sp in plan.scenarios:
        s = rows.get(sp.scenario)
        if s is None:
            s = rows[sp.scenario] = ScenarioSummary(sp.scenario, 0)
            reasons[sp.scenario] = Counter()
        s.requested += sp.target
        s.routes_planned += len(sp.tasks)
        if sp.error and sp.error not in s.note:
            s.note = f"{s.note}; {sp.error}" if s.note else sp.error
        for r in (r for t in sp.tasks for r in by_route.get(str(t.route.id), ())):
            if is_lost(r):
                s.lost += 1
                continue
            s.attempts += 1
            if _is_clip(r, out, sensors):
                s.clips += 1
            elif r.get("status") == STATUS_ERROR:
                s.errors += 1
                reasons[sp.scenario][f"error: {str(r.get('reason', ''))[:80]}"] += 1
            else:
                s.failed += 1
                reasons[sp.scenario][str(r.get("reason") or r.get("route_status") or "failed")] += 1
    for scenario, s in rows.items():
        s.reasons = dict(reasons[scenario].most_common())
    return list(rows.values())


def _write_summary(out: Path, summary: CollectSummary) -> None:
    target = out / SUMMARY_FILE
    temp = target.with_name(f".{target.name}.tmp-{os.getpid()}-000000")
    temp.write_text(json.dumps(summary.to_dict(), indent=2), encoding="utf-8")
    os.replace(temp, target)


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
        removed = prepare_corpus(out, config)
        plan = plan_collection(config)
        check_settings(out, plan.settings, config.resume)
        if config.sensors:
            for town in plan.towns:
                ensure_hdmap(load_map(town), out)
        run_log = rl.RunLog(out / rl.LOG_FILE)
        records = rl.read_run_log(run_log.path)
        resumed = None
        if config.resume:
            resumed = _resume(out, records, config, run_log, removed)
            log.info("%s", resumed.describe())
        session = _Session(plan, out, config, run_log, records, progress, resumed)
        attempts, clips = session.run()
        if session.retries:  # what the lost workers were writing
            remove_temporaries(out)
        scenarios = summarise(plan, records, out, config.sensors)
        summary = CollectSummary(
            str(out),
            scenarios,
            attempts,
            clips,
            time.monotonic() - t0,
            list(plan.skipped),
            config.sensors,
            session.lost,
            _space_needed(out, records, session, scenarios, config.sensors) if session.disk_full else None,
        )
        if plan.preset is not None:
            summary.left_out = plan.preset.left_out()
            if config.sensors:
                _write_preset_manifest(out, plan, records, config, summary)
        _write_summary(out, summary)
        return summary


def _space_needed(
    out: Path, records: list[dict[str, Any]], session: _Session, scenarios: list[ScenarioSummary], sensors: bool
) -> SpaceNeeded:
    """The space the missing clips need, from the corpus's clips or the attempts the full disk stopped."""
    finals = rl.final_records(records)
    clip_dirs = [out / str(r.get("clip")) for r in finals if _is_clip(r, out, sensors) and sensors]
    stopped = [r for r in finals if r.get("note") == DISK_FULL]
    missing = sum(max(s.requested - s.clips, 0) for s in scenarios)
    return space_needed(out, clip_dirs, stopped, missing, session.state.typical_frames())


def _write_preset_manifest(
    out: Path, plan: CollectionPlan, records: list[dict[str, Any]], config: CollectConfig, summary: CollectSummary
) -> None:
    """The preset's split manifest of the clips made so far (rewritten by every session, so a resume completes it)."""
    from b2d_data.collection.preset_plan import SPLITS_DIR, write_manifest

    assert plan.preset is not None
    made = {str(r.get("route_id")): str(r.get("clip")) for r in rl.final_records(records) if _is_clip(r, out, True)}
    manifest = write_manifest(out, plan.preset, made, config)
    summary.manifest = str(out / SPLITS_DIR / f"{manifest.name}.json")
    summary.manifest_clips = (len(manifest.train), len(manifest.val))


def _resume(
    out: Path, records: list[dict[str, Any]], config: CollectConfig, run_log: rl.RunLog, removed: list[Path]
) -> ResumeReport:
    """Reconcile the corpus with its run log; log what was discarded and which interruptions had no record."""
    report = reconcile(out, records, config, run_log)
    report.discarded = record_discarded(run_log, records, out, removed)
    report.interrupted = rl.interrupted_routes(records)
    record_interrupted(run_log, records, rl.unrecorded_interruptions(records), "on resume")
    finals = rl.final_records(records)
    report.attempts_kept = len(finals)
    report.clips_kept = sum(1 for r in finals if _is_clip(r, out, config.sensors))
    return report


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
        resumed: ResumeReport | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.plan, self.out, self.config, self.run_log, self.records = plan, out, config, run_log, records
        self.progress, self.resumed, self.clock = progress, resumed, clock
        finals = rl.final_records(records)
        # A route whose attempts all ended in an error (a crash, not a verdict on the route) is tried again.
        attempted = {str(r.get("route_id")) for r in finals if r.get("status") != STATUS_ERROR}
        self.pending = {sp.key: deque(t for t in sp.tasks if str(t.route.id) not in attempted)
                        for sp in plan.scenarios}  # fmt: skip
        # route id -> its target's key: one pass over the log however many targets (a preset has one per clip)
        key_of = {str(t.route.id): sp.key for sp in plan.scenarios for t in sp.tasks}
        self.done = {sp.key: 0 for sp in plan.scenarios}
        for r in finals:
            key = key_of.get(str(r.get("route_id")))
            if key is not None and _is_clip(r, out, config.sensors):
                self.done[key] += 1
        self.attempts_before = sum(1 for r in finals if str(r.get("route_id")) in key_of)
        self.target = {sp.key: sp.target for sp in plan.scenarios}
        self.in_flight = {sp.key: 0 for sp in plan.scenarios}
        self.requested = sum(self.target.values())
        self.retries: Counter[str] = Counter()
        #: Attempts of this run lost with their worker or to a full disk (not counted as attempts).
        self.lost = 0
        #: Set by the first attempt that found the disk full: no route starts after it.
        self.disk_full = False
        self.state = ProgressState(self.requested, self._clips(), self.attempts_before, clock=clock)
        mine = set(key_of)
        self.state.finished_frames = [
            frames_of(int(r.get("ticks") or 0), int(r.get("frames") or 0))
            for r in finals
            if str(r.get("route_id")) in mine and (r.get("ticks") or r.get("frames"))
        ]
        self._last_report: float | None = None
        #: Tasks in a row given to a free worker for its town ahead of the target whose turn it was.
        self._passed = 0

    def _clips(self) -> int:
        return sum(min(self.done[s], self.target[s]) for s in self.done)

    def _wants(self, key: str) -> bool:
        return self.target[key] - self.done[key] - self.in_flight[key] > 0 and bool(self.pending[key])

    def _next_task(self, order: deque[str], town: str | None = None) -> RouteTask | None:
        """Round robin over the targets (scenarios, a preset's clips) that still need clips and have routes left (none
        once the disk is full).

        ``town``: where the free worker ran its last route. Of the next ``TOWN_LOOKAHEAD`` targets in turn, the first
        whose next route is on that town goes first, so that the worker keeps the town's scene (map, meshes, GPU
        buffers; a route on another town builds them again); never more than ``TOWN_PASSES`` times in a row past the
        target whose turn it is. Each target's routes keep their order, so the clips are the same.
        """
        if self.disk_full:
            return None
        for _ in range(len(order)):
            if self._wants(order[0]):
                break
            order.rotate(-1)
        else:
            return None
        pick = 0
        if town is not None and self._passed < TOWN_PASSES:
            same = (j for j, key in enumerate(islice(order, TOWN_LOOKAHEAD))
                    if self._wants(key) and self.pending[key][0].town.name == town)  # fmt: skip
            pick = next(same, 0)
        self._passed = self._passed + 1 if pick else 0
        key = order[pick]
        del order[pick]
        order.append(key)
        return self.pending[key].popleft()

    def report(self, result: JobResult | None = None, force: bool = False) -> None:
        """Call the progress callback: always with a result or ``force``, else when the last call is
        ``REFRESH_SECONDS`` old."""
        if self.progress is None:
            return
        now = self.clock()
        recent = self._last_report is not None and now - self._last_report < REFRESH_SECONDS
        if recent and not force and result is None:
            return
        self._last_report = now
        state = self.state
        typical = state.typical_frames()
        self.progress(Progress(
            self._clips(), self.requested, state.attempts, result, state.elapsed(), state.eta(), state.routes(),
            typical, state.frames_this_run(), self.resumed if result is None and force else None,
        ))  # fmt: skip

    def frames_reported(self, report: FrameReport) -> None:
        """A job's frame report (the backends call this)."""
        self.state.frames_reported(report)
        self.report()

    def run(self, backend: Backend | None = None) -> tuple[int, int]:
        """Launch and collect attempts until nothing is left to do; returns (attempts, clips) of this run (lost
        attempts apart, counted in ``lost``)."""
        attempts = clips = 0
        self.report(force=True)
        if backend is None:
            backend = make_backend(self.out, self.config, self.frames_reported)
        order = deque(self.target)
        freed: deque[str] = deque()  # towns of the routes just finished: their workers are the free ones
        abandon = False
        try:
            while True:
                while backend.running() < backend.capacity:
                    task = self._next_task(order, freed.popleft() if freed else None)
                    if task is None:
                        break
                    self._launch(backend, task)
                freed.clear()
                if backend.running() == 0:
                    break
                for task, result in backend.wait(timeout=REFRESH_SECONDS):
                    freed.append(task.town.name)
                    self.in_flight[task.key] -= 1
                    if result.note in LOST_NOTES:
                        self.lost += 1
                    else:
                        attempts += 1
                    if result.note == DISK_FULL and not self.disk_full:
                        self.disk_full = True
                        log.warning("the disk of %s is full: no new route starts (%d still running)", self.out,
                                    backend.running())  # fmt: skip
                    if result.status == STATUS_CLIP:
                        self.done[task.key] += 1
                        clips += 1
                    record = result.to_record()
                    self.run_log.append(record)
                    self.records.append(record)
                    self._retry_if_lost(task, result)
                    self.state.route_finished(task.route.id, frames_of(result.ticks, result.frames),
                                              result.status == STATUS_CLIP)  # fmt: skip
                    self.state.clips = self._clips()
                    self.report(result)
                self.report()
        except BaseException as exc:
            abandon = True
            running = list(self.state.running)
            backend.close(abandon=True)
            # The run log says why these starts have no attempt; resume runs them again.
            how = "on interrupt" if isinstance(exc, KeyboardInterrupt) else f"on {type(exc).__name__}"
            record_interrupted(self.run_log, self.records, running, how)
            raise
        finally:
            if not abandon:
                backend.close()
        return attempts, clips

    def _retry_if_lost(self, task: RouteTask, result: JobResult) -> None:
        """Queue a route again (first in its scenario's line) when its worker died under it."""
        route_id = str(task.route.id)
        if result.note != WORKER_LOST or self.retries[route_id] >= LOST_WORKER_RETRIES:
            return
        self.retries[route_id] += 1
        self.pending[task.key].appendleft(task)
        log.warning("route %s: its worker was lost (%s); running it again", route_id, result.reason)

    def _launch(self, backend: Backend, task: RouteTask) -> None:
        start = {"event": rl.EVENT_START, "route_id": str(task.route.id), "scenario": task.scenario,
                 "town": task.town.name, "seed": task.seed,
                 "time": datetime.now(timezone.utc).isoformat(timespec="milliseconds")}  # fmt: skip
        self.run_log.append(start)
        self.records.append(start)
        self.in_flight[task.key] += 1
        self.state.route_started(str(task.route.id), task.scenario)
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
    """The end-of-run table: per scenario clips, attempts, attempts lost with their worker, success rate (of the
    attempts) and main failure reasons."""
    head = ("scenario", "clips", "attempts", "lost", "success", "main failure reasons")
    rows = []
    for s in summary.scenarios:
        # a preset's type can have failed attempts and, besides, slots without routes (the note says why)
        parts = [f"{k} ×{v}" for k, v in list(s.reasons.items())[:3]] + ([s.note] if s.note else [])
        reasons = "; ".join(parts) or "—"
        rows.append((s.scenario, f"{s.clips}/{s.requested}", str(s.attempts), str(s.lost),
                     f"{100 * s.success_rate:.0f}%", reasons[:90]))  # fmt: skip
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(head, widths)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
    if any(s.lost for s in summary.scenarios):
        lines.append("lost: attempts whose worker process died (killed, crashed, node lost) or whose disk was full: "
                     "no verdict on the route, which runs again; they count in neither attempts nor success")  # fmt: skip
    return "\n".join(lines)
