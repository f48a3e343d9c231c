"""One tiny clip of each issue-14 scenario type (and a NoScenario clip) collected from a route file and loaded.

The generated routes of the default town are cut to ~12–35 m around the scenario's place (the junction, or the
trigger point) so that each clip takes seconds.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from b2d_data.cli.collect import main
from b2d_data.collection import run_log as rl
from b2d_data.collection.towns import TownSource, load_map
from b2d_data.format.names import ClipName
from b2d_data.format.scenario_types import BY_XML_TYPE
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.scenarios.placement import LAYOUTS
from b2d_data.scenarios.route_xml import Route, write_routes

TYPES = (
    "NoScenario", "VanillaNonSignalizedTurn", "VanillaSignalizedTurnEncounterGreenLight", "T_Junction",
    "OppositeVehicleTakingPriority", "ParkingCrossingPedestrian", "ControlLoss", "BlockedIntersection",
    "PedestrianCrossing", "VehicleTurningRoutePedestrian", "VehicleTurningRoute", "ParkingCutIn", "StaticCutIn",
)  # fmt: skip
TINY = ["--width", "32", "--height", "18", "--lidar-azimuth-steps", "45", "--encode-workers", "0", "--no-progress"]


def _short(route: Route) -> Route:
    """The route cut to a few metres around its scenario's place.

    Junction routes keep 16 m before the junction and 2–4 m after it (keypoints skip the junction: the first gap
    wider than 3 m), their trigger moved onto the cut route's start; OppositeVehicleTakingPriority keeps its whole
    approach (the crossing car must come in time). The others keep 4 m before and 8 m after the trigger point.
    """
    points = route.waypoints
    gaps = [k for k in range(len(points) - 1) if points[k].distance_2d(points[k + 1]) > 3.0]
    scenario = route.scenarios[0] if route.scenarios else None
    if scenario is not None and not LAYOUTS[scenario.type].is_junction:
        t = scenario.trigger_point.location
        k = min(range(len(points)), key=lambda i: math.hypot(points[i].x - t.x, points[i].y - t.y))
        return replace(route, waypoints=points[max(0, k - 2) : k + 5])
    first = 0 if scenario is not None and scenario.type == "OppositeVehicleTakingPriority" else max(0, gaps[0] - 8)
    keep = points[first : gaps[0] + 3]
    if scenario is None or first == 0:
        return replace(route, waypoints=keep)
    yaw = math.degrees(math.atan2(keep[1].y - keep[0].y, keep[1].x - keep[0].x))
    trigger = Transform(Location(keep[0].x, keep[0].y, keep[0].z), Rotation(yaw=yaw))
    return replace(route, waypoints=keep, scenarios=(replace(scenario, trigger_point=trigger),))


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    """A corpus holding the clips of one short route per type."""
    from b2d_data.scenarios import placement

    folder = tmp_path_factory.mktemp("town")
    town = TownSource(preset="all").materialise(folder)
    world_map = load_map(town)
    routes = [_short(placement.make_routes(world_map, t, 1, seed=0, params="bench2drive220")[0]) for t in TYPES]
    path = folder / "issue14.xml"
    write_routes(routes, path)
    out = tmp_path_factory.mktemp("corpus") / "data"
    main(["--routes", str(path), "--xodr", str(town.xodr), "--seed", "3", "--out", str(out), *TINY])
    return out


def test_one_clip_of_each_type_loads(corpus):
    from b2d_data import ClipDataset

    records = rl.final_records(rl.read_run_log(corpus / rl.LOG_FILE))
    failed = {r["clip"]: r.get("reason") for r in records if r["status"] != "clip"}
    assert not failed, failed
    prefixes = {"NoScenario" if t == "NoScenario" else BY_XML_TYPE[t].clip_prefix for t in TYPES}
    ds = ClipDataset(corpus, index="memory", semantic=True, instance=True, keep_anno=True)
    names = [ClipName.parse(c) for c in ds.clip_names]
    assert sorted(n.scenario for n in names) == sorted(prefixes) and {n.town for n in names} == {"Town100"}
    first: dict[str, int] = {}
    for i in range(len(ds)):
        first.setdefault(ds.frame_key(i)[0], i)
    assert set(first) == set(ds.clip_names)
    for index in first.values():
        sample = ds[index]
        assert sample["images"].shape == (6, 18, 32, 3)
        assert sample["semantic"].shape == sample["instance"].shape == (6, 18, 32)
        assert sample["lidar"].ndim == 2 and sample["boxes"].shape[1] == 7
