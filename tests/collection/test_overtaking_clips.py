"""One tiny clip of each overtaking/give-way scenario type loads through ``ClipDataset`` and annotates its actors.

The routes are generated routes of the default town cut to ~22 m: the scenarios' actors stand 40–90 m after the
start, inside the 100 m annotation radius, so every clip carries them while taking only seconds to record.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from b2d_data.cli.collect import main
from b2d_data.codecs.anno_json import read_anno
from b2d_data.collection.towns import TownSource, load_map
from b2d_data.format.names import ClipName
from b2d_data.scenarios.route_xml import write_routes

TINY = ["--width", "64", "--height", "36", "--lidar-azimuth-steps", "90", "--encode-workers", "0", "--no-progress"]
ROUTE_LENGTH = 22.0
#: Scenario type → (class, type id prefix) of boxes its clip must carry.
EXPECTED: dict[str, set[tuple[str, str]]] = {
    "ParkedObstacle": {("vehicle", "vehicle."), ("traffic_sign", "static.prop.warningaccident")},
    "AccidentTwoWays": {("vehicle", "vehicle.dodge.charger_police_2020"), ("traffic_sign", "static.prop.warningaccident")},
    "ConstructionObstacle": {("traffic_sign", "static.prop.constructioncone"),
                             ("traffic_sign", "static.prop.trafficwarning"),
                             ("traffic_sign", "static.prop.warningconstruction")},
    "ConstructionObstacleTwoWays": {("traffic_sign", "static.prop.constructioncone"),
                                    ("traffic_sign", "static.prop.trafficwarning")},
    "HazardAtSideLaneTwoWays": {("vehicle", "vehicle.")},
    "VehicleOpensDoorTwoWays": {("vehicle", "vehicle.")},
    "InvadingTurn": {("traffic_sign", "static.prop.constructioncone")},
}  # fmt: skip


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    from b2d_data.scenarios import placement

    folder = tmp_path_factory.mktemp("town")
    town = TownSource(preset="all").materialise(folder)
    world_map = load_map(town)
    routes = []
    for scenario_type in EXPECTED:
        route = placement.make_routes(world_map, scenario_type, 1, seed=0, params="bench2drive220")[0]
        start = route.waypoints[0]
        keep = tuple(p for p in route.waypoints if math.hypot(p.x - start.x, p.y - start.y) <= ROUTE_LENGTH)
        routes.append(replace(route, waypoints=keep))
    path = folder / "short.xml"
    write_routes(routes, path)
    out = tmp_path_factory.mktemp("corpus") / "data"
    scenarios = [arg for t in EXPECTED for arg in ("--scenario", t)]
    assert main(["--routes", str(path), "--xodr", str(town.xodr), *scenarios, "--out", str(out), *TINY]) == 0
    return out


def test_one_clip_of_each_type_loads_and_annotates_the_scenario_actors(corpus):
    from b2d_data import ClipDataset

    clips = sorted(p for p in corpus.iterdir() if p.is_dir() and (p / "anno").is_dir())
    by_type = {ClipName.parse(c.name).scenario: c for c in clips}
    assert sorted(by_type) == sorted(EXPECTED)
    ds = ClipDataset(corpus, index="memory", semantic=True, instance=True, keep_anno=True)
    assert len(ds) > 0 and ds[len(ds) - 1]["images"].shape == (6, 36, 64, 3)
    for scenario_type, clip in by_type.items():
        anno = read_anno(max((clip / "anno").glob("*.json.gz")))
        boxes = {(b["class"], b.get("type_id", "")) for b in anno["bounding_boxes"][1:]}
        for cls, prefix in EXPECTED[scenario_type]:
            assert any(c == cls and t.startswith(prefix) for c, t in boxes), (scenario_type, cls, prefix, boxes)
