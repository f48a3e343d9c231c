"""Leaderboard checkpoint JSON: round trips, message formats, penalties and the global record."""

from __future__ import annotations

import json
import math
from datetime import datetime

import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location


def test_vad_merged_file_round_trips_key_for_key(b2d_data_dir, tmp_path):
    path = b2d_data_dir / "VAD_merged_results.json"
    original = json.loads(path.read_text())
    results = lb.read_results(path)
    assert results.merged and len(results.records) == 213 and results.records[0].index is None
    assert results.extra == {"driving score": original["driving score"], "success rate": 0.15, "eval num": 214}
    # Same content and the same key order everywhere (json.dumps keeps insertion order).
    assert json.dumps(results.to_dict()) == json.dumps(original)
    out = tmp_path / "copy.json"
    lb.write_results(results, out)
    assert json.loads(out.read_text()) == original


def test_vad_record_fields(b2d_data_dir):
    record = lb.read_results(b2d_data_dir / "VAD_merged_results.json").records[0]
    assert record.route_id == "RouteScenario_4937_rep0" and record.route_number == "4937" and record.repetition == 0
    assert record.town_name == "Town12" and record.status == "Completed" and record.num_infractions == 19
    assert record.scores.score_route == 100 and record.meta.route_length == 65.304
    assert record.infraction_counts()[lb.MIN_SPEED_INFRACTIONS] == 17 and not record.success


def test_messages_match_the_leaderboard_text():
    # The first VAD record's collision, from an unrounded ego location.
    assert (
        lb.collision_message("vehicle.mini.cooper_s_2021", 56246, Location(3130.10512, 5245.41288, 368.31711))
        == "Agent collided against object with type=vehicle.mini.cooper_s_2021 and id=56246 "
        "at (x=3130.105, y=5245.413, z=368.317)"
    )
    assert (
        lb.outside_lanes_message(4.0, 6.1249)
        == "Agent went outside its route lanes for about 4.0 meters (6.12% of the completed route)"
    )
    red = lb.red_light_message(971, (341.25, 209.1, 0.1041))
    assert red == "Agent ran a red light 971 at (x=341.25, y=209.1, z=0.104)"
    assert lb.stop_message(12, Location(1, 2, 3)) == "Agent ran a stop with id=12 at (x=1.0, y=2.0, z=3.0)"
    assert lb.route_deviation_message(Location(95.92, 165.6731, 0.138)).endswith("at (x=95.92, y=165.673, z=0.138)")
    assert lb.blocked_message(Location(8.541, 326.009, 0.001)) == "Agent got blocked at (x=8.541, y=326.009, z=0.001)"
    assert lb.min_speed_message(round(89.2071, 2)) == "Average speed is 89.21% of the surrounding traffic's one"
    assert lb.min_speed_message(100) == "Average speed is 100% of the surrounding traffic's one"
    assert lb.route_timeout_message() == "Route timeout."
    assert lb.scenario_timeout_message() == "Agent timed out a scenario"
    assert lb.yield_emergency_message() == "Agent failed to yield to an emergency vehicle"


def test_message_parsers():
    assert lb.parse_min_speed_percentage(lb.min_speed_message(3306.64)) == 3306.64
    assert lb.parse_min_speed_percentage(lb.min_speed_message(100)) == 100.0
    assert lb.parse_outside_lanes(lb.outside_lanes_message(12.5, 3.25)) == (12.5, 3.25)
    assert lb.parse_outside_lanes("something else") is None


def test_collision_typing():
    assert lb.collision_key("static.prop.trafficcone01") == lb.COLLISIONS_LAYOUT
    assert lb.collision_key("traffic.traffic_light") == lb.COLLISIONS_LAYOUT
    assert lb.collision_key("static.sidewalk") is None  # 'sidewalk' excluded from layout, matches nothing else
    assert lb.collision_key("vehicle.tesla.model3") == lb.COLLISIONS_VEHICLE
    assert lb.collision_key("walker.pedestrian.0001") == lb.COLLISIONS_PEDESTRIAN


