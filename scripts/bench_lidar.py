"""Time the LiDAR sweep on Embree against the GPU ray caster, in the same run, and check that they agree.

Builds a town's static scene (Town10HD by default) with a dozen actors around the ego, then for a few sensor poses
(the roof LiDAR turned and moved along the road) casts the 64 × 1000-ray sweep into both casters and prints per
sweep: wall and CPU milliseconds of each (the GPU caster's CPU split into the calling thread, i.e. what a route
process pays, and the whole process, which on llvmpipe includes the rasteriser threads running the shader), the
per-tick cost of the dynamic scene (Embree's scene build, the GPU caster's tree build and upload) and the agreement:
rays whose hit / miss differ, hits whose tag or actor id differ, and the largest distance difference.

    python scripts/bench_lidar.py [--town PATH.xodr | --synthetic] [--poses 8] [--repeats 5]

On llvmpipe the GPU caster is slow (the shader runs on the CPU); compare the calling thread's CPU there, and the
wall time on a hardware GPU.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from b2d_data import data
from b2d_data.format.rig import LIDAR
from b2d_data.format.weather import preset
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.fixture_mesh import fixture_static_mesh
from b2d_data.sim.builtin.sensors.gpu_raycast import GpuRayCaster
from b2d_data.sim.builtin.sensors.lidar import cast_from
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.raycast import RayCaster, RayHits
from b2d_data.sim.builtin.sensors.scene_mesh import merge
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import crossroads_layout

DEFAULT_TOWN = data.carla_maps_dir() / "Town10HD.xodr"


def _timed(fn: Callable[[], object], repeats: int) -> tuple[object, dict[str, float]]:
    """Median wall, calling-thread CPU and process CPU milliseconds of ``fn`` over ``repeats`` calls."""
    wall, thread, process = [], [], []
    result = None
    for _ in range(repeats):
        w, t, p = time.perf_counter(), time.thread_time(), time.process_time()
        result = fn()
        wall.append(time.perf_counter() - w)
        thread.append(time.thread_time() - t)
        process.append(time.process_time() - p)
    return result, {k: 1e3 * statistics.median(v) for k, v in (("wall", wall), ("thread", thread), ("cpu", process))}


def _poses(base: np.ndarray, count: int) -> list[np.ndarray]:
    """The LiDAR pose turned by ``count`` yaws and moved up to 20 m along its x axis."""
    out = []
    for k in range(count):
        yaw = 2.0 * np.pi * k / count + 0.1234  # off the axes: no ray set aligned with the grid of the town
        c, s = np.cos(yaw), np.sin(yaw)
        turn = np.eye(4)
        turn[:2, :2] = [[c, -s], [s, c]]
        turn[0, 3] = 20.0 * k / max(count - 1, 1) - 10.0
        out.append(base @ turn)
    return out


def compare(a: RayHits, b: RayHits, atol: float = 1e-3) -> dict[str, float]:
    """Disagreements of two casts of the same rays."""
    both = a.hit & b.hit
    dt = np.abs(a.t[both] - b.t[both])
    return {
        "rays": len(a.hit),
        "hit_differs": int((a.hit != b.hit).sum()),
        "label_differs": int(((a.tags != b.tags) | (a.actor_ids != b.actor_ids))[both].sum()),
        "t_over_tol": int((dt > atol).sum()),
        "max_dt": float(dt.max()) if len(dt) else 0.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", type=Path, default=DEFAULT_TOWN, help="OpenDRIVE file (default Town10HD)")
    parser.add_argument("--synthetic", action="store_true", help="the synthetic crossroads instead of a town")
    parser.add_argument("--poses", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=5, help="timed sweeps per pose and caster")
    parser.add_argument("--azimuth-steps", type=int, default=1000)
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING)

    rig = RigConfig(cameras=(), radar=False, lidar_azimuth_steps=args.azimuth_steps, gpu_rays="off")
    if args.synthetic or not args.town.exists():
        from b2d_data.sim.builtin.sensors.synthetic import actor_state, snapshot_of

        suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=0), rig)
        actors = [actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero"),
                  actor_state(2, "vehicle.tesla.model3", -15.0, 5.25, 0.0),
                  actor_state(3, "walker.pedestrian.0001", -20.0, 8.5, 90.0)]  # fmt: skip
        snapshot, ego_id = snapshot_of(actors, preset(1)), 1
    else:
        from b2d_data.maps import load_opendrive
        from b2d_data.viz.town_scene import town_snapshot

        town = load_opendrive(args.town)
        suite = SensorSuite(town, rig, seed=0)
        snapshot, ego_id = town_snapshot(town, None, preset(1), seed=0)
    tick = suite._prepare(snapshot, ego_id)
    embree = suite.caster
    assert isinstance(embree, RayCaster)
    # The static scene as the suite gave it to Embree: the town plus its traffic-light and sign fixtures.
    static = merge([suite.scene.mesh, fixture_static_mesh(suite.fixtures)])
    dynamic = merge([m for i, m in tick.actor_parts if i != ego_id] + [tick.lamps])

    gpu = GpuRayCaster(static)
    print(f"static {len(static)} triangles, dynamic {len(dynamic)}; GPU caster on {gpu.gl_renderer}")
    _, embree_dyn = _timed(lambda: embree.set_dynamic(dynamic), args.repeats)
    _, gpu_dyn = _timed(lambda: gpu.set_dynamic(dynamic), args.repeats)

    dirs = suite.lidar._dirs
    base = suite.sensor_poses(tick.ego)[LIDAR.sensor_id]
    rows: dict[str, list[dict[str, float]]] = {"embree": [], "gpu": []}
    worst = {"hit_differs": 0, "label_differs": 0, "t_over_tol": 0, "max_dt": 0.0, "rays": 0}
    for pose in _poses(base, args.poses):
        a, ta = _timed(lambda: cast_from(embree, pose, dirs, LIDAR.range_m), args.repeats)
        b, tb = _timed(lambda: cast_from(gpu, pose, dirs, LIDAR.range_m), args.repeats)
        rows["embree"].append(ta)
        rows["gpu"].append(tb)
        for k, v in compare(a, b).items():  # type: ignore[arg-type]
            worst[k] = max(worst[k], v) if k == "max_dt" else worst[k] + v
    # As the rig runs them: submitted, then collected and turned into the sweep (the GPU had time in between).
    lidar = suite.lidar

    def gpu_sweep() -> object:
        return lidar.sweep_of(gpu.collect(gpu.submit_turned(base, dirs, LIDAR.range_m)))

    _, gpu_rig = _timed(gpu_sweep, args.repeats)
    # The GPU's time for one sweep: the wall from submit to a finished queue (an upper bound: launch included). A
    # timer query cannot wrap the dispatch here, since the caster's calls make its context current and release it.
    gpu_ms = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        pending = gpu.submit_turned(base, dirs, LIDAR.range_m)
        with gpu.ctx:
            gpu.ctx.finish()
        gpu_ms.append((time.perf_counter() - t0) * 1e3)
        gpu.collect(pending)
    _, embree_rig = _timed(lambda: lidar.scan(embree, base), args.repeats)
    gpu.close()

    # The whole rig's rays per tick, as SensorSuite.capture runs them (no cameras): the actors meshed and handed to
    # the caster, then the LiDAR sweep and the five radars; Embree on its worker thread's code path, the GPU caster
    # submitted and collected.
    rigs = {mode: SensorSuite.from_scene(suite.scene, replace(rig, radar=True, gpu_rays=mode)) for mode in ("off", "on")}
    suite.close()
    per_tick: dict[str, dict[str, float]] = {}
    outputs = {}
    for mode, r in rigs.items():
        poses = r.sensor_poses(snapshot.actors[ego_id])

        def rays(r: SensorSuite = r, mode: str = mode) -> object:
            tick = r._prepare(snapshot, ego_id)
            if mode == "off":
                return r._cast_rays(tick, poses)[:2]
            return r._collect_rays(tick, r._submit_rays(tick, poses))[:2]

        outputs[mode], per_tick[mode] = _timed(rays, args.repeats)
        r.close()
    (sweep_a, radar_a), (sweep_b, radar_b) = outputs["off"], outputs["on"]  # type: ignore[misc]
    same = (np.array_equal(sweep_a.tags, sweep_b.tags) and np.array_equal(sweep_a.actor_ids, sweep_b.actor_ids)
            and np.allclose(sweep_a.points, sweep_b.points, atol=1e-3, rtol=0)
            and all(np.allclose(radar_a[k], radar_b[k], atol=1e-3, rtol=0) for k in radar_a))  # fmt: skip

    def med(name: str, key: str) -> float:
        return statistics.median(r[key] for r in rows[name])

    print(f"per sweep ({len(dirs)} rays), median over {args.poses} poses of the median of {args.repeats}, ms:")
    print(f"  Embree       wall {med('embree', 'wall'):7.2f}  thread CPU {med('embree', 'thread'):7.2f}  "
          f"process CPU {med('embree', 'cpu'):7.2f}")  # fmt: skip
    print(f"  GPU caster   wall {med('gpu', 'wall'):7.2f}  thread CPU {med('gpu', 'thread'):7.2f}  "
          f"process CPU {med('gpu', 'cpu'):7.2f}")  # fmt: skip
    print(f"  ratio GPU / Embree: wall {med('gpu', 'wall') / med('embree', 'wall'):.3f}, calling-thread CPU "
          f"{med('gpu', 'thread') / med('embree', 'thread'):.3f}")  # fmt: skip
    print(f"GPU time per sweep (submit to a finished queue, an upper bound): "
          f"{statistics.median(gpu_ms):.3f} ms")
    print(f"per tick, dynamic scene ({len(dynamic)} triangles): Embree build wall {embree_dyn['wall']:.2f} ms "
          f"(CPU {embree_dyn['cpu']:.2f}); GPU tree + upload wall {gpu_dyn['wall']:.2f} ms "
          f"(thread CPU {gpu_dyn['thread']:.2f})")  # fmt: skip
    print(f"per tick, host CPU of the LiDAR as the rig runs it (dynamic scene + sweep + points): Embree "
          f"{embree_dyn['cpu'] + embree_rig['cpu']:.2f} ms (process), GPU "
          f"{gpu_dyn['thread'] + gpu_rig['thread']:.2f} ms (calling thread; wall of the sweep {gpu_rig['wall']:.2f})")
    print(f"per tick, the rig's rays (actors meshed + caster's dynamic scene + LiDAR + 5 radars): Embree "
          f"{per_tick['off']['cpu']:.2f} ms process CPU (wall {per_tick['off']['wall']:.2f}); GPU caster "
          f"{per_tick['on']['thread']:.2f} ms calling-thread CPU (wall {per_tick['on']['wall']:.2f}); "
          f"same points, tags, ids and detections: {same}")  # fmt: skip
    print(f"agreement over {worst['rays']} rays: hit/miss differ {worst['hit_differs']}, tag or actor id differ "
          f"{worst['label_differs']}, distance off by > 1 mm {worst['t_over_tol']}, largest difference "
          f"{worst['max_dt'] * 1e3:.3f} mm")  # fmt: skip


if __name__ == "__main__":
    main()
