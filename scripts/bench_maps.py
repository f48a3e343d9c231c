"""Time the map package on the CARLA towns against its bounds.

Per town: OpenDRIVE load (bound 5 s), route-graph build, ``get_waypoint`` per call at random locations around the
town (bound 1 ms), ``Waypoint.next(1.0)`` per call, and ``interpolate_trajectory`` per Bench2Drive route of that
town. Each line prints the measured value, the bound and their ratio (< 1 is within the bound).

    python scripts/bench_maps.py [--maps DIR_OF_XODR] [--routes ROUTES.xml] [--queries 2000]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from lxml import etree

from b2d_data import data
from b2d_data.format.transform import Location
from b2d_data.maps import load_opendrive

LOAD_BOUND_S = 5.0
GET_WAYPOINT_BOUND_S = 1e-3
NEXT_BOUND_S = 1e-3
ROUTE_BOUND_S = 1.0


def _line(what: str, value: float, bound: float, unit: str = "s") -> str:
    scale, label = (1e3, "ms") if unit == "ms" else (1.0, "s")
    measured, limit = f"{value * scale:9.3f} {label}", f"{bound * scale:7.3f} {label}"
    return f"  {what:<34} {measured}   bound {limit}   ratio {value / bound:6.3f}"


def _routes(path: Path) -> dict[str, list[list[Location]]]:
    routes: dict[str, list[list[Location]]] = {}
    if not path.is_file():
        return routes
    for route in etree.parse(str(path)).getroot().iter("route"):
        points = [Location(float(p.get("x")), float(p.get("y")), float(p.get("z"))) for p in route.iter("position")]
        routes.setdefault(route.get("town", ""), []).append(points)
    return routes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--maps", type=Path, default=data.carla_maps_dir(), help="folder of .xodr towns")
    parser.add_argument("--routes", type=Path, default=data.bench2drive_file("bench2drive220.xml"))
    parser.add_argument("--queries", type=int, default=2000, help="get_waypoint / next calls per town")
    args = parser.parse_args()
    routes = _routes(args.routes)
    rng = np.random.default_rng(0)
    for xodr in sorted(args.maps.glob("*.xodr")):
        start = time.perf_counter()
        town = load_opendrive(xodr)
        load_s = time.perf_counter() - start
        start = time.perf_counter()
        town.route_graph()
        graph_s = time.perf_counter() - start
        centres = np.concatenate([seg.data[:, :3] for seg in town.lane_segments()])
        lo, hi = centres.min(axis=0), centres.max(axis=0)
        points = rng.uniform(lo, hi, size=(args.queries, 3))
        start = time.perf_counter()
        waypoints = [town.get_waypoint(p) for p in points]
        get_s = (time.perf_counter() - start) / len(points)
        start = time.perf_counter()
        for wp in waypoints:
            wp.next(1.0)
        next_s = (time.perf_counter() - start) / len(waypoints)
        print(f"{town.name}: {len(town.data.roads)} roads, {len(town.lane_segments())} lane sections")
        print(_line("load_opendrive", load_s, LOAD_BOUND_S))
        print(_line("route graph (1 m)", graph_s, LOAD_BOUND_S))
        print(_line("get_waypoint per call", get_s, GET_WAYPOINT_BOUND_S, "ms"))
        print(_line("Waypoint.next(1.0) per call", next_s, NEXT_BOUND_S, "ms"))
        town_routes = routes.get(xodr.stem, [])
        if town_routes:
            times = []
            for keypoints in town_routes:
                start = time.perf_counter()
                town.interpolate_trajectory(keypoints)
                times.append(time.perf_counter() - start)
            print(_line(f"interpolate_trajectory ({len(times)} routes)", statistics.median(times), ROUTE_BOUND_S))


if __name__ == "__main__":
    main()
