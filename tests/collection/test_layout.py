"""The worker layout `--workers auto` picks from the cores and GPUs present."""

from __future__ import annotations

import os

import pytest

from b2d_data.collection.layout import Layout, auto_layout, raster_threads, single_thread_worker, take_gpu_slot


def test_gpu_machine_runs_a_quarter_more_route_processes_than_cores() -> None:
    # 16 cores + 16 // 4 = 20 route processes, each encoding its own frames.
    assert auto_layout(cores=16, gpus=1) == Layout(workers=20, encode_workers=0)
    # 3 cores: 3 // 4 = 0 extra.
    assert auto_layout(cores=3, gpus=2) == Layout(workers=3, encode_workers=0)


def test_cpu_machine_runs_one_route_per_core_up_to_four() -> None:
    # llvmpipe spreads only the draws over the cores; the rest of a frame is serial, so routes run side by side.
    assert auto_layout(cores=2, gpus=0) == Layout(workers=2, encode_workers=0)
    assert auto_layout(cores=32, gpus=0) == Layout(workers=4, encode_workers=0)
    assert auto_layout(cores=1, gpus=0) == Layout(workers=1, encode_workers=0)


def test_each_route_process_rasterises_on_its_share_of_the_cores() -> None:
    assert raster_threads(2, cores=2) == 1  # two routes on the 2-core machine: one llvmpipe thread each
    assert raster_threads(1, cores=2) == 2  # one route keeps both
    assert raster_threads(4, cores=16) == 4
    assert raster_threads(20, cores=16) == 1  # more processes than cores: still one


def test_the_worker_sets_llvmpipe_threads_unless_the_user_did(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LP_NUM_THREADS", "0")  # records the variable's own state, restored after the test
    monkeypatch.delenv("LP_NUM_THREADS")
    single_thread_worker(3)
    assert os.environ["LP_NUM_THREADS"] == "3"
    monkeypatch.setenv("LP_NUM_THREADS", "7")
    single_thread_worker(1)
    assert os.environ["LP_NUM_THREADS"] == "7"
    monkeypatch.delenv("LP_NUM_THREADS")
    single_thread_worker()  # no count: llvmpipe's own default stays
    assert "LP_NUM_THREADS" not in os.environ


def test_route_processes_take_gpu_slots_in_turn(monkeypatch: pytest.MonkeyPatch) -> None:
    import multiprocessing

    counter = multiprocessing.get_context("spawn").Value("i", 0)
    monkeypatch.delenv("B2D_EGL_DEVICE", raising=False)
    taken = []
    for _ in range(3):  # three new route processes, each with a fresh environment
        monkeypatch.delenv("B2D_GPU_SLOT", raising=False)
        taken.append((take_gpu_slot(counter), os.environ["B2D_GPU_SLOT"]))
    # slots 0, 1, 2: on a 2-GPU machine the renderer puts them on devices 0, 1, 0 (slot modulo the GPUs)
    assert taken == [(0, "0"), (1, "1"), (2, "2")] and counter.value == 3
    # a slot or a device the user set is kept, and the counter is left alone
    assert take_gpu_slot(counter) is None and os.environ["B2D_GPU_SLOT"] == "2"
    monkeypatch.delenv("B2D_GPU_SLOT")
    monkeypatch.setenv("B2D_EGL_DEVICE", "1")
    assert take_gpu_slot(counter) is None and "B2D_GPU_SLOT" not in os.environ and counter.value == 3
    assert take_gpu_slot(None) is None


_WORKER_PROBE = """
import os, sys
from concurrent.futures import ProcessPoolExecutor
from b2d_data.collection.layout import worker_context

def probe():
    return os.environ.get("OPENBLAS_NUM_THREADS"), "b2d_data.sim.builtin.world" in sys.modules

if __name__ == "__main__":
    os.environ.pop("OPENBLAS_NUM_THREADS", None)
    # A first pool (as preset placement starts before the route processes) starts the fork server ...
    with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
        pool.submit(os.getpid).result()
    # ... whose environment and modules every later pool's workers get.
    with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
        print(*pool.submit(probe).result())
"""


def test_workers_start_single_threaded_with_the_route_modules_loaded(tmp_path) -> None:
    """Every worker of every pool runs with one BLAS thread (the fork server keeps the environment it started with,
    so a setting made after the first pool would never arrive) and finds the route modules already imported."""
    import subprocess
    import sys

    script = tmp_path / "probe_workers.py"
    script.write_text(_WORKER_PROBE)
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=120, check=True)
    assert out.stdout.split() == ["1", "True"]