def test_penalties():
    # The first VAD record: one vehicle collision (0.6) and 6.125 % outside its lanes (1 − 0.06125)
    # gives 0.6 × 0.93875 = 0.56325, its recorded score_penalty.
    penalty = lb.score_penalty([(lb.COLLISIONS_VEHICLE, None), (lb.OUTSIDE_ROUTE_LANES, 6.125)])
    assert penalty == pytest.approx(0.56325)
    scores = lb.Scores.compose(100, penalty)
    assert (scores.score_route, scores.score_penalty, scores.score_composed) == (100, 0.56325, 56.325)
    assert lb.penalty_factor(lb.MIN_SPEED_INFRACTIONS, 20.0) == 1.0  # 'unused' in Bench2Drive
    assert lb.penalty_factor(lb.ROUTE_DEV) == 1.0 and lb.penalty_factor(lb.STOP_INFRACTION) == 0.8
    with pytest.raises(ValueError, match="percentage"):
        lb.penalty_factor(lb.OUTSIDE_ROUTE_LANES)
    with pytest.raises(KeyError, match="unknown infraction key"):
        lb.penalty_factor("speeding")


def test_status_and_success_rules():
    assert lb.route_status(True, 0) == "Perfect" and lb.route_status(True, 3) == "Completed"
    assert lb.route_status(False, 0, "Agent got blocked") == "Failed - Agent got blocked"
    assert lb.route_status(False, 1) == "Failed"
    infractions = lb.empty_infractions()
    infractions[lb.MIN_SPEED_INFRACTIONS].append(lb.min_speed_message(50.0))
    assert lb.is_success("Completed", infractions)
    infractions[lb.ROUTE_TIMEOUT].append(lb.route_timeout_message())
    assert not lb.is_success("Completed", infractions)  # route_timeout is part of the check
    assert not lb.is_success("Failed - TickRuntime", lb.empty_infractions())


def _two_records() -> list[lb.RouteRecord]:
    first = lb.RouteRecord(route_id="RouteScenario_1_rep0", status="Completed", town_name="Town01", index=0)
    first.add_infraction(lb.COLLISIONS_VEHICLE, lb.collision_message("vehicle.audi.tt", 5, Location()))
    first.add_infraction(lb.OUTSIDE_ROUTE_LANES, lb.outside_lanes_message(50.0, 5.0))
    first.add_infraction(lb.MIN_SPEED_INFRACTIONS, lb.min_speed_message(80.0))
    first.add_infraction(lb.MIN_SPEED_INFRACTIONS, lb.min_speed_message(90.0))
    first.scores = lb.Scores(100, 0.6, 60)
    first.meta = lb.RouteMeta(1000.0, 10.0, 20.0)
    second = lb.RouteRecord(route_id="RouteScenario_2_rep0", status="Failed - Agent got blocked", index=1)
    second.add_infraction(lb.VEHICLE_BLOCKED, lb.blocked_message(Location()))
    second.scores = lb.Scores(50, 1.0, 50)
    second.meta = lb.RouteMeta(2000.0, 30.0, 40.0)
    second.town_name = "Town02"
    return [first, second]


