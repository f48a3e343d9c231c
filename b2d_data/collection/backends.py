"""Where route attempts run: in this process, in a local process pool, or on Ray (``ray_backend.py``).

Every backend forwards the jobs' frame reports (``progress.py``) to the driver's ``on_frames`` callback: inline
directly, from pool workers through a queue drained in :meth:`Backend.wait`, from Ray tasks through an actor.
"""

from __future__ import annotations

import logging
import multiprocessing.util
import os
import queue
import signal
import sys
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from concurrent.futures.process import BrokenProcessPool
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, NoReturn, Protocol

from b2d_data.collection.job import (
    STATUS_ERROR,
    CollectConfig,
    JobResult,
    exit_with_parent,
    ignore_interrupts,
    run_route_job,
    shutdown_encoders,
)
from b2d_data.collection.layout import (
    raster_threads,
    single_thread_worker,
    take_gpu_slot,
    worker_context,
)
from b2d_data.collection.plan import CollectError, RouteTask
from b2d_data.collection.progress import FrameReport, FrameSink, set_frame_sink

log = logging.getLogger(__name__)

#: Seconds idle workers get to read their stop sentinel at close.
IDLE_GRACE = 10.0
#: Seconds an interrupted collection gives its workers to drop their routes and exit cleanly before killing them.
ABANDON_GRACE = 15.0


class Backend(Protocol):
    """Runs route tasks somewhere; ``wait`` returns at least one finished task while any is running."""

    capacity: int

    def submit(self, task: RouteTask) -> None:
        """Start a task."""
        ...

    def wait(self, timeout: float | None = None) -> list[tuple[RouteTask, JobResult]]:
        """Block until at least one task finished or ``timeout`` seconds passed; return the finished ones."""
        ...

    def running(self) -> int:
        """Tasks started and not yet returned by ``wait``."""
        ...

    def close(self, abandon: bool = False) -> None:
        """Stop; with ``abandon`` (the driver was interrupted) running tasks are killed instead of awaited."""
        ...


#: ``JobResult.note`` of an attempt that ended because its worker died or was lost, not because of the route.
WORKER_LOST = "worker lost"


def error_result(task: RouteTask, reason: str) -> JobResult:
    """The result of a task whose worker died or could not be reached (noted ``WORKER_LOST``)."""
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
        note=WORKER_LOST,
    )


class InlineBackend:
    """Runs each task in this process, one at a time."""

    capacity = 1

    def __init__(self, out: Path, config: CollectConfig, on_frames: FrameSink | None = None) -> None:
        self.out, self.config, self.on_frames = out, config, on_frames
        self._queue: deque[RouteTask] = deque()

    def submit(self, task: RouteTask) -> None:
        """Queue the task; it runs in :meth:`wait`."""
        self._queue.append(task)

    def wait(self, timeout: float | None = None) -> list[tuple[RouteTask, JobResult]]:
        """Run the oldest queued task (to its end: ``timeout`` does not apply; its frame reports arrive meanwhile)."""
        task = self._queue.popleft()
        previous = set_frame_sink(self.on_frames)
        try:
            return [(task, run_route_job(task.route, task.town, self.out, self.config, task.seed))]
        finally:
            set_frame_sink(previous)

    def running(self) -> int:
        """Queued tasks."""
        return len(self._queue)

    def close(self, abandon: bool = False) -> None:
        """Drop queued tasks and stop this process's encoder pool."""
        self._queue.clear()
        shutdown_encoders()


#: Whether this pool worker is inside a task (set by :func:`_pool_task`).
_in_task = False


def _leave(signum: int, frame: object) -> None:
    """SIGTERM in a pool worker: unwind a running task (the route's writer and simulator clean up), then exit;
    an idle worker exits at once."""
    # Nothing may cut the clean-up short: the pool sends another SIGTERM when a sibling exits first.
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if _in_task:
        raise SystemExit(0)  # _pool_task ends the process once the task has unwound
    _exit_worker()


def _exit_worker() -> NoReturn:
    """End this pool worker the way multiprocessing ends its processes: run the finalizers (encoder pools, named
    semaphores, shared memory), then ``os._exit``.

    Never back into the pool's loop: it takes a SystemExit for the task's own error and waits on its call queue
    again, where the lock of a sibling killed while idle blocks it for ever, and the driver's exit waits on it.
    """
    try:
        multiprocessing.util._exit_function()
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
    finally:
        os._exit(0)


def _pool_task(job: Callable[..., JobResult], *args: Any) -> JobResult:
    """Run one task in a pool worker; a task that SIGTERM stopped ends the worker."""
    global _in_task
    try:
        _in_task = True
        return job(*args)
    except SystemExit:
        _exit_worker()
    finally:
        _in_task = False


def _worker_init(
    log_level: int, driver_pid: int, reports: Any, rasteriser_threads: int = 0, gpu_slots: Any = None
) -> None:
    """Pool worker set-up: die with the driver (no orphan finishing a route after a kill), leave Ctrl-C to the
    driver and stop cleanly on its SIGTERM, quiet logging, frame reports into the driver's queue, the next GPU slot
    (``gpu_slots``: a shared counter) for its GL context."""
    exit_with_parent(driver_pid)
    take_gpu_slot(gpu_slots)
    ignore_interrupts()
    single_thread_worker(rasteriser_threads)
    # An exit through the interpreter (not the default SIGTERM death) releases the worker's semaphores and shared
    # memory; otherwise the resource tracker reports them as leaked.
    signal.signal(signal.SIGTERM, _leave)
    logging.basicConfig(level=log_level, format="%(levelname)s %(name)s [%(process)d]: %(message)s")
    logging.getLogger().setLevel(log_level)
    # Never wait at exit for reports the driver will not read (it may be gone).
    reports.cancel_join_thread()
    set_frame_sink(reports.put_nowait)


