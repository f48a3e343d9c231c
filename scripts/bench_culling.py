"""CPU cost of culling a camera view's static tiles: the renderer's one-pass culling against a per-material reference.

The reference is the plain definition (a tile is culled when all eight corners of its box lie outside one clip
plane; visible tiles nearest first, contiguous vertex ranges merged), run material by material as the renderer did
before. Both must give the same runs for every view; the ratio is reference time / renderer time.

    python scripts/bench_culling.py --views 50
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from b2d_data.collection.job import CollectConfig
from b2d_data.collection.plan import plan_collection
from b2d_data.collection.towns import load_map
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene, layout_from_map
from b2d_data.sim.builtin.sensors.renderer import CameraView, _batch_mesh, _Culling, _Tiles, projection_from_intrinsic

SIGNS = np.array([(sx, sy, sz) for sx in (0, 1) for sy in (0, 1) for sz in (0, 1)], np.float64)


def reference_runs(tiles: _Tiles, viewproj: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """Runs of one material by the definition: eight homogeneous corners per tile through the clip matrix."""
    corners = tiles.lo[:, None, :] + SIGNS[None] * (tiles.hi - tiles.lo)[:, None, :]
    clip = np.concatenate([corners, np.ones(corners.shape[:2] + (1,))], axis=2) @ viewproj.T
    x, y, z, w = clip[..., 0], clip[..., 1], clip[..., 2], clip[..., 3]
    out = (x < -w).all(1) | (x > w).all(1) | (y < -w).all(1) | (y > w).all(1) | (z < -w).all(1) | (z > w).all(1)
    visible = np.flatnonzero(~out)
    visible = visible[np.argsort(np.linalg.norm(corners[visible].mean(axis=1) - eye, axis=1), kind="stable")]
    runs: list[list[int]] = []
    for first, count in zip(tiles.first[visible].tolist(), tiles.count[visible].tolist()):
        if runs and runs[-1][0] + runs[-1][1] == first:
            runs[-1][1] += count
        else:
            runs.append([first, count])
    return np.array(runs, np.int64).reshape(-1, 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--views", type=int, default=50, help="random camera poses in the town")
    parser.add_argument("--scenario", default="Accident", help="scenario whose first planned town is used")
    args = parser.parse_args()
    with TemporaryDirectory() as scratch:  # the plan writes its generated town here
        task = plan_collection(CollectConfig(out=Path(scratch), scenarios=(args.scenario,), n=1)).scenarios[0].tasks[0]
        scene = build_static_scene(layout_from_map(load_map(task.town)), seed=0)
    _, batches = _batch_mesh(scene.mesh, 48.0)
    culling = _Culling(batches)
    rng = np.random.default_rng(0)
    views = []
    for _ in range(args.views):
        eye = culling.centres[rng.integers(len(culling.centres))] + np.array([0.0, 0.0, 2.0])
        yaw = rng.uniform(0.0, 2.0 * np.pi)
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 3] = (np.cos(yaw), np.sin(yaw), 0.0), (-np.sin(yaw), np.cos(yaw), 0.0), eye
        view = CameraView(pose, 70.0, 1600, 900)
        views.append((projection_from_intrinsic(view.intrinsic(), 1600, 900, 0.05, 1500.0) @ view.world_to_cv(), eye))
    same = all(
        all(np.array_equal(reference_runs(t, vp, eye), culling.runs(vp, eye)[m]) for m, t in batches.items())
        for vp, eye in views
    )
    timings = {}
    for name, cull in (("reference", lambda vp, eye: {m: reference_runs(t, vp, eye) for m, t in batches.items()}),
                       ("renderer", culling.runs)):  # fmt: skip
        t0 = time.perf_counter()
        for _ in range(4):
            for vp, eye in views:
                cull(vp, eye)
        timings[name] = (time.perf_counter() - t0) / (4 * len(views))
    print(f"town {task.town.name}: {len(scene.mesh)} static triangles in {len(culling.first)} tiles, {len(views)} views")
    print(f"same runs for every view: {same}")
    for name, seconds in timings.items():
        print(f"  {name:<10} {1e3 * seconds:.3f} ms per view")
    print(f"ratio reference / renderer: {timings['reference'] / timings['renderer']:.1f}")


if __name__ == "__main__":
    main()
