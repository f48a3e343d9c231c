"""Time a full-rig sensor capture of the builtin simulator against the 0.25 s render budget.

Captures the Bench2Drive rig (6 × 1600×900 cameras with depth / semantic / instance, the top-down camera, the
64-channel LiDAR and the 5 radars) on a CARLA town (Town10HD by default) or on the synthetic crossroads, with a
dozen vehicles and walkers around the ego, and prints the median time of each part.

    python scripts/bench_sensors.py [--town PATH.xodr | --synthetic] [--repeats 7] [--weather 26]
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import time
from pathlib import Path

from b2d_data import data
from b2d_data.format.weather import preset
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, crossroads_layout, snapshot_of
from b2d_data.viz.town_scene import town_snapshot

BUDGET_S = 0.25
DEFAULT_TOWN = data.carla_maps_dir() / "Town10HD.xodr"


def _synthetic_snapshot(weather):
    actors = [
        actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero", velocity=(6.0, 0.0, 0.0)),
        actor_state(2, "vehicle.tesla.model3", -15.0, 5.25, 0.0, velocity=(6.0, 0.0, 0.0)),
        actor_state(3, "vehicle.carlamotors.carlacola", -5.0, 1.75, 0.0),
        actor_state(4, "vehicle.audi.a2", -45.0, -1.75, 180.0, velocity=(-8.0, 0.0, 0.0)),
        actor_state(5, "walker.pedestrian.0001", -20.0, 8.5, 90.0, velocity=(0.0, 1.2, 0.0)),
        actor_state(6, "vehicle.bh.crossbike", -25.0, -5.25, 180.0),
        actor_state(7, "vehicle.mitsubishi.fusorosa", 10.0, -5.25, 180.0),
        actor_state(8, "static.prop.trafficcone01", -22.0, 3.5, 0.0),
        actor_state(9, "vehicle.nissan.patrol", 20.0, 1.75, 0.0),
        actor_state(10, "vehicle.ford.ambulance", -60.0, 1.75, 0.0),
        actor_state(11, "walker.pedestrian.0015", -35.0, -8.5, 0.0),
        actor_state(12, "vehicle.yamaha.yzf", -70.0, -1.75, 180.0),
    ]
    return snapshot_of(actors, weather), 1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", type=Path, default=DEFAULT_TOWN, help="OpenDRIVE file (default Town10HD)")
    parser.add_argument("--synthetic", action="store_true", help="use the synthetic crossroads instead of a town")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--weather", type=int, default=26, help="Bench2Drive weather id")
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING)
    weather = preset(args.weather)

    t0 = time.perf_counter()
    if args.synthetic or not args.town.exists():
        suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=0), RigConfig())
        snapshot, ego_id = _synthetic_snapshot(weather)
        where = "synthetic crossroads"
    else:
        from b2d_data.maps import load_opendrive

        town = load_opendrive(args.town)
        suite = SensorSuite(town, RigConfig(), seed=0)
        snapshot, ego_id = town_snapshot(town, None, weather, seed=0)
        where = town.name
    setup = time.perf_counter() - t0
    renderer = suite.renderer.gl_renderer if suite.renderer else "none"
    print(f"scene: {where}, {len(suite.scene.mesh)} static triangles, set-up {setup:.2f} s, GL: {renderer}")

    suite.capture(snapshot, ego_id)  # warm-up: compiles the shader variants
    keys = ("actors", "cameras", "lidar", "radar", "wall")
    rows: dict[str, list[float]] = {k: [] for k in keys}
    cpu: list[float] = []
    load_before = os.getloadavg()[0]
    for _ in range(args.repeats):
        c = time.process_time()
        suite.capture(snapshot, ego_id)
        cpu.append(time.process_time() - c)
        for key in keys:
            rows[key].append(getattr(suite.timings, key))
    suite.close()
    labels = {
        "actors": "actor meshes, fixtures, Embree dynamic build",
        "cameras": "6 cams + top-down 1600x900 render + read-back",
        "lidar": "LiDAR 64 x 1000 static+dynamic (worker)",
        "radar": "5 radars (worker)",
        "wall": "whole capture (wall)",
    }
    print(f"median of {args.repeats} captures, seconds (machine load average before: {load_before:.2f}):")
    for key in keys:
        values = rows[key]
        print(f"  {labels[key]:<46} {statistics.median(values):7.3f}   (min {min(values):.3f})")
    print(f"  {'process CPU time per capture (all threads)':<46} {statistics.median(cpu):7.3f}")
    total = statistics.median(rows["wall"])
    best = min(rows["wall"]) / BUDGET_S
    print(f"render budget {BUDGET_S:.2f} s: ratio {total / BUDGET_S:.2f} (best capture {best:.2f})")


if __name__ == "__main__":
    main()
