"""Render the same poses with two checkouts of the renderer and compare every camera's output (a check, not a test).

    python scripts/compare_renders.py --save new.npz                          # this checkout
    PYTHONPATH=<old checkout> python scripts/compare_renders.py --save old.npz
    python scripts/compare_renders.py --compare old.npz new.npz

Full resolution, a shipped town's static scene, three ego poses and three weathers; prints, per output, how many
values differ and by how much at most.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from b2d_data.collection import towns
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.map_mesh import layout_from_map
from b2d_data.sim.builtin.sensors.suite import SensorSuite, town_scene
from b2d_data.sim.builtin.sensors.synthetic import actor_state, snapshot_of

WEATHERS = (
    WeatherParameters(cloudiness=30.0, sun_altitude_angle=60.0, sun_azimuth_angle=45.0),
    WeatherParameters(cloudiness=90.0, precipitation=60.0, wetness=80.0, precipitation_deposits=70.0,
                      sun_altitude_angle=-30.0),  # fmt: skip
    WeatherParameters(fog_density=60.0, fog_distance=10.0, sun_altitude_angle=20.0),
)


def render(town: str) -> dict[str, np.ndarray]:
    """Every camera output for three poses × three weathers on ``town``, keyed by pose, weather, camera, field."""
    world_map = towns.load_map(towns.shipped_town(town))
    config = RigConfig(float_depth=False, jpeg_planes="gpu", lidar=False, radar=False)
    suite = SensorSuite.from_scene(town_scene(layout_from_map(world_map)), config, seed=1)
    out: dict[str, np.ndarray] = {}
    try:
        for k, (x, y, yaw) in enumerate(((100.0, 55.0, 0.0), (150.0, 60.0, 90.0), (90.0, 130.0, 200.0))):
            ego = actor_state(1, "vehicle.lincoln.mkz_2020", x, y, yaw, role_name="hero")
            other = actor_state(2, "vehicle.tesla.model3", x + 12.0, y + 1.0, yaw)
            for w, weather in enumerate(WEATHERS):
                for cam, frame in suite.capture(snapshot_of([ego, other], weather, frame=k), 1).cameras.items():
                    for field in ("rgb", "depth", "semantic", "labels"):
                        value = getattr(frame, field)
                        if value is not None:
                            out[f"{k}/{w}/{cam}/{field}"] = np.ascontiguousarray(value)
                    for i, plane in enumerate(frame.jpeg_planes or ()):
                        out[f"{k}/{w}/{cam}/plane{i}"] = plane
    finally:
        suite.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", default="Town01")
    parser.add_argument("--save", type=Path)
    parser.add_argument("--compare", type=Path, nargs=2)
    args = parser.parse_args()
    if args.save:
        np.savez_compressed(args.save, **render(args.town))
    if args.compare:
        a, b = (np.load(p) for p in args.compare)
        assert set(a.files) == set(b.files), "the two files hold different outputs"
        by_field: dict[str, list[int]] = {}
        for key in sorted(a.files):
            diff = np.abs(a[key].astype(np.int64) - b[key].astype(np.int64))
            stats = by_field.setdefault(key.rsplit("/", 1)[1], [0, 0, 0])
            stats[0] += int(np.count_nonzero(diff))
            stats[1] = max(stats[1], int(diff.max()))
            stats[2] += diff.size
        for field, (count, worst, size) in sorted(by_field.items()):
            print(f"{field:<9} {count:>9} of {size:>10} values differ, by at most {worst}")


if __name__ == "__main__":
    main()