def test_global_record_by_hand():
    records = _two_records()
    g = lb.compute_global_record(records, total_routes=3)
    # Means over 3 routes: composed (60 + 50) / 3, route (100 + 50) / 3, penalty (0.6 + 1.0) / 3.
    assert g.scores_mean == {"score_composed": 36.666667, "score_route": 50.0, "score_penalty": 0.533333}
    # Std dev over the records against the rounded means, divided by total − 1 = 2, rounded to 3 decimals.
    expected = math.sqrt(((60 - 36.666667) ** 2 + (50 - 36.666667) ** 2) / 2)  # 19.00292...
    assert g.scores_std_dev["score_composed"] == round(expected, 3) == 19.003
    # km driven: 1 km × 100 % + 2 km × 50 % = 2 km. Counts per km; outside lanes in km (50 m), not divided.
    assert g.infractions[lb.COLLISIONS_VEHICLE] == 0.5 and g.infractions[lb.VEHICLE_BLOCKED] == 0.5
    assert g.infractions[lb.MIN_SPEED_INFRACTIONS] == 1.0 and g.infractions[lb.OUTSIDE_ROUTE_LANES] == 0.05
    assert g.status == "Failed" and g.exceptions == [["RouteScenario_2_rep0", 1, "Failed - Agent got blocked"]]
    assert (g.total_length, g.duration_game, g.duration_system) == (3000.0, 40.0, 60.0)
    assert lb.global_values(g) == [
        "36.666667", "50.0", "0.533333", "0.0", "0.5", "0.0", "0.0", "0.0", "0.05", "0.0", "0.0", "0.5", "0.0",
        "0.0", "1.0",
    ]  # fmt: skip
    single = lb.compute_global_record(records[:1], total_routes=1)
    assert single.scores_std_dev == {"score_composed": 0, "score_route": 0, "score_penalty": 0}


def test_checkpoint_file_round_trip_and_key_order(tmp_path):
    results = lb.LeaderboardResults(records=_two_records(), progress=[2, 3], sensors=["carla_camera"])
    lb.finalize(results, 3)
    assert results.entry_status == "Finished" and results.eligible and results.labels == list(lb.LABELS)
    path = tmp_path / "eval_0.json"
    lb.write_results(results, path)
    data = json.loads(path.read_text())
    assert list(data) == ["_checkpoint", "entry_status", "eligible", "sensors", "values", "labels"]
    assert list(data["_checkpoint"]) == ["global_record", "progress", "records"]
    assert list(data["_checkpoint"]["records"][0]) == [
        "index", "route_id", "scenario_name", "weather_id", "save_name", "status", "num_infractions",
        "infractions", "scores", "meta", "town_name",
    ]  # fmt: skip
    assert list(data["_checkpoint"]["records"][0]["infractions"]) == list(lb.INFRACTION_KEYS)
    again = lb.read_results(path)
    assert not again.merged and again == results


def test_record_in_progress_is_not_written():
    record = lb.RouteRecord(route_id="RouteScenario_3_rep0")  # index −1: still running
    results = lb.LeaderboardResults(records=[record])
    assert results.to_dict()["_checkpoint"]["records"] == []


def test_entry_status_follows_crashes():
    crashed = lb.RouteRecord(route_id="RouteScenario_1_rep0", status="Failed - Simulation crashed")
    assert lb.entry_status_of([crashed]) == "Crashed"
    assert lb.entry_status_of([]) == "Finished"


def test_save_name_and_route_id():
    route_id = lb.record_route_id(1711)
    assert route_id == "RouteScenario_1711_rep0"
    when = datetime(2024, 8, 21, 22, 13, 59)
    assert (
        lb.make_save_name(route_id, "Town12", "ParkingCutIn_1", "0", when)
        == "RouteScenario_1711_rep0_Town12_ParkingCutIn_1_0_08_21_22_13_59"
    )


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("", "file is empty"),
        ("{not json", "not JSON: Expecting property name"),
        ("[1, 2]", "top level is a list"),
        ('{"Overtaking": 0.3}', "no '_checkpoint' object"),
        ('{"_checkpoint": {"records": {}}}', "'_checkpoint.records' is missing or not a list"),
        ('{"_checkpoint": {"records": [{"route_id": "RouteScenario_1_rep0", "status": "Completed"}]}}',
         "record 0 (RouteScenario_1_rep0) lacks 'infractions'"),
    ],
)  # fmt: skip
def test_not_leaderboard_json_names_file_and_problem(tmp_path, text, problem):
    path = tmp_path / "results.json"
    path.write_text(text)
    with pytest.raises(lb.LeaderboardFormatError) as exc:
        lb.read_results(path)
    assert str(exc.value).startswith(f"{path}: ") and problem in str(exc.value)
