"""The default junction provider: which town file it looks for, a missing map, and a real Town01 route."""

from __future__ import annotations

import pytest

from b2d_data.eval.abilities import MAP_MISSING, JunctionUnavailable, compute_abilities
from b2d_data.eval.junctions import MapJunctionProvider, find_town_map
from b2d_data.format import leaderboard as lb
from b2d_data.format.scenario_types import Ability
from b2d_data.format.transform import Location
from b2d_data.scenarios.route_xml import Route, read_routes


def test_find_town_map_in_flat_and_carla_layouts(tmp_path):
    (tmp_path / "Town01.xodr").write_text("<OpenDRIVE/>")
    (tmp_path / "OpenDrive").mkdir()
    (tmp_path / "OpenDrive" / "Town02.xodr").write_text("<OpenDRIVE/>")
    (tmp_path / "Town03" / "OpenDrive").mkdir(parents=True)
    (tmp_path / "Town03" / "OpenDrive" / "Town03.xodr").write_text("<OpenDRIVE/>")
    assert find_town_map(tmp_path, "Town01") == tmp_path / "Town01.xodr"
    assert find_town_map(tmp_path, "Town02") == tmp_path / "OpenDrive" / "Town02.xodr"
    assert find_town_map(tmp_path, "Town03") == tmp_path / "Town03" / "OpenDrive" / "Town03.xodr"
    assert find_town_map(tmp_path, "Town12") is None


def test_missing_town_map_is_reported_with_its_kind(carla_maps_dir):
    provider = MapJunctionProvider(carla_maps_dir)
    route = Route(id="1711", town="Town12", waypoints=(Location(0, 0, 0), Location(2, 0, 0)))
    with pytest.raises(JunctionUnavailable) as exc:
        provider(route)
    assert exc.value.kind == MAP_MISSING
    assert "Town12" in str(exc.value) and str(carla_maps_dir) in str(exc.value)


def test_default_provider_on_a_real_bench2drive220_route(b2d_data_dir, carla_maps_dir):
    route = {r.id: r for r in read_routes(b2d_data_dir / "bench2drive220.xml")}["28035"]  # T_Junction, Town01
    provider = MapJunctionProvider(carla_maps_dir)
    lookup = provider(route)
    # CARLA measured this route as 120.817 m (meta.route_length of VAD's record); at a 1 m hop the densified
    # route holds about that many waypoints, and a T-junction route enters its junction well before the end.
    assert 115 <= lookup.num_waypoints <= 135
    assert lookup.first_junction is not None and 1 < lookup.first_junction + 8 < lookup.num_waypoints
    assert provider(route) is lookup  # served from the cache the second time

    # A failed run of this route earns the Traffic_Signs credit just above the junction threshold, not below it.
    threshold = (lookup.first_junction + 8) / lookup.num_waypoints
    for completion, credited in ((threshold + 0.01, True), (threshold - 0.01, False)):
        record = lb.RouteRecord(route_id=lb.record_route_id("28035"), status="Failed - TickRuntime", town_name="Town01")
        record.scores = lb.Scores.compose(100 * completion, 1.0)
        result = compute_abilities([record], [route], provider)
        assert result.scores[Ability.TRAFFIC_SIGNS].successes == int(credited)
        assert result.traffic_sign_checks[0].checked
