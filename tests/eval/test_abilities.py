"""Abilities as tools/ability_benchmark.py (v0.0.4) computes them, on the synthetic run and on VAD."""

from __future__ import annotations

import pytest

from b2d_data.eval.abilities import (
    ABILITIES,
    MAP_MISSING,
    NO_PROVIDER,
    compute_abilities,
    first_junction_lookup,
)
from b2d_data.eval.results import load_result_set
from b2d_data.format.leaderboard import read_results
from b2d_data.format.scenario_types import Ability
from b2d_data.scenarios.route_xml import read_routes


def _values(result):
    return {a.value: result.scores[a].value for a in ABILITIES}


def test_synthetic_abilities_with_traffic_sign_credit(synthetic_run, hand_junctions):
    routes = read_routes(synthetic_run.routes_file)
    result_set = load_result_set(synthetic_run.files, "synthetic")
    junctions = hand_junctions
    result = compute_abilities(result_set.records, routes, junctions)

    # Successes: 101 (Accident), 102 (ParkingCutIn), 106 (YieldToEmergencyVehicle); 107 never ran.
    # Overtaking {101}: 1/1. Merging {103 failed}: 0/1. Emergency_Brake {102 ok, 108 failed}: 1/2.
    # Give_Way {106 ok; 107 crashed, left out}: 1/1.
    # Traffic_Signs {103, 104, 105, 108}, no success; credit only for 103: completion 0.60 > (20 + 8) / 100.
    # 104 has 0.20 <= 0.28; 105 ran a red light (decided without a map); 108's town has no map (unchecked).
    scores = result.scores
    assert [(scores[a].successes, scores[a].routes) for a in ABILITIES] == [(1, 1), (0, 1), (1, 2), (1, 1), (1, 4)]
    assert _values(result) == {
        "Overtaking": 100.0,
        "Merging": 0.0,
        "Emergency_Brake": 50.0,
        "Give_Way": 100.0,
        "Traffic_Signs": 25.0,
    }
    assert result.mean == pytest.approx((100 + 0 + 50 + 100 + 25) / 5)  # 55
    assert scores[Ability.TRAFFIC_SIGNS].credited == 1
    assert [scores[a].routes_in_xml for a in ABILITIES] == [1, 1, 2, 2, 4]
    assert result.crashed == [("InvadingTurn", "107")]

    checks = {c.route_id: c for c in result.traffic_sign_checks}
    assert set(checks) == {"103", "104", "105", "108"}
    assert checks["103"].credited and checks["103"].threshold == pytest.approx(0.28)
    assert not checks["104"].credited and checks["104"].checked
    assert not checks["105"].credited and checks["105"].checked and "red light" in checks["105"].reason
    assert not checks["108"].checked and checks["108"].unchecked_kind == MAP_MISSING
    assert [c.route_id for c in result.unchecked] == ["108"]
    # The provider is only asked about failed Traffic_Signs routes without red-light/stop infractions.
    assert sorted(junctions.calls) == ["103", "104", "108"]


def test_without_provider_every_failed_traffic_sign_route_is_reported(synthetic_run):
    routes = read_routes(synthetic_run.routes_file)
    result = compute_abilities(load_result_set(synthetic_run.files, "s").records, routes, None)
    assert result.scores[Ability.TRAFFIC_SIGNS].successes == 0
    assert {c.route_id for c in result.unchecked} == {"103", "104", "108"}
    assert {c.unchecked_kind for c in result.unchecked} == {NO_PROVIDER}


def test_first_junction_lookup_is_one_based():
    lookup = first_junction_lookup([False, False, True, True, False])
    assert (lookup.first_junction, lookup.num_waypoints) == (3, 5)
    assert first_junction_lookup([False, False]).first_junction is None


def test_denominators_of_bench2drive220(b2d_data_dir):
    routes = read_routes(b2d_data_dir / "bench2drive220.xml")
    result = compute_abilities([], routes)
    # format.md §8.5: 45, 80, 60, 10, 95 routes per ability when every route has a record.
    assert [result.scores[a].routes_in_xml for a in ABILITIES] == [45, 80, 60, 10, 95]
    assert len(result.crashed) == 220 and all(result.scores[a].routes == 0 for a in ABILITIES)


def test_vad_abilities_without_map_credit(b2d_data_dir):
    records = read_results(b2d_data_dir / "VAD_merged_results.json").records
    routes = read_routes(b2d_data_dir / "bench2drive220.xml")
    result = compute_abilities(records, routes, None)
    # 7 of the 220 routes have no VAD record (4 HighwayExit, ParkingCutIn, EnterActorFlow, MergerIntoSlowTraffic);
    # they leave the denominators, so 45, 80, 60, 10, 95 become 45, 74, 59, 10, 94.
    missing = ["1711", "11715", "23659", "23687", "3800", "23670", "24041"]
    assert sorted(rid for _, rid in result.crashed) == sorted(missing)
    assert [(result.scores[a].successes, result.scores[a].routes) for a in ABILITIES] == [
        (11, 45),
        (6, 74),
        (11, 59),
        (2, 10),
        (4, 94),
    ]
    # Overtaking, Merging, Emergency_Brake and Give_Way equal Bench2Drive's published VAD row
    # (24.44, 8.11, 18.64, 20.00); Traffic_Signs lacks the map credit here (4.26 instead of the published 19.15).
    assert {k: round(v, 2) for k, v in _values(result).items()} == {
        "Overtaking": 24.44,
        "Merging": 8.11,
        "Emergency_Brake": 18.64,
        "Give_Way": 20.0,
        "Traffic_Signs": 4.26,
    }
    assert round(result.mean, 2) == 15.09
    # 90 failed Traffic_Signs routes: 14 ran a red light or stop sign, the other 76 need a map.
    assert len(result.traffic_sign_checks) == 90 and len(result.unchecked) == 76


def test_each_repetition_of_a_route_counts_as_one_run(synthetic_run):
    routes = read_routes(synthetic_run.routes_file)
    accident = next(r for r in load_result_set(synthetic_run.files, "s").records if r.route_number == "101")
    failed_rerun = read_results(synthetic_run.files[0]).records[0]  # any record object to copy the shape from
    failed_rerun.route_id = "RouteScenario_101_rep1"
    failed_rerun.status = "Failed - Agent got blocked"
    # Overtaking holds only route 101 (Accident): rep0 succeeded, rep1 failed → 1 success in 2 runs = 50 %
    result = compute_abilities([accident, failed_rerun], routes)
    assert (result.scores[Ability.OVERTAKING].successes, result.scores[Ability.OVERTAKING].routes) == (1, 2)
    assert result.scores[Ability.OVERTAKING].value == 50.0
