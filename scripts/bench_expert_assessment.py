"""Cost of the per-frame expert vector (BEV raster + progress + action) against other per-frame work, same run.

An ego drives a route of a CARLA town with the builtin simulator's background traffic (no sensors). Every recorded
frame (two 20 Hz ticks) the script times, on the same snapshot:

- ``assessment_vector`` — what the data agent adds per frame for ``expert_assessment/`` (the raster, the value, the
  nearest action);
- ``bounding_boxes`` — the annotation's box list of the same snapshot (a part of the annotation the collector
  already builds every frame; LiDAR point counts off);
- the two world ticks of the frame.

It prints medians in ms and the ratios of the expert vector to both references, plus the one-off per-town cost (the
drivable-area KD-tree) and the npz size per frame.

    python scripts/bench_expert_assessment.py [--town Town10HD] [--frames 100] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from b2d_data.codecs.expert_npz import encode_expert
from b2d_data.collection import expert_assessment as ea
from b2d_data.collection.annotations import bounding_boxes
from b2d_data.format.transform import Location, Transform
from b2d_data.maps.towns import resolve_town
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorSpec, VehicleControl
from b2d_data.sim.builtin import BuiltinSimulator
from bench_sim import _route  # noqa: E402 - the script's own folder is on sys.path when run as a script


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", default="Town10HD", help="town name, preset or .xodr (default Town10HD)")
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    town = resolve_town(args.town)
    route = _route(town, 400.0)
    route_xy = np.array([(wp.transform.location.x, wp.transform.location.y) for wp, _ in route])

    t0 = time.perf_counter()
    rasterizer = ea.BevRasterizer(town)
    build_s = time.perf_counter() - t0

    sim = BuiltinSimulator(town, seed=args.seed)
    start = route[0][0].transform
    ego_id = sim.spawn_actor(ActorSpec(blueprints.EGO_TYPE_ID, role_name="hero"),
                             Transform(Location(start.location.x, start.location.y, start.location.z + 0.5),
                                       start.rotation))  # fmt: skip
    sim.background.start(ego_id, [wp for wp, _ in route])
    for _ in range(20):  # let traffic appear around the ego
        sim.apply_control(ego_id, VehicleControl(throttle=0.3))
        sim.tick()
    anno = {"throttle": 0.3, "steer": 0.0, "brake": 0.0, "reverse": False}
    tick_ms, boxes_ms, expert_ms, actors, lit = [], [], [], [], []
    size = 0
    index = 0
    for frame in range(args.frames):
        t0 = time.perf_counter()
        for _ in range(2):
            sim.apply_control(ego_id, VehicleControl(throttle=0.3))
            snapshot = sim.tick()
        t1 = time.perf_counter()
        ego = snapshot.actors[ego_id]
        d = np.hypot(route_xy[index : index + 40, 0] - ego.location.x, route_xy[index : index + 40, 1] - ego.location.y)
        index += int(np.argmin(d))
        ahead = route_xy[index : index + 50]
        t2 = time.perf_counter()
        bounding_boxes(town, snapshot, ego, None, ahead)
        t3 = time.perf_counter()
        vector = ea.assessment_vector(rasterizer, snapshot, ego, ahead, index / (len(route_xy) - 1), anno)
        t4 = time.perf_counter()
        tick_ms.append(1000 * (t1 - t0))
        boxes_ms.append(1000 * (t3 - t2))
        expert_ms.append(1000 * (t4 - t3))
        actors.append(len(snapshot.actors))
        lit.append(int(vector[2 * 256 : 3 * 256].sum()))
        if frame == 0:
            size = len(encode_expert(vector))
    sim.close()
    med = statistics.median
    print(f"Expert vector cost on {town.name}, {args.frames} frames, {med(actors):.0f} actors per snapshot (median), "
          f"{max(lit)} vehicle cells lit at most")  # fmt: skip
    print("| per frame | median ms | p90 ms |")
    print("|---|---:|---:|")
    for label, values in (("expert vector (raster + value + action)", expert_ms),
                          ("annotation bounding_boxes (reference)", boxes_ms),
                          ("two world ticks (reference)", tick_ms)):  # fmt: skip
        print(f"| {label} | {med(values):.2f} | {np.percentile(values, 90):.2f} |")
    print(f"ratio expert vector / bounding_boxes: {med(expert_ms) / med(boxes_ms):.2f}")
    print(f"ratio expert vector / two world ticks: {med(expert_ms) / med(tick_ms):.3f}")
    print(f"one-off per town (drivable-area KD-tree): {1000 * build_s:.0f} ms; npz per frame: {size} bytes")


if __name__ == "__main__":
    main()
