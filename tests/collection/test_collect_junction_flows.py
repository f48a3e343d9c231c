"""One tiny clip of each junction-flow scenario of issue 12 is collected by ``b2d-collect`` and loads through
``ClipDataset``; the crossing bicycles are annotated as bicycles with their riders.

Each generated route is cut to 14 m before its junction (its new trigger point) to just after it (the scenario needs
the junction on the route), so that a clip takes seconds.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from b2d_data.cli.collect import main
from b2d_data.codecs.anno_json import read_anno
from b2d_data.collection.towns import TownSource, load_map
from b2d_data.format.names import ClipName
from b2d_data.format.semantic import SemanticTag
from b2d_data.scenarios.route_xml import write_routes

TYPES = (
    "NonSignalizedJunctionLeftTurn", "SignalizedJunctionRightTurn", "SignalizedJunctionLeftTurnEnterFlow",
    "NonSignalizedJunctionLeftTurnEnterFlow", "EnterActorFlow", "CrossingBicycleFlow",
)  # fmt: skip
TINY = ["--width", "64", "--height", "36", "--lidar-azimuth-steps", "90", "--encode-workers", "0", "--no-progress"]


@pytest.fixture(scope="module")
def collection(tmp_path_factory) -> Path:
    from b2d_data.scenarios import placement

    folder = tmp_path_factory.mktemp("town")
    town = TownSource(preset="all").materialise(folder)
    world_map = load_map(town)
    routes = []
    for scenario_type in TYPES:
        route = placement.make_routes(world_map, scenario_type, 1, seed=0, params="bench2drive220")[0]
        # keypoints skip the junction: keep the last ones before it (the widest gap) and the first one past it,
        # and move the trigger to the new start
        gaps = [a.distance(b) for a, b in zip(route.waypoints, route.waypoints[1:])]
        last = gaps.index(max(gaps)) + 1
        keep = route.waypoints[max(0, last - 8) : last + 1]
        scenario = route.scenarios[0]
        trigger = replace(scenario.trigger_point, location=keep[0])
        routes.append(replace(route, waypoints=keep, scenarios=(replace(scenario, trigger_point=trigger),)))
    path = folder / "junction_flows.xml"
    write_routes(routes, path)
    out = tmp_path_factory.mktemp("corpus") / "data"
    assert main(["--routes", str(path), "--xodr", str(town.xodr), "--out", str(out), "--seed", "3", *TINY]) == 0
    return out


def test_one_clip_per_junction_flow_type_loads(collection):
    from b2d_data import ClipDataset

    clips = sorted(p for p in collection.iterdir() if p.is_dir() and (p / "anno").is_dir())
    assert sorted(ClipName.parse(c.name).scenario for c in clips) == sorted(TYPES)
    ds = ClipDataset(collection, index="memory", semantic=True, keep_anno=True)
    assert len(ds) > 0
    sample = ds[len(ds) - 1]
    assert sample["images"].shape == (6, 36, 64, 3) and sample["boxes"].shape[1] == 7


def test_crossing_bicycles_are_annotated_as_bicycles_with_riders(collection):
    clip = next(p for p in collection.iterdir() if p.name.startswith("CrossingBicycleFlow_"))
    bikes = [
        box
        for f in sorted((clip / "anno").glob("*.json.gz"))
        for box in read_anno(f)["bounding_boxes"]
        if box.get("base_type") == "bicycle"
    ]
    assert bikes, "no bicycle in the clip's annotations"
    for box in bikes:
        assert box["class"] == "vehicle" and box["type_id"].startswith("vehicle.")
        assert set(box["semantic_tags"]) == {int(SemanticTag.BICYCLE), int(SemanticTag.RIDER)}
