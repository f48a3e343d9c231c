"""Captures per second of an agent's own sensors (``MountedSensors``) against the Bench2Drive rig (``SensorSuite``).

Three rigs on one town snapshot (the ego and a few vehicles and walkers, ``viz.town_scene``), each captured
``--frames`` times after a warm-up capture, in the same run:

- ``b2d``: the Bench2Drive data-collection rig (6 cameras with depth / semantic / instance, the top-down camera,
  the 64-channel LiDAR, 5 radars, IMU / GNSS) at ``--width`` × ``--height``;
- ``uniad``: the UniAD / VAD agents' rig: six cameras at the Bench2Drive poses (``--width`` × ``--height``), the
  512×512 ``bev`` camera 50 m up (scaled with the width), IMU and GNSS, with the Leaderboard wrapper's attributes;
- ``lidar``: one LiDAR with the wrapper's forced attributes (half a turn of 64 × 469 rays per tick).

It prints each rig's median time per capture, captures per second, the ratio to the ``b2d`` capture and where the
time went. On the 2-core llvmpipe machine keep the images small:

    python scripts/bench_mounted_sensors.py --width 400 --height 225 --frames 10
    python scripts/bench_mounted_sensors.py [--town Town01] [--width 1600 --height 900] [--frames 20] [--weather 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import statistics
import time
from collections.abc import Callable

from b2d_data.closed_loop.sensor_config import preprocess_sensors
from b2d_data.format.rig import CAMERAS, LIDAR
from b2d_data.format.weather import preset
from b2d_data.maps.towns import resolve_town
from b2d_data.sim.api import RigConfig, SensorMount, Snapshot
from b2d_data.sim.builtin.sensors import CaptureTimings, MountedSensors, SensorSuite
from b2d_data.viz.town_scene import town_snapshot

FULL_WIDTH = 1600
BEV_SIZE = 512


def uniad_rig(width: int, height: int) -> list[SensorMount]:
    """The UniAD / VAD agents' physical sensors as the agent wrapper mounts them (the speedometer is no sensor)."""
    bev = max(16, round(BEV_SIZE * width / FULL_WIDTH))
    specs: list[dict] = [
        {"type": "sensor.camera.rgb", "id": c.sensor_id, "x": c.mount.x, "y": c.mount.y, "z": c.mount.z, "roll": 0.0,
         "pitch": 0.0, "yaw": c.mount.yaw, "width": width, "height": height, "fov": c.fov}
        for c in CAMERAS
    ]  # fmt: skip
    specs += [
        {"type": "sensor.other.imu", "id": "IMU", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0},
        {"type": "sensor.other.gnss", "id": "GPS", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0},
        {"type": "sensor.camera.rgb", "id": "bev", "x": 0.0, "y": 0.0, "z": 50.0, "roll": 0.0, "pitch": -90.0,
         "yaw": 0.0, "width": bev, "height": bev, "fov": 50},
    ]  # fmt: skip
    return preprocess_sensors(specs)[0]


def lidar_rig() -> list[SensorMount]:
    """One LiDAR at the Bench2Drive roof mount with the wrapper's forced attributes."""
    m = LIDAR.mount
    spec = {"type": "sensor.lidar.ray_cast", "id": "LIDAR", "x": m.x, "y": m.y, "z": m.z, "roll": 0.0, "pitch": 0.0,
            "yaw": 0.0}  # fmt: skip
    return preprocess_sensors([spec])[0]


def _time(capture: Callable[[Snapshot], object], timings: Callable[[], CaptureTimings], snapshot: Snapshot,
          frames: int) -> tuple[float, dict[str, float]]:  # fmt: skip
    """Median seconds per capture over ``frames`` ticks (after a warm-up) and the median of each timed part."""
    capture(snapshot)  # warm-up: compiles the shader variants, meshes the fixtures
    walls: list[float] = []
    parts: dict[str, list[float]] = {k: [] for k in ("actors", "cameras", "lidar", "radar")}
    for i in range(frames):
        tick = dataclasses.replace(snapshot, frame=snapshot.frame + 1 + i)  # the LiDARs' turn moves on
        t0 = time.perf_counter()
        capture(tick)
        walls.append(time.perf_counter() - t0)
        for key, values in parts.items():
            values.append(getattr(timings(), key))
    return statistics.median(walls), {k: statistics.median(v) for k, v in parts.items()}


def main() -> None:
    """Run the three rigs and print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", default="Town01", help="town name, preset or .xodr path (default Town01)")
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=900)
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--weather", type=int, default=1, help="Bench2Drive weather id")
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING)

    town = resolve_town(args.town)
    snapshot, ego_id = town_snapshot(town, None, preset(args.weather), seed=0)
    w, h = args.width, args.height
    b2d = SensorSuite(town, RigConfig(width=w, height=h, top_down_width=w, top_down_height=h), seed=0)
    rigs: dict[str, tuple[Callable[[Snapshot], object], SensorSuite | MountedSensors]] = {
        "b2d": (lambda s: b2d.capture(s, ego_id), b2d),
    }
    for name, mounts in (("uniad", uniad_rig(w, h)), ("lidar", lidar_rig())):
        rig = MountedSensors(town, mounts, seed=0, start_frame=snapshot.frame)
        rigs[name] = (lambda s, rig=rig: rig.capture(s, ego_id), rig)
    gl = b2d.renderer.gl_renderer if b2d.renderer is not None else "none"
    print(f"town {town.name}, {len(snapshot.actors)} actors, cameras {w}×{h}, {args.frames} frames, GL: {gl}")
    results = {}
    try:
        for name, (capture, rig) in rigs.items():
            results[name] = _time(capture, lambda rig=rig: rig.timings, snapshot, args.frames)
    finally:
        for _, rig in rigs.values():
            rig.close()
    base = results["b2d"][0]
    print(f"{'rig':<6} {'s/capture':>10} {'captures/s':>11} {'vs b2d':>7}   median parts (s)")
    for name, (wall, parts) in results.items():
        detail = "  ".join(f"{k} {v:.4f}" for k, v in parts.items())
        print(f"{name:<6} {wall:>10.4f} {1.0 / wall:>11.1f} {wall / base:>7.2f}   {detail}")


if __name__ == "__main__":
    main()
