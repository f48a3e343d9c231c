"""The worker layout `--workers auto` picks from the cores and GPUs present."""

from __future__ import annotations

from b2d_data.collection.layout import Layout, auto_layout


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
