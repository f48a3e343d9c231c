"""Where route attempts run: in this process, in a local process pool, or on Ray (``ray_backend.py``)."""

from __future__ import annotations

import logging
import os
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from concurrent.futures.process import BrokenProcessPool
from datetime import datetime, timezone
from pathlib import Path
from typing import Protocol

from b2d_data.collection.job import (
    STATUS_ERROR,
    CollectConfig,
    JobResult,
    exit_with_parent,
    run_route_job,
    shutdown_encoders,
)
from b2d_data.collection.layout import single_thread_environment, single_thread_worker
from b2d_data.collection.plan import CollectError, RouteTask

log = logging.getLogger(__name__)


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
    """Pool worker set-up: die with the driver (no orphan finishing a route after a kill), one OpenCV thread, logging."""
    exit_with_parent(driver_pid)
    single_thread_worker()
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
        single_thread_environment()
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
