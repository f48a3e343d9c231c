"""b2d-collect finds the shipped CARLA towns and route files by name (no map folder needed)."""

from __future__ import annotations

from pathlib import Path

from b2d_data import data
from b2d_data.collection.job import CollectConfig
from b2d_data.collection.plan import plan_collection


def test_generated_routes_on_a_shipped_carla_town(tmp_path: Path) -> None:
    plan = plan_collection(CollectConfig(out=tmp_path, scenarios=("HardBreakRoute",), n=1, town="Town01"))
    assert [t.xodr for t in plan.towns] == [data.carla_maps_dir() / "Town01.xodr"]
    tasks = plan.scenarios[0].tasks
    assert tasks and all(t.route.town == "Town01" for t in tasks)


def test_a_bare_shipped_route_file_name_runs_on_the_shipped_towns(tmp_path: Path) -> None:
    config = CollectConfig(out=tmp_path, scenarios=("HardBreakRoute",), routes_file=Path("bench2drive220.xml"))
    plan = plan_collection(config)
    tasks = [t for p in plan.scenarios for t in p.tasks]
    # bench2drive220.xml has HardBreakRoute routes 24330 (Town10HD), 24781 (Town01) and 26406 (Town04) on the
    # shipped towns; its other HardBreakRoute routes are on towns we do not ship and are skipped.
    assert {t.route.id for t in tasks} == {"24330", "24781", "26406"}
    assert {t.town.xodr.parent for t in tasks} == {data.carla_maps_dir()}
