"""Builtin-simulator speed: world step time versus number of actors, and the full-rig frame time.

1. **World step**: a BuiltinSimulator on a town with N vehicles driven by the background-traffic lane follower;
   milliseconds per 20 Hz tick, printed against the real-time budget of one tick (50 ms) as a ratio.
2. **Full-rig frame**: the whole recording path of one 10 Hz frame at full resolution — two world ticks with
   traffic, the Bench2Drive rig (6 × 1600×900 cameras with depth / semantic / instance, top-down, 64-channel LiDAR,
   5 radars), the annotation, and JPEG/PNG/LAZ/h5/JSON encoding through the ClipWriter's worker processes — wall
   seconds per frame in steady state (the writer's final flush included, spread over the frames), printed
   against the 0.5 s bound as a ratio.

    python scripts/bench_sim.py [--town Town10HD] [--frames 20] [--width 1600 --height 900] [--skip-world]

On a GPU machine the renderer picks the NVIDIA EGL device by itself (``B2D_EGL_DEVICE=<i>`` forces one).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import numpy as np

from b2d_data.collection.data_agent import DataAgent
from b2d_data.format.names import ClipName
from b2d_data.format.transform import Location, Transform
from b2d_data.maps.towns import resolve_town
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorSpec, RigConfig, VehicleControl
from b2d_data.sim.builtin import BuiltinSimulator
from b2d_data.writers.clip_writer import ClipWriter

TICK_BUDGET_S = 0.05
FRAME_BOUND_S = 0.5


def _route(town, length: float = 300.0) -> list:
    """A long driving route from the town's first spawn point with enough road ahead."""
    for spawn in town.get_spawn_points():
        wp = town.get_waypoint(spawn.location)
        ahead = wp.next(length)
        if ahead:
            return town.trace_route(wp.transform.location, ahead[0].transform.location)
    raise RuntimeError(f"{town.name}: no spawn point with {length} m of road ahead")


def world_step(town, counts: list[int], ticks: int, seed: int) -> None:
    """Print ms per tick with N vehicles driven by the background lane follower (IDM + pure pursuit)."""
    from b2d_data.sim.builtin.lane_following import DrivingAgent, LanePath, TrafficDriver

    print(f"World step on {town.name} ({ticks} ticks each; vehicles driven by the background lane follower):")
    print("| vehicles | world tick ms | driver ms | total ms / tick | ratio to the 50 ms tick |")
    print("|---:|---:|---:|---:|---:|")
    spawns = town.get_spawn_points()
    for n in counts:
        sim = BuiltinSimulator(town, seed=seed)
        rng = np.random.default_rng(seed)
        agents = []
        for spawn in spawns:
            if len(agents) >= n:
                break
            actor = sim.try_spawn_actor(blueprints.random_background_car(rng), spawn)
            if actor is not None:
                wp = town.get_waypoint(spawn.location)
                agents.append(DrivingAgent(actor, LanePath(wp, rng), target_speed=8.0))
        driver = TrafficDriver(town)
        snapshot = sim.tick()
        tick_s = drive_s = 0.0
        for step in range(ticks + 5):
            t0 = time.perf_counter()
            for actor, out in driver.plan(snapshot, agents).items():
                sim.apply_control(actor, out.control)
            t1 = time.perf_counter()
            snapshot = sim.tick()
            t2 = time.perf_counter()
            if step >= 5:  # warm-up: first paths, stop-line index
                drive_s += t1 - t0
                tick_s += t2 - t1
        tick_ms, drive_ms = 1000 * tick_s / ticks, 1000 * drive_s / ticks
        total = (tick_ms + drive_ms) / 1000
        print(f"| {len(agents)} | {tick_ms:.1f} | {drive_ms:.1f} | {1000 * total:.1f} | {total / TICK_BUDGET_S:.3f} |")
        sim.close()


def full_rig(town, frames: int, width: int, height: int, workers: int, seed: int) -> None:
    """Print the steady-state wall time of one recorded frame."""
    route = _route(town)
    sim = BuiltinSimulator(town, seed=seed)
    start = route[0][0].transform
    ego = sim.spawn_actor(ActorSpec(blueprints.EGO_TYPE_ID, role_name="hero"),
                          Transform(Location(start.location.x, start.location.y, start.location.z + 0.5),
                                    start.rotation))  # fmt: skip
    sim.background.start(ego, [wp for wp, _ in route])
    config = RigConfig(width=width, height=height, top_down_width=width, top_down_height=height)
    sim.attach_rig(ego, config)
    agent = DataAgent(town, list(DenseRoute.from_pairs(route, town)), config)
    for _ in range(20):  # let traffic appear around the ego
        sim.apply_control(ego, VehicleControl(throttle=0.3))
        sim.tick()
    with tempfile.TemporaryDirectory() as tmp:
        name = ClipName("HardBreakRoute", town.name if town.name.startswith("Town") else "Town100", 1, 0)
        writer = ClipWriter(tmp, name, workers=workers)
        times: list[float] = []
        capture: list[float] = []
        warmup = 3  # the first captures build the static scene and compile shaders
        t_start = time.perf_counter()
        for index in range(frames + warmup):
            if index == warmup:
                t_start = time.perf_counter()
            t0 = time.perf_counter()
            for _ in range(2):
                sim.apply_control(ego, VehicleControl(throttle=0.3))
                snapshot = sim.tick()
            t1 = time.perf_counter()
            data = sim.read_sensors()
            t2 = time.perf_counter()
            writer.write(agent.make_record(index, snapshot, data, ego))
            if index >= warmup:
                capture.append(t2 - t1)
                times.append(time.perf_counter() - t0)
        writer.close()
        total = time.perf_counter() - t_start
    sim.close()
    warm = times
    per_frame = total / frames
    print(f"\nFull-rig frame on {town.name}: {width}×{height} cameras, {frames} frames, writer workers={workers}")
    print(f"  sensor capture (render + LiDAR + radar), median: {statistics.median(capture):.3f} s")
    print(f"  frame loop (2 ticks + capture + annotation + hand-off), median: {statistics.median(warm):.3f} s")
    print(f"  wall per frame including the writer's final flush: {per_frame:.3f} s")
    print(f"  ratio to the {FRAME_BOUND_S} s bound: {per_frame / FRAME_BOUND_S:.2f}  "
          f"({'within' if per_frame <= FRAME_BOUND_S else 'over'} the bound)")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", default="Town10HD", help="town name, preset or .xodr (default Town10HD)")
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=900)
    parser.add_argument("--workers", type=int, default=2, help="writer encoder processes")
    parser.add_argument("--ticks", type=int, default=200, help="ticks per world-step measurement")
    parser.add_argument("--counts", default="0,10,25,50,100", help="vehicle counts for the world step")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--skip-world", action="store_true")
    parser.add_argument("--skip-rig", action="store_true")
    args = parser.parse_args()
    town = resolve_town(args.town)
    if not args.skip_world:
        world_step(town, [int(c) for c in args.counts.split(",")], args.ticks, args.seed)
    if not args.skip_rig:
        full_rig(town, args.frames, args.width, args.height, args.workers, args.seed)


if __name__ == "__main__":
    main()
