"""How many rig captures per second one GPU serves to many processes at once, and which part of a capture sets that.

Each of ``P`` processes builds the collection's sensor rig (``CollectConfig.rig``: JPEG planes and PNG scanlines on
the GPU) on a CARLA town, warms it up, waits for the others, then captures ``--frames`` frames of the same scene (the ego
and a few actors standing in a lane). No expert, no encoders, no files: what is left is the rig's own per-frame work, most of it the GPU's.
The figure is frames per second over all processes (the slowest process's wall time); variants drop one part so
that the difference tells what that part costs when the GPU is shared:

- ``full``: the capture as a collection runs it;
- ``no-read``: the GPU is waited for (glFinish) but nothing is read back into host memory;
- ``no-rays``: no LiDAR and no radars (camera work only);
- ``no-labels``: colour only, no depth / semantic / instance targets;
- ``no-pack``: the one-byte targets read back by glReadPixels instead of the compute pass (``Renderer.pack_reads``).

    python scripts/probe_gpu_share.py --procs 1 --procs 16 --frames 40 --variant full --variant no-read
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import queue
import time
from dataclasses import replace
from typing import Any

for _key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_key, "1")


def _skip_read_back() -> None:
    """Make every frame's read-back a plain glFinish whose arrays view one zeroed block (never written by the GPU)."""
    import numpy as np

    from b2d_data.sim.builtin.sensors import renderer

    block = np.zeros(0, dtype=np.uint8)

    def finish(self: Any) -> list[Any]:
        nonlocal block
        self.ctx.finish()
        if block.size < self._size:
            block = np.zeros(self._size, dtype=np.uint8)
        return [self._view(block, shape, dtype, offset) for _, _, shape, dtype, offset in self._reads]

    renderer._Readback.finish = finish  # type: ignore[method-assign]


def _worker(variant: str, town: str, frames: int, width: int, height: int, weather: int, slot: int,
            barrier: Any, results: Any) -> None:  # fmt: skip
    from b2d_data import data
    from b2d_data.collection.job import CollectConfig
    from b2d_data.format.weather import preset
    from b2d_data.maps import load_opendrive
    from b2d_data.sim.builtin.sensors.suite import SensorSuite
    from b2d_data.viz.town_scene import town_snapshot

    os.environ.setdefault("B2D_GPU_SLOT", str(slot))
    if variant == "no-read":
        _skip_read_back()
    if variant == "no-pack":
        import functools

        from b2d_data.sim.builtin.sensors import suite as suite_module

        suite_module.Renderer = functools.partial(suite_module.Renderer, pack_reads=False)  # type: ignore[misc]
    rig = CollectConfig(out=data.carla_maps_dir(), width=width, height=height).rig()
    if variant == "no-rays":
        rig = replace(rig, lidar=False, radar=False)
    if variant == "no-labels":
        rig = replace(rig, dense_labels=False)
    world_map = load_opendrive(data.carla_maps_dir() / f"{town}.xodr")
    suite = SensorSuite(world_map, rig, seed=slot)
    snapshot, ego_id = town_snapshot(world_map, None, preset(weather), seed=slot)
    for _ in range(3):  # shader variants compiled, static scene uploaded
        suite.capture(snapshot, ego_id)
    barrier.wait()
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(frames):
        suite.capture(snapshot, ego_id)
    results.put((time.perf_counter() - t0, time.process_time() - c0))
    suite.close()


def run_together(target: Any, args: tuple, procs: int, what: str) -> list[Any]:
    """Start ``procs`` processes of ``target(*args, k, barrier, results)`` (k: the process's index; each waits at
    the barrier, then puts one result); returns their results, or stops the run if one of them fails."""
    context = multiprocessing.get_context("spawn")
    barrier, results = context.Barrier(procs), context.Queue()
    workers = [context.Process(target=target, args=(*args, k, barrier, results)) for k in range(procs)]
    for w in workers:
        w.start()
    got = []
    while len(got) < procs:
        try:
            got.append(results.get(timeout=5))
        except queue.Empty:
            if any(w.exitcode not in (None, 0) for w in workers):
                for w in workers:
                    w.kill()
                raise SystemExit(f"a process failed ({procs} processes, {what})") from None
    for w in workers:
        w.join()
    return got


def run(procs: int, variant: str, args: argparse.Namespace) -> tuple[float, float]:
    """(frames/s over all processes, CPU ms per frame) of ``procs`` processes capturing at once."""
    got = run_together(_worker, (variant, args.town, args.frames, args.width, args.height, args.weather), procs,
                       variant)  # fmt: skip
    wall = max(g[0] for g in got)
    cpu = sum(g[1] for g in got) / (procs * args.frames)
    return procs * args.frames / wall, 1e3 * cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--procs", type=int, action="append", default=[], help="processes at once (repeatable)")
    parser.add_argument("--variant", action="append", default=[],
                        choices=("full", "no-read", "no-rays", "no-labels", "no-pack"), help="repeatable (default full)")
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--town", default="Town10HD")
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=900)
    parser.add_argument("--weather", type=int, default=1)
    parser.add_argument("--rounds", type=int, default=1, help="every (procs, variant) pair this many times, alternated")
    args = parser.parse_args()
    procs = args.procs or [1, 16]
    variants = args.variant or ["full"]
    print("| processes | variant | frames/s (all) | ratio to first variant | CPU ms per frame |\n|---:|---|---:|---:|---:|")
    for _ in range(args.rounds):
        for p in procs:
            base = None
            for variant in variants:
                fps, cpu = run(p, variant, args)
                base = fps if base is None else base
                print(f"| {p} | {variant} | {fps:.1f} | {fps / base:.2f} | {cpu:.1f} |", flush=True)


if __name__ == "__main__":
    main()
