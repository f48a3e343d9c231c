"""How many route processes and encoder processes a collection runs, chosen from the cores and GPUs present.

With a GPU the rendering costs the CPU little, so every stage of a frame is CPU work that scales with processes:
route processes each encoding their own frames (an encoder pool would only add copies), a quarter more of them than
cores, since each spends part of every frame waiting for the shared GPU (16 processes kept 13 of an H100 machine's
16 cores busy; 20 ran the frame loops at 74 frames/s against 59, same machine and call). Without a GPU the cameras
are rasterised by Mesa's llvmpipe, which spreads each draw over every core, but the rest of a frame is serial: one
route process per core (at most 4, for memory) beat one route with an encoder pool beside it, 6.3 against 4.2
frames/s on two cores.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.context
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Thread pools of the native libraries a route process uses, capped at one thread when several route processes
#: share the cores: each pool sizes itself to every core of the machine, and dozens of spinning helper threads per
#: process cost more CPU than they save (OpenCV's colour conversions alone took 3x their single-thread CPU time).
SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

#: Where the NVIDIA driver lists its GPUs (one folder each).
_NVIDIA_GPUS = Path("/proc/driver/nvidia/gpus")


@dataclass(frozen=True)
class Layout:
    """Route processes and encoder processes per route process."""

    workers: int
    encode_workers: int


#: Modules a collection's route process imports for its first route, imported once by the fork server instead
#: (about 1 CPU-s in every worker otherwise, and 20 workers start at once on a 16-core machine).
COLLECTION_PRELOAD = (
    "__main__",  # the multiprocessing default, kept
    "b2d_data.collection.job",
    "b2d_data.collection.data_agent",
    "b2d_data.expert",
    "b2d_data.scenarios.route_runner",
    "b2d_data.sim.builtin.world",
    "b2d_data.sim.builtin.sensors.suite",
    "b2d_data.writers",
)


def worker_context(
    preload: Sequence[str] = COLLECTION_PRELOAD, single_thread: bool = True
) -> multiprocessing.context.BaseContext:
    """How every pool of worker processes starts: from a fork server, so that a worker never inherits this process's
    threads (progress display, GL contexts) mid-state, or by spawn where the platform has no fork server.

    The fork server starts once per process, with the first pool, and keeps the environment and the ``preload``
    modules of that moment (a later change of ``os.environ`` never reaches its workers); so the single-thread
    settings for workers that share the cores are made here, before any pool.
    """
    if single_thread:
        single_thread_environment()
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(preload))
    return context


def count_gpus() -> int:
    """NVIDIA GPUs visible to this process (``CUDA_VISIBLE_DEVICES`` narrows the driver's list); 0 without any."""
    try:
        present = sum(1 for p in _NVIDIA_GPUS.iterdir() if p.is_dir())
    except OSError:
        return 0
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is None:
        return present
    chosen = [v for v in visible.split(",") if v.strip() and v.strip() != "-1"]
    return min(present, len(chosen))


def usable_cores() -> int:
    """Cores this process may run on (its affinity mask where the platform has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def auto_layout(cores: int | None = None, gpus: int | None = None) -> Layout:
    """The layout of ``--workers auto`` for ``cores`` cores and ``gpus`` GPUs (default: this machine's)."""
    cores = usable_cores() if cores is None else max(1, cores)
    gpus = count_gpus() if gpus is None else max(0, gpus)
    if gpus > 0:
        return Layout(workers=cores + cores // 4, encode_workers=0)
    return Layout(workers=min(cores, 4), encode_workers=0)


#: Environment variable naming a route process's GPU slot (read by the renderer when it creates its GL context).
GPU_SLOT_ENV = "B2D_GPU_SLOT"


def take_gpu_slot(counter: Any) -> int | None:
    """In a new route process: take the next slot of a shared counter (``multiprocessing.Value``) as its GPU slot,
    so that a machine's route processes spread over all its GPUs; None (nothing set) without a counter or where
    the user chose a device (``B2D_EGL_DEVICE``) or slot."""
    if counter is None or "B2D_EGL_DEVICE" in os.environ or GPU_SLOT_ENV in os.environ:
        return None
    with counter.get_lock():
        slot = int(counter.value)
        counter.value = slot + 1
    os.environ[GPU_SLOT_ENV] = str(slot)
    return slot


def single_thread_environment() -> None:
    """Cap the BLAS/OpenMP pools of processes started from now on (values the user set are kept)."""
    for key, value in SINGLE_THREAD_ENV.items():
        os.environ.setdefault(key, value)


def raster_threads(workers: int, cores: int | None = None) -> int:
    """Software-rasteriser threads for each of ``workers`` route processes: its share of the cores, at least one."""
    cores = usable_cores() if cores is None else max(1, cores)
    return max(1, cores // max(1, workers))


def single_thread_worker(rasteriser_threads: int = 0) -> None:
    """In a route process that shares the machine with others: one OpenCV thread (set before any encoding) and,
    when given, that many llvmpipe threads (read when the GL context is created; a value the user set is kept).

    llvmpipe starts a thread per core in every process; with one each, two route processes on two cores ran about 2 %
    more frames/s (five runs each, 6.33 against 6.19 on average). Hardware GPUs ignore the setting.
    """
    import cv2

    cv2.setNumThreads(1)
    if rasteriser_threads > 0:
        os.environ.setdefault("LP_NUM_THREADS", str(rasteriser_threads))
