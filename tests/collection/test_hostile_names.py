"""Names read from route and results files never become paths outside the folders they belong in (issue 25 item 4)."""

from __future__ import annotations

from pathlib import Path

import pytest

from b2d_data import data
from b2d_data.collection.job import CollectConfig
from b2d_data.collection.plan import CollectError, plan_collection
from b2d_data.format import names

_ROUTE = (
    "<routes>\n<route id='24211' town='{town}'>\n<waypoints><position x='0' y='0' z='0'/></waypoints>\n"
    "<scenarios>\n<scenario name='Accident_1' type='{type}'><trigger_point x='0' y='0' z='0' yaw='0'/></scenario>\n"
    "</scenarios></route></routes>"
)


def test_scenario_type_escaping_out_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    routes = tmp_path / "q_evil_type.xml"
    routes.write_text(_ROUTE.format(town="Town01", type="../../evil"))
    out = tmp_path / "a" / "b" / "out"
    with pytest.raises(CollectError) as exc:
        plan_collection(CollectConfig(out=out, routes_file=routes))
    assert f"{routes}: line 5: scenario type '../../evil' is not a plain name" in str(exc.value)
    # The old plan accepted it and the crash record went to out/results/../../evil_Town01_Route24211_Weather*.json.
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["q_evil_type.xml"]


def test_route_town_climbing_out_of_the_xodr_folder_is_refused(tmp_path: Path) -> None:
    maps = tmp_path / "maps"
    maps.mkdir()
    # A map one level above --xodr DIR: what town="../Town200" would have reached.
    (tmp_path / "Town200.xodr").write_bytes((data.carla_maps_dir() / "Town01.xodr").read_bytes())
    routes = tmp_path / "town.xml"
    routes.write_text(_ROUTE.format(town="../Town200", type="Accident"))
    with pytest.raises(CollectError) as exc:
        plan_collection(CollectConfig(out=tmp_path / "out", routes_file=routes, xodr=maps))
    assert f"{routes}: line 2: route town '../Town200' is not a plain name" in str(exc.value)


@pytest.mark.parametrize(("scenario", "town"), [("../../evil", "Town01"), ("Accident", "../Town01"), ("a/b", "Town01")])
def test_clip_names_refuse_path_parts(scenario: str, town: str) -> None:
    with pytest.raises(names.UnsafeNameError, match="is not a plain name"):
        names.ClipName(scenario, town, 1, 0)
