"""Run collection tasks on a Ray cluster: one Ray task per route (the optional ``b2d-data[ray]`` extra).

Every node must see the corpus folder at the same path (a shared file system): the jobs write their clips and
records there and read the generated towns from ``<out>/towns``. The driver alone writes the run log. The tasks'
frame reports go to a small actor (:class:`FrameBoard`) that the driver empties whenever it waits.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from b2d_data.collection.job import CollectConfig, JobResult, run_route_job
from b2d_data.collection.layout import single_thread_worker
from b2d_data.collection.progress import FrameReport, FrameSink, set_frame_sink

log = logging.getLogger(__name__)


class RayUnavailableError(RuntimeError):
    """Ray is not installed, or the cluster cannot be reached."""


def require_ray() -> Any:
    """The ``ray`` module, or :class:`RayUnavailableError` saying how to install it."""
    try:
        import ray
    except ImportError:
        raise RayUnavailableError(
            "--ray needs Ray, which is not installed: pip install 'b2d-data[ray]' (or pip install ray)"
        ) from None
    return ray


class FrameBoard:
    """The Ray actor collecting the tasks' frame reports until the driver takes them."""

    def __init__(self) -> None:
        self._reports: list[FrameReport] = []

    def report(self, report: FrameReport) -> None:
        """Keep one report."""
        self._reports.append(report)

    def take(self) -> list[FrameReport]:
        """The reports since the last call."""
        out, self._reports = self._reports, []
        return out


def route_job_reporting_to(board: Any, *args: Any) -> JobResult:
    """:func:`run_route_job` in a Ray task, its frame reports sent (fire and forget) to the ``board`` actor."""
    set_frame_sink(lambda report: board.report.remote(report))
    single_thread_worker(1)  # a task holds one CPU of its node (Ray caps the BLAS pools the same way)
    try:
        return run_route_job(*args)
    finally:
        set_frame_sink(None)


class RayBackend:
    """Submits :func:`~b2d_data.collection.job.run_route_job` as Ray tasks (one CPU each)."""

    def __init__(self, out: Path, config: CollectConfig, address: str, on_frames: FrameSink | None = None) -> None:
        ray = require_ray()
        self._ray = ray
        self.out, self.config, self.on_frames = Path(out).resolve(), config, on_frames
        try:
            # "local" starts a private cluster on this machine; anything else joins an existing one.
            ray.init(
                address=None if address == "local" else address,
                ignore_reinit_error=True,
                log_to_driver=False,
                include_dashboard=False,
            )
        except Exception as exc:  # noqa: BLE001 - whatever Ray raises becomes one clear message
            raise RayUnavailableError(f"cannot connect to the Ray cluster at {address!r}: {exc}") from None
        self._remote = ray.remote(num_cpus=1, max_retries=0)(route_job_reporting_to)
        self._board = ray.remote(num_cpus=0)(FrameBoard).remote()
        cpus = int(ray.cluster_resources().get("CPU", 1))
        # Never more in flight than the cluster can run, nor than the user allowed when asking for fewer.
        self.capacity = max(1, min(cpus, config.workers) if config.workers > 1 else cpus)
        self._refs: dict[Any, Any] = {}
        log.info("Ray cluster at %s: %d CPUs, %d routes in flight", address, cpus, self.capacity)

    def submit(self, task: Any) -> None:
        """Start one Ray task for the route."""
        ref = self._remote.remote(self._board, task.route, task.town, self.out, self.config, task.seed)
        self._refs[ref] = task

    def _drain_reports(self) -> None:
        """Hand the tasks' frame reports to ``on_frames``."""
        if self.on_frames is None:
            return
        try:
            reports = self._ray.get(self._board.take.remote(), timeout=10)
        except Exception:  # progress is best effort; the results still arrive
            log.debug("cannot read the frame reports", exc_info=True)
            return
        for report in reports:
            self.on_frames(report)

    def wait(self, timeout: float | None = None) -> list[tuple[Any, JobResult]]:
        """Results of the tasks that finished within ``timeout`` s (a lost worker becomes an error result)."""
        from b2d_data.collection.backends import error_result

        ready, _ = self._ray.wait(list(self._refs), num_returns=1, timeout=timeout)
        self._drain_reports()
        out = []
        for ref in ready:
            task = self._refs.pop(ref)
            try:
                out.append((task, self._ray.get(ref)))
            except Exception as exc:  # noqa: BLE001 - RayTaskError, WorkerCrashedError, node loss, ...
                out.append((task, error_result(task, f"Ray task failed: {type(exc).__name__}: {exc}")))
        return out

    def running(self) -> int:
        """Tasks in flight."""
        return len(self._refs)

    def close(self, abandon: bool = False) -> None:
        """Cancel what is still running (the driver is leaving)."""
        for ref in list(self._refs):
            try:
                self._ray.cancel(ref, force=True)
            except Exception:
                log.debug("cannot cancel a Ray task", exc_info=True)
        self._refs.clear()
        try:
            self._ray.kill(self._board)
        except Exception:
            log.debug("cannot stop the frame-report actor", exc_info=True)
