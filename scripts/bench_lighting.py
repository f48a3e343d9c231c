"""CPU cost of the camera rig's rendering per weather, for comparing two checkouts of the renderer on llvmpipe.

Renders the full camera rig (six 1600×900 cameras with uint8 depth, semantic and instance, and the top-down camera;
no LiDAR or radar) at a town's default place (``viz.town_scene``) under a few weathers and prints, per weather, the
median process CPU time of one capture (all threads: llvmpipe's rasteriser threads included) and its wall time.
Only APIs the code before the lighting (issue 24) already had are used, so the same file runs against both:

    PYTHONPATH=$PWD python scripts/bench_lighting.py                       # this checkout
    PYTHONPATH=/tmp/light_base python scripts/bench_lighting.py            # another one (same file)

``LP_NUM_THREADS`` defaults to 1 here, as in a route process of a 2-core collection (``layout.raster_threads``).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import statistics
import time

os.environ.setdefault("LP_NUM_THREADS", "1")
for _key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_key, "1")

from b2d_data.format.weather import PRESETS  # noqa: E402
from b2d_data.maps.towns import resolve_town  # noqa: E402
from b2d_data.sim.api import RigConfig  # noqa: E402
from b2d_data.sim.builtin.sensors.suite import SensorSuite  # noqa: E402
from b2d_data.viz.town_scene import town_snapshot  # noqa: E402

#: Clear noon (sharp shadows), the bench route's weather 3 (soft shadows), dense fog by day, clear night, night in
#: dense fog (beams lighting the fog).
DEFAULT_WEATHERS = (0, 3, 6, 22, 23, 25)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", default="Town100")
    parser.add_argument("--weather", type=int, action="append", help="weather id (repeatable)")
    parser.add_argument("--repeats", type=int, default=5, help="timed captures per weather (after one warm-up)")
    parser.add_argument("--size", default="1600x900", help="camera size WxH")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    w, _, h = args.size.partition("x")
    town = resolve_town(args.town)
    config = RigConfig(width=int(w), height=int(h), top_down_width=int(w), top_down_height=int(h), float_depth=False,
                       lidar=False, radar=False)  # fmt: skip
    suite = SensorSuite(town, config, seed=0)
    snapshot, ego_id = town_snapshot(town, None, PRESETS[0], seed=0)
    gl = suite.renderer.gl_renderer if suite.renderer is not None else "none"
    print(f"{args.town}, {args.size}, GL: {gl}, LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS')}", flush=True)
    total = []
    try:
        for weather_id in args.weather or DEFAULT_WEATHERS:
            shot = dataclasses.replace(snapshot, weather=PRESETS[weather_id])
            suite.capture(shot, ego_id)  # warm-up: shader variants compile
            cpu, wall = [], []
            for _ in range(args.repeats):
                c, t = time.process_time(), time.perf_counter()
                suite.capture(shot, ego_id)
                cpu.append(time.process_time() - c)
                wall.append(time.perf_counter() - t)
            total.append(statistics.median(cpu))
            print(f"weather {weather_id:>2}: CPU {1e3 * statistics.median(cpu):6.1f} ms (min {1e3 * min(cpu):6.1f}), "
                  f"wall {1e3 * statistics.median(wall):6.1f} ms per capture", flush=True)  # fmt: skip
    finally:
        suite.close()
    print(f"mean over weathers: CPU {1e3 * statistics.mean(total):.1f} ms per capture")


if __name__ == "__main__":
    main()
