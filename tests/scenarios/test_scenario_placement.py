"""Scenario placement on the generated towns and on CARLA towns: candidates, routes, parameters, replay."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from b2d_data.format.weather import PRESETS, preset
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.framework import SCENARIO_CLASSES, UnknownScenarioError
from b2d_data.scenarios.placement import LAYOUTS, PlacementError, find_candidates, make_routes, route_id
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import read_routes, write_routes
from b2d_data.scenarios.triggers import trigger_route_index

IMPLEMENTED = sorted(t for t in SCENARIO_CLASSES if not t.endswith("ForTests"))


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


@pytest.fixture(scope="module")
def interurban(tmp_path_factory):
    return load_opendrive(write_town("interurban", 0, tmp_path_factory.mktemp("towns")))


def test_every_implemented_type_has_a_layout():
    # NoScenario: plain routes, a layout without a behaviour
    assert sorted(set(LAYOUTS) - {"NoScenario"}) == IMPLEMENTED and "NoScenario" in LAYOUTS
    assert len(IMPLEMENTED) >= 30  # issue 4's 12, issue 12's 6 and issue 14's 12


def test_no_scenario_routes_hold_no_scenario_and_cross_a_junction(town):
    routes = make_routes(town, "NoScenario", 3, seed=1)
    # the index after the 44 types: (1 × 100 + 44) × 10000 + k + 1
    assert [r.id for r in routes] == ["1440001", "1440002", "1440003"]
    for r in routes:
        assert r.scenarios == () and r.scenario_type is None
        dense = DenseRoute.from_route(town, r)
        assert any(wp.is_junction for wp in dense.waypoints) and not dense.waypoints[0].is_junction


@pytest.mark.parametrize("scenario_type", IMPLEMENTED)
def test_candidates_exist_in_the_all_layouts_preset(town, scenario_type):
    candidates = find_candidates(town, scenario_type)
    assert candidates, f"no place for {scenario_type}"
    assert all(c.scenario_type == scenario_type and not c.trigger.is_junction for c in candidates)
    spec = candidates[0].spec  # the default parameter set's layout (EnterActorFlow: its training on-ramp one)
    assert all(c.spec is spec for c in candidates)
    if spec.is_junction:
        assert all(c.connection is not None and c.connection.turn in spec.turns for c in candidates)


def _in(value: str, lo: int, hi: int) -> bool:
    return lo <= int(value) <= hi


def test_accident_routes_are_complete_and_checked(town):
    # bench2drive220's ranges and route lengths (the training set's: tests/scenarios/test_param_ranges.py)
    routes = make_routes(town, "Accident", 4, seed=3, params="bench2drive220")
    assert [r.id for r in routes] == [route_id(3, "Accident", k) for k in range(4)]
    assert len({r.id for r in routes}) == 4
    for k, r in enumerate(routes):
        assert r.town == town.name and len(r.scenarios) == 1
        sc = r.scenarios[0]
        assert (sc.name, sc.type) == (f"Accident_{k + 1}", "Accident")
        assert _in(sc.parameter("distance"), 40, 44) and _in(sc.parameter("speed"), 53, 57)
        assert sc.parameter("direction") == "right"
        # two identical weather entries at 0 % and 100 %, one of the 23 presets
        (p0, w0), (p1, w1) = r.weathers
        assert (p0, p1) == (0.0, 100.0) and w0 == w1 and w0 in PRESETS.values()
        pts = np.array([[p.x, p.y] for p in r.waypoints])
        steps = np.hypot(*np.diff(pts, axis=0).T)
        # keypoints 2 m apart along the lane's reference line (a little more on the outside of curves)
        assert np.all((steps > 1.9) & (steps < 2.3))
        dense = DenseRoute.from_route(town, r)
        assert 120.0 <= dense.total_length <= 160.0
        index = trigger_route_index(dense, sc.trigger_point)
        assert index is not None and 8.0 <= dense.cumulative_length[index] <= 16.0


def test_junction_routes_turn_through_their_junction(town):
    for r in make_routes(town, "SignalizedJunctionLeftTurn", 3, seed=0, params="bench2drive220"):
        sc = r.scenarios[0]
        assert _in(sc.parameter("flow_speed"), 9, 11)
        assert _in(sc.parameter("source_dist_interval", "from"), 15, 24)
        assert _in(sc.parameter("source_dist_interval", "to"), 25, 28)
        dense = DenseRoute.from_route(town, r)
        assert 50.0 <= dense.total_length <= 105.0  # Bench2Drive's junction routes are 60-90 m
        index = trigger_route_index(dense, sc.trigger_point)
        assert index is not None and dense.cumulative_length[index] <= 10.0
        inside = [k for k, wp in enumerate(dense.waypoints) if wp.is_junction]
        assert inside and inside[0] > index
    for r in make_routes(town, "OppositeVehicleRunningRedLight", 3, seed=0):
        assert r.scenarios[0].parameter("direction") in ("left", "right", "opposite")


def test_routes_are_deterministic_and_replay_identically(town, tmp_path):
    first = make_routes(town, "DynamicObjectCrossing", 3, seed=7, weathers=[1, 2])
    again = make_routes(town, "DynamicObjectCrossing", 3, seed=7, weathers=[1, 2])
    assert first == again
    assert all(r.weathers[0][1] in (preset(1), preset(2)) for r in first)
    other = make_routes(town, "DynamicObjectCrossing", 3, seed=8, weathers=[1, 2])
    assert {r.id for r in other}.isdisjoint({r.id for r in first})
    path = tmp_path / "routes.xml"
    write_routes(first + make_routes(town, "ParkingExit", 2, seed=7), path)
    back = read_routes(path)
    assert back[:3] == first
    assert [r.scenarios[0].type for r in back] == ["DynamicObjectCrossing"] * 3 + ["ParkingExit"] * 2


def test_more_routes_than_places_reuse_places_with_new_parameters(town):
    candidates = find_candidates(town, "VanillaNonSignalizedTurnEncounterStopsign")
    routes = make_routes(town, "VanillaNonSignalizedTurnEncounterStopsign", len(candidates) + 3, seed=0)
    assert len(routes) == len(candidates) + 3
    assert len({r.id for r in routes}) == len(routes)


def test_missing_layouts_and_unknown_types_are_explained(interurban, town):
    with pytest.raises(PlacementError, match="layout 'multi_lane' missing"):
        make_routes(interurban, "Accident", 1)
    with pytest.raises(PlacementError, match="layout 'signalized_junction' missing"):
        make_routes(interurban, "SignalizedJunctionLeftTurn", 1)
    with pytest.raises(UnknownScenarioError, match="known types: Accident"):
        make_routes(town, "Nope", 1)
    with pytest.raises(KeyError):
        make_routes(town, "Accident", 1, weathers=[99])
    assert make_routes(town, "Accident", 0) == []


def test_carla_towns(carla_maps_dir):
    town04 = load_opendrive(carla_maps_dir / "Town04.xodr")
    assert len(make_routes(town04, "YieldToEmergencyVehicle", 2, seed=0)) == 2
    town07 = load_opendrive(carla_maps_dir / "Town07.xodr")
    # Town07's stop signs govern the junctions' connecting lanes
    assert find_candidates(town07, "VanillaNonSignalizedTurnEncounterStopsign")
    town01 = load_opendrive(carla_maps_dir / "Town01.xodr")
    assert make_routes(town01, "ParkedObstacleTwoWays", 1, seed=0)
    with pytest.raises(PlacementError, match="parking_lane"):
        make_routes(town01, "ParkingExit", 1)


def test_layouts_are_registered_beside_their_scenarios():
    # issue 23 "Structure": the catalog registers every layout; placement.py names no scenario type
    import b2d_data.scenarios.placement as placement_module
    from b2d_data.format.scenario_types import SCENARIO_TYPES
    from b2d_data.scenarios.catalog.layout import LAYOUTS as REGISTERED
    from b2d_data.scenarios.catalog.layout import register_layouts

    assert LAYOUTS is REGISTERED
    source = Path(placement_module.__file__).read_text(encoding="utf-8")
    assert [t.xml_type for t in SCENARIO_TYPES if f'"{t.xml_type}"' in source] == []
    with pytest.raises(ValueError, match="registered already"):
        register_layouts({"Accident": LAYOUTS["Accident"]})
    assert LAYOUTS["Accident"] is REGISTERED["Accident"]  # the failed call changed nothing


def test_a_single_place_is_redrawn_when_its_first_draw_fails(tmp_path):
    """Town100 has one highway exit; with seed 53 its first draw gives a planner route that leaves the planned lanes,
    and make_routes gave up ('none of the 1 places ... gives a valid HighwayExit route'). It now redraws."""
    town = load_opendrive(write_town("all", 0, tmp_path))
    assert len(find_candidates(town, "HighwayExit")) == 1
    routes = make_routes(town, "HighwayExit", 2, seed=53)
    assert [r.scenario_type for r in routes] == ["HighwayExit", "HighwayExit"]
    assert len({r.id for r in routes}) == 2
