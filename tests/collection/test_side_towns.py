"""``b2d-collect --scenario`` without ``--town``: a drawn side the default town has no place for (``direction=left``
of the kerb-side types) goes to the generated town that has one (Town104); a chosen town keeps every route."""

from __future__ import annotations

import logging
from pathlib import Path

from b2d_data.collection.job import CollectConfig
from b2d_data.collection.plan import plan_collection
from b2d_data.collection.towns import load_map
from b2d_data.scenarios import placement


def test_left_draws_of_an_unpinned_run_go_to_the_one_way_town(tmp_path: Path) -> None:
    config = CollectConfig(out=tmp_path / "c", scenarios=("ParkingCutIn",), n=4, sensors=False)
    plan = plan_collection(config)
    assert [t.xodr.name for t in plan.towns] == ["Town100.xodr", "Town104.xodr"]
    (scenario,) = plan.scenarios
    routes = [t.route for t in scenario.tasks]
    assert len(routes) == 12  # the budget: 3 attempts per clip x 4
    here = [r for r in routes if r.town == "Town100"]
    there = [r for r in routes if r.town == "Town104"]
    assert here and there and len({r.id for r in routes}) == 12
    assert {r.scenarios[0].parameter("direction") for r in here} == {"right"}
    assert {r.scenarios[0].parameter("direction") for r in there} == {"left"}
    # the default town's routes are its first ones for that many, as a run without the move would have them
    town100 = load_map(plan.towns[0])
    assert here == placement.make_routes(town100, "ParkingCutIn", len(here), 0)
    # the moved routes run on their own town's file
    assert {t.town.xodr.name for t in scenario.tasks if t.route.town == "Town104"} == {"Town104.xodr"}


def test_a_chosen_town_keeps_every_route_and_logs_the_missing_side(tmp_path: Path, caplog) -> None:
    config = CollectConfig(out=tmp_path / "c", scenarios=("ParkingCutIn",), n=4, sensors=False, town="all")
    with caplog.at_level(logging.WARNING, logger="b2d_data.scenarios.placement"):
        plan = plan_collection(config)
    assert [t.xodr.name for t in plan.towns] == ["Town100.xodr"]
    routes = [t.route for t in plan.scenarios[0].tasks]
    assert {r.town for r in routes} == {"Town100"}
    assert {r.scenarios[0].parameter("direction") for r in routes} == {"right"}
    assert "Town100 has no place for ParkingCutIn with direction=left" in caplog.text