class ProcessPoolBackend:
    """Runs tasks in ``workers`` processes of this machine; each process owns its simulator and map cache.

    ``job`` is what a worker runs per task, ``job(route, town, out, config, seed)`` (the route job; tests pass an
    importable stand-in).
    """

    def __init__(
        self,
        out: Path,
        config: CollectConfig,
        workers: int,
        on_frames: FrameSink | None = None,
        job: Callable[..., JobResult] = run_route_job,
    ) -> None:
        self.out, self.config, self.capacity, self.on_frames, self.job = out, config, workers, on_frames, job
        self._futures: dict[Future[JobResult], RouteTask] = {}
        #: Workers of broken pools, stopped (SIGTERM) by the pool itself; killed at close() if still alive.
        self._orphans: list[Any] = []
        self._context = worker_context()
        self._reports = self._context.Queue()
        #: The next GPU slot a new worker takes (round robin over the machine's GPUs, replacement workers included).
        self._gpu_slots = self._context.Value("i", 0)
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            self.capacity,
            mp_context=self._context,
            initializer=_worker_init,
            initargs=(logging.getLogger().getEffectiveLevel(), os.getpid(), self._reports, raster_threads(self.capacity),
                      self._gpu_slots),
        )

    def _drain_reports(self) -> None:
        """Hand the workers' frame reports to ``on_frames``."""
        while True:
            try:
                report = self._reports.get_nowait()
            except queue.Empty:
                return
            except Exception:  # e.g. a report cut short by a killed worker; progress is best effort
                log.debug("cannot read a frame report", exc_info=True)
                return
            if self.on_frames is not None and isinstance(report, FrameReport):
                self.on_frames(report)

    def submit(self, task: RouteTask) -> None:
        """Start the task in a worker."""
        args = (_pool_task, self.job, task.route, task.town, self.out, self.config, task.seed)
        try:
            future = self._pool.submit(*args)
        except BrokenProcessPool:
            self._orphans += _processes(self._pool)
            self._pool = self._new_pool()
            future = self._pool.submit(*args)
        self._futures[future] = task

    def wait(self, timeout: float | None = None) -> list[tuple[RouteTask, JobResult]]:
        """Results of the tasks that finished (a dead worker fails its tasks, and the pool is rebuilt)."""
        done, _ = wait_futures(list(self._futures), timeout=timeout, return_when=FIRST_COMPLETED)
        self._drain_reports()
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
            self._orphans += _processes(self._pool)
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

    def close(self, abandon: bool = False) -> None:
        """Shut the pool down; queued tasks are cancelled, running ones awaited unless ``abandon`` (then killed)."""
        if abandon:
            self._abandon()
        elif not self._futures:
            # Nothing runs: a worker killed while idle may have died holding the call queue's lock, and the others
            # would wait on that lock for ever instead of reading their stop sentinel (the pool need not have
            # noticed the death); those still alive after a grace are stopped (an idle worker exits on SIGTERM).
            processes = _processes(self._pool)
            self._pool.shutdown(wait=False, cancel_futures=True)
            _join_or_stop(processes, IDLE_GRACE)
        else:
            self._pool.shutdown(wait=True, cancel_futures=True)
        # A broken pool's manager thread waits for its workers, and the interpreter's exit for that thread.
        _join_or_kill(self._orphans, ABANDON_GRACE)
        self._orphans.clear()
        self._reports.close()
        self._reports.join_thread()

    def _abandon(self) -> None:
        """Stop the workers now (a route can run for minutes): SIGTERM drops their routes, a late one is killed."""
        processes = _processes(self._pool)
        for process in processes:
            process.terminate()
        self._pool.shutdown(wait=False, cancel_futures=True)
        _join_or_kill(processes, ABANDON_GRACE)


def _processes(pool: ProcessPoolExecutor) -> list[Any]:
    """The worker processes of a pool (``multiprocessing.Process`` objects)."""
    return list((getattr(pool, "_processes", None) or {}).values())


def _join_or_kill(processes: list[Any], grace: float) -> None:
    """Wait up to ``grace`` seconds for stopped workers to exit; kill the late ones."""
    deadline = time.monotonic() + grace
    for process in processes:
        process.join(timeout=max(deadline - time.monotonic(), 0.0))
        if process.is_alive():
            log.warning("worker %d did not stop within %.0f s; killing it", process.pid, grace)
            process.kill()
            process.join(timeout=5.0)


def _join_or_stop(processes: list[Any], grace: float) -> None:
    """Wait up to ``grace`` seconds for idle workers to exit; stop the late ones (SIGTERM, then kill)."""
    deadline = time.monotonic() + grace
    for process in processes:
        process.join(timeout=max(deadline - time.monotonic(), 0.0))
    late = [p for p in processes if p.is_alive()]
    if late:
        log.warning("%d idle worker(s) did not exit within %.0f s (a sibling died holding the pool's queue); "
                    "stopping them", len(late), grace)  # fmt: skip
        for process in late:
            process.terminate()
        _join_or_kill(late, ABANDON_GRACE)


def make_backend(out: Path, config: CollectConfig, on_frames: FrameSink | None = None) -> Backend:
    """Ray with ``ray_address``, a process pool with several workers, else this process; frame reports go to
    ``on_frames``."""
    if config.ray_address is not None:
        from b2d_data.collection.ray_backend import RayBackend, RayUnavailableError

        try:
            return RayBackend(out, config, config.ray_address, on_frames)
        except RayUnavailableError as exc:
            raise CollectError(str(exc)) from None
    if config.workers > 1:
        return ProcessPoolBackend(out, config, config.workers, on_frames)
    return InlineBackend(out, config, on_frames)
