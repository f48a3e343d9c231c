"""Criteria results → Leaderboard records, with scores, statuses and messages worked out by hand."""

from __future__ import annotations

from datetime import datetime

import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import preset
from b2d_data.scenarios.criteria import CriteriaResult, Infraction
from b2d_data.scenarios.route_xml import Route, ScenarioConfig
from b2d_data.scenarios.statistics import checkpoint_results, route_record

WHEN = datetime(2024, 5, 17, 13, 4, 5)
AT = Location(1.0, 2.0, 0.0)


def route(weather_id: int = 3) -> Route:
    scenario = ScenarioConfig(name="ParkingCutIn_1", type="ParkingCutIn", trigger_point=Transform(AT, Rotation()))
    return Route(id="1711", town="Town12", waypoints=(AT, Location(50.0, 2.0, 0.0)), scenarios=(scenario,),
                 weathers=((0.0, preset(weather_id)),))


def vehicle_hit() -> Infraction:
    return Infraction(lb.COLLISIONS_VEHICLE, lb.collision_message("vehicle.tesla.model3", 42, AT), 10)


def red_light() -> Infraction:
    return Infraction(lb.RED_LIGHT, lb.red_light_message(7, AT), 20)


def min_speed(value: float) -> Infraction:
    return Infraction(lb.MIN_SPEED_INFRACTIONS, lb.min_speed_message(value), 30, percentage=value)


def record(result: CriteriaResult, failure: str = "", **kwargs) -> lb.RouteRecord:
    return route_record(route(), result, 152.99909645917796, 11.2, 2.3456, failure_message=failure, when=WHEN,
                        **kwargs)


def test_identity_fields_and_meta():
    r = record(CriteriaResult(100.0, ()), index=4)
    assert r.route_id == "RouteScenario_1711_rep0" and r.index == 4
    assert r.scenario_name == "ParkingCutIn_1" and r.town_name == "Town12"
    assert r.weather_id == "3"
    assert r.save_name == "RouteScenario_1711_rep0_Town12_ParkingCutIn_1_3_05_17_13_04_05"
    assert r.meta.to_dict() == {"route_length": 152.999, "duration_game": 11.2, "duration_system": 2.346}


def test_no_infraction_and_completed_is_perfect():
    r = record(CriteriaResult(100.0, ()))
    assert r.status == "Perfect" and r.num_infractions == 0 and r.success
    assert r.scores.to_dict() == {"score_route": 100.0, "score_penalty": 1.0, "score_composed": 100.0}


def test_penalties_multiply():
    # One vehicle collision (0.6) and one red light (0.7): 0.42; 100 % done → 42 and "Completed".
    r = record(CriteriaResult(100.0, (vehicle_hit(), red_light())))
    assert r.scores.to_dict() == {"score_route": 100.0, "score_penalty": 0.42, "score_composed": 42.0}
    assert r.status == "Completed" and r.num_infractions == 2 and not r.success
    assert r.infractions[lb.COLLISIONS_VEHICLE] == [
        "Agent collided against object with type=vehicle.tesla.model3 and id=42 at (x=1.0, y=2.0, z=0.0)"
    ]
    assert r.infractions[lb.RED_LIGHT] == ["Agent ran a red light 7 at (x=1.0, y=2.0, z=0.0)"]


def test_all_fixed_factors():
    events = tuple(Infraction(key, "m", 1) for key in (
        lb.COLLISIONS_PEDESTRIAN, lb.COLLISIONS_LAYOUT, lb.STOP_INFRACTION, lb.SCENARIO_TIMEOUTS,
        lb.YIELD_EMERGENCY_VEHICLE))  # fmt: skip
    r = record(CriteriaResult(50.0, events))
    # 0.5 × 0.65 × 0.8 × 0.7 × 0.7 = 0.1274; 50 % of the route → 6.37.
    assert r.scores.score_penalty == 0.1274 and r.scores.score_composed == 6.37


def test_min_speed_messages_count_but_do_not_penalise():
    r = record(CriteriaResult(100.0, (min_speed(80.5), min_speed(120.0))))
    assert r.status == "Completed" and r.num_infractions == 2
    assert r.scores.score_penalty == 1.0 and r.scores.score_composed == 100.0
    assert r.success  # Bench2Drive success ignores min-speed messages
    assert r.infractions[lb.MIN_SPEED_INFRACTIONS] == [
        "Average speed is 80.5% of the surrounding traffic's one",
        "Average speed is 120.0% of the surrounding traffic's one",
    ]


def test_outside_lanes_multiplies_by_one_minus_the_percentage():
    event = Infraction(lb.OUTSIDE_ROUTE_LANES, lb.outside_lanes_message(10.0, 25.0), 5, percentage=25.0)
    r = record(CriteriaResult(100.0, (event,)))
    assert r.scores.score_penalty == 0.75 and r.scores.score_composed == 75.0
    assert r.infractions[lb.OUTSIDE_ROUTE_LANES] == [
        "Agent went outside its route lanes for about 10.0 meters (25.0% of the completed route)"
    ]


def test_an_unfinished_route_fails_with_its_reason():
    # The ego drove 80 % and ran out of ticks.
    r = record(CriteriaResult(80.0, ()), failure="TickRuntime")
    assert r.status == "Failed - TickRuntime" and not r.success
    assert r.scores.to_dict() == {"score_route": 80.0, "score_penalty": 1.0, "score_composed": 80.0}
    assert record(CriteriaResult(80.0, ())).status == "Failed"


def test_criteria_failures_override_the_outside_reason():
    deviation = Infraction(lb.ROUTE_DEV, lb.route_deviation_message(AT), 50)
    blocked = Infraction(lb.VEHICLE_BLOCKED, lb.blocked_message(AT), 60)
    r = record(CriteriaResult(31.0, (deviation,), route_timeout=True), failure="TickRuntime")
    # The timeout names "Agent timed out" first; the deviation event comes later and wins.
    assert r.status == "Failed - Agent deviated from the route"
    assert r.infractions[lb.ROUTE_TIMEOUT] == ["Route timeout."] and r.num_infractions == 2
    assert record(CriteriaResult(31.0, (), route_timeout=True)).status == "Failed - Agent timed out"
    assert record(CriteriaResult(31.0, (deviation, blocked))).status == "Failed - Agent got blocked"
    assert r.scores.score_penalty == 1.0  # deviation, blocked and timeout end the route without a factor


def test_a_completed_route_stays_completed_whatever_stopped_the_loop():
    assert record(CriteriaResult(100.0, ()), failure="TickRuntime").status == "Perfect"


def test_unknown_keys_are_rejected():
    with pytest.raises(ValueError, match="unknown infraction key"):
        record(CriteriaResult(100.0, (Infraction("speeding", "m", 1),)))


def test_checkpoint_file_round_trip(tmp_path):
    records = [record(CriteriaResult(100.0, (vehicle_hit(), red_light())), index=0),
               record(CriteriaResult(80.0, ()), failure="TickRuntime", index=1)]
    results = checkpoint_results(records)
    path = tmp_path / "eval.json"
    lb.write_results(results, path)
    back = lb.read_results(path)
    assert [r.to_dict() for r in back.records] == [r.to_dict() for r in records]
    assert back.progress == [2, 2] and back.entry_status == "Finished" and back.eligible
    # Means over the two routes: DS (42 + 80) / 2 = 61, RC 90, IP (0.42 + 1) / 2 = 0.71.
    assert back.global_record.scores_mean == {"score_composed": 61.0, "score_route": 90.0, "score_penalty": 0.71}
    assert back.global_record.status == "Failed"
