"""Parameter sets of generated routes: LB2.0 training ranges (default) and bench2drive220's, through the CLIs."""

from __future__ import annotations

import importlib.util
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from b2d_data.cli import collect
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios import placement
from b2d_data.scenarios.param_ranges import PARAM_SETS, TRAINING, param_set
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.triggers import trigger_route_index

N = 8

# Worked out by hand from leaderboard-2.0's data/routes_training.xml (min/max over the scenarios that set them;
# "from"/"to" as (lo, hi) pairs; typos 3255 and "40" left out). Types not listed draw no numbers.
TRAINING_RANGES: dict[str, dict[str, tuple[int, int] | set[str]]] = {
    "Accident": {"distance": (50, 200), "direction": {"right", "left"}, "speed": (40, 70)},
    "ParkedObstacle": {"distance": (50, 160), "direction": {"right", "left"}, "speed": (40, 70)},
    "ConstructionObstacle": {"distance": (70, 200), "direction": {"right", "left"}, "speed": (40, 60)},
    "StaticCutIn": {"distance": (80, 170), "direction": {"right", "left"}},
    "AccidentTwoWays": {"distance": (70, 170), "frequency.from": (30, 75), "frequency.to": (105, 220)},
    "ParkedObstacleTwoWays": {"distance": (50, 130), "frequency.from": (15, 75), "frequency.to": (80, 200)},
    "ConstructionObstacleTwoWays": {"distance": (70, 300), "frequency.from": (35, 75), "frequency.to": (80, 220)},
    "HazardAtSideLane": {"distance": (50, 90), "speed": (30, 60), "bicycle_drive_distance": (60, 200),
                         "bicycle_speed": (8, 15)},
    "HazardAtSideLaneTwoWays": {"distance": (40, 135), "frequency": (75, 140), "bicycle_drive_distance": (40, 300),
                                "bicycle_speed": (5, 12)},
    "VehicleOpensDoorTwoWays": {"distance": (35, 80), "frequency.from": (25, 40), "frequency.to": (80, 105)},
    "InvadingTurn": {"distance": (90, 200)},
    "DynamicObjectCrossing": {"distance": (15, 70), "crossing_angle": (0, 20)},
    "ParkingCrossingPedestrian": {"distance": (30, 50), "crossing_angle": (5, 15)},
    "YieldToEmergencyVehicle": {"distance": (110, 140)},
    "SignalizedJunctionLeftTurn": {"flow_speed": (8, 19), "source_dist_interval.from": (10, 40),
                                   "source_dist_interval.to": (40, 85)},
    "NonSignalizedJunctionLeftTurn": {"flow_speed": (8, 20), "source_dist_interval.from": (10, 80),
                                      "source_dist_interval.to": (40, 110)},
    "SignalizedJunctionRightTurn": {"flow_speed": (10, 18), "source_dist_interval.from": (10, 40),
                                    "source_dist_interval.to": (35, 80)},
    "NonSignalizedJunctionRightTurn": {"flow_speed": (5, 21), "source_dist_interval.from": (10, 50),
                                       "source_dist_interval.to": (30, 110)},
    "EnterActorFlow": {"flow_speed": (15, 20), "source_dist_interval.from": (15, 30),
                       "source_dist_interval.to": (30, 70)},
    "CrossingBicycleFlow": {"flow_speed": (5, 10), "source_dist_interval.from": (5, 30),
                            "source_dist_interval.to": (18, 60)},
    "InterurbanActorFlow": {"flow_speed": (15, 20), "source_dist_interval.from": (25, 65),
                            "source_dist_interval.to": (75, 120)},
    "InterurbanAdvancedActorFlow": {"flow_speed": (15, 18), "source_dist_interval.from": (20, 50),
                                    "source_dist_interval.to": (75, 105)},
    "MergerIntoSlowTraffic": {"flow_speed": (8, 17), "source_dist_interval.from": (10, 20),
                              "source_dist_interval.to": (30, 50)},
    "HighwayExit": {"flow_speed": (10, 15), "source_dist_interval.from": (10, 25), "source_dist_interval.to": (25, 50)},
    # LB2.0-only (issue 23): its 9 scenarios set 18 / 22 / 15 m/s and 20-40 / 15-40 / 15-35 m
    "EnterActorFlowV2": {"flow_speed": (15, 22), "source_dist_interval.from": (15, 20),
                         "source_dist_interval.to": (35, 40)},
}  # fmt: skip

# The ranges the placement drew before the training set (expert-and-scenarios.md §2.2).
BENCH2DRIVE220_RANGES: dict[str, dict[str, tuple[int, int] | set[str]]] = {
    "Accident": {"distance": (40, 44), "direction": {"right"}, "speed": (53, 57)},
    "StaticCutIn": {"distance": (40, 45), "direction": {"right"}},
    "InvadingTurn": {"distance": (50, 60)},
    "YieldToEmergencyVehicle": {"distance": (26, 30)},
    "NonSignalizedJunctionRightTurn": {"flow_speed": (8, 11), "source_dist_interval.from": (18, 22),
                                       "source_dist_interval.to": (27, 30)},
}  # fmt: skip

# bench2drive220's largest distance, which each layout's junction-free stretch was sized for.
B2D_MAX_DISTANCE = {"Accident": 44, "StaticCutIn": 45, "InvadingTurn": 60, "ConstructionObstacleTwoWays": 45}

# Interurban and highway types are placed on their own presets, the rest on "all".
PRESET = {
    "InterurbanActorFlow": "interurban",
    "InterurbanAdvancedActorFlow": "interurban",
    "MergerIntoSlowTraffic": "highway",
    "HighwayExit": "highway",
}


@pytest.fixture(scope="module")
def towns(tmp_path_factory):
    folder = tmp_path_factory.mktemp("towns")
    return {p: load_opendrive(write_town(p, 0, folder)) for p in ("all", "interurban", "highway")}


def _value(scenario, name: str) -> str:
    key, _, attr = name.partition(".")
    return scenario.other_parameters[key][attr or "value"]


def _check(routes, ranges: dict[str, tuple[int, int] | set[str]]) -> dict[str, Counter]:
    seen: dict[str, Counter] = {name: Counter() for name in ranges}
    for r in routes:
        sc = r.scenarios[0]
        for name, allowed in ranges.items():
            value = _value(sc, name)
            seen[name][value] += 1
            if isinstance(allowed, set):
                assert value in allowed, (r.id, name, value)
            else:
                assert allowed[0] <= float(value) <= allowed[1], (r.id, name, value)
        interval = sc.other_parameters.get("source_dist_interval") or sc.other_parameters.get("frequency")
        if interval is not None and "from" in interval:
            assert float(interval["from"]) <= float(interval["to"]), (r.id, interval)
    return seen


@pytest.mark.parametrize("scenario_type", sorted(TRAINING_RANGES))
def test_training_routes_draw_inside_routes_training_ranges(towns, scenario_type):
    town = towns[PRESET.get(scenario_type, "all")]
    routes = placement.make_routes(town, scenario_type, N, seed=23)  # training is the default
    assert len(routes) == N
    seen = _check(routes, TRAINING_RANGES[scenario_type])
    if "direction" in seen and len(TRAINING_RANGES[scenario_type]["direction"]) > 1:
        assert set(seen["direction"]) == {"right", "left"}, seen["direction"]
    if scenario_type == "InvadingTurn":
        offsets = [float(r.scenarios[0].parameter("offset")) for r in routes]
        assert all(0.15 <= o <= 0.40 for o in offsets)


def test_training_distances_reach_past_bench2drive220_and_the_route_reaches_past_them(towns):
    town = towns["all"]
    for scenario_type, b2d_max in B2D_MAX_DISTANCE.items():
        spec = placement.LAYOUTS[scenario_type]
        routes = placement.make_routes(town, scenario_type, N, seed=23)
        distances = [float(r.scenarios[0].parameter("distance")) for r in routes]
        assert max(distances) > b2d_max + 40, (scenario_type, distances)
        for r, distance in zip(routes, distances):
            dense = DenseRoute.from_route(town, r)
            index = trigger_route_index(dense, r.scenarios[0].trigger_point)
            assert index is not None
            # the junction-free stretch after the actors is as long as with bench2drive220's distances
            after_trigger = dense.total_length - dense.cumulative_length[index]
            assert after_trigger >= spec.clear_after + (distance - b2d_max) - 3.0, (scenario_type, r.id, distance)


def test_yield_to_emergency_vehicle_has_room_behind_and_a_long_route(towns):
    town = towns["all"]
    for r in placement.make_routes(town, "YieldToEmergencyVehicle", 3, seed=23):
        distance = float(r.scenarios[0].parameter("distance"))
        dense = DenseRoute.from_route(town, r)
        index = trigger_route_index(dense, r.scenarios[0].trigger_point)
        assert index is not None
        trigger_wp = town.get_waypoint(r.scenarios[0].trigger_point.location)
        assert placement.move_along(trigger_wp, distance, forward=False) is not None
        assert dense.total_length - dense.cumulative_length[index] >= 200.0 + 4.0 * (distance - 30.0) - 3.0


@pytest.mark.parametrize("scenario_type", sorted(BENCH2DRIVE220_RANGES))
def test_bench2drive220_routes_keep_todays_ranges(towns, scenario_type):
    routes = placement.make_routes(towns["all"], scenario_type, N, seed=23, params="bench2drive220")
    _check(routes, BENCH2DRIVE220_RANGES[scenario_type])
    # the default set draws differently on the same seed
    default = placement.make_routes(towns["all"], scenario_type, N, seed=23)
    assert [r.scenarios[0].other_parameters for r in default] != [r.scenarios[0].other_parameters for r in routes]


def test_b2d_only_types_keep_their_ranges_in_both_sets():
    for scenario_type in ("SignalizedJunctionLeftTurnEnterFlow", "NonSignalizedJunctionLeftTurnEnterFlow"):
        assert TRAINING.ranges(scenario_type) == PARAM_SETS["bench2drive220"].ranges(scenario_type)


def test_drawing_is_deterministic_and_intervals_are_ordered():
    a = [TRAINING.draw("CrossingBicycleFlow", np.random.default_rng(s)) for s in range(200)]
    b = [TRAINING.draw("CrossingBicycleFlow", np.random.default_rng(s)) for s in range(200)]
    assert a == b
    assert all(int(p["source_dist_interval"]["from"]) <= int(p["source_dist_interval"]["to"]) for p in a)


def test_unknown_parameter_set_is_named():
    with pytest.raises(ValueError, match="unknown parameter set 'lb2'; choose one of training, bench2drive220"):
        param_set("lb2")
    with pytest.raises(ValueError, match="unknown parameter set"):
        placement.make_routes(None, "Accident", 1, params="lb2")  # type: ignore[arg-type]  # refused before the town


def test_collect_cli_params_option(tmp_path, capsys, monkeypatch):
    assert collect.PARAM_SET_NAMES == tuple(PARAM_SETS)
    parser = collect.build_parser()
    base = ["--scenario", "Accident", "--out", str(tmp_path / "o"), "--workers", "1"]
    assert collect._config(parser.parse_args(base)).params == "training"
    assert collect._config(parser.parse_args([*base, "--params", "bench2drive220"])).params == "bench2drive220"
    with pytest.raises(SystemExit) as exc:
        collect.main([*base, "--params", "lb2"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--params: invalid choice: 'lb2' (choose from 'training', 'bench2drive220')" in err
    with pytest.raises(SystemExit) as exc:
        collect.main(["--routes", "bench2drive220.xml", "--params", "training", "--out", str(tmp_path / "r")])
    assert exc.value.code == 2
    assert "--params sets the ranges of generated routes" in capsys.readouterr().err

    # the plan hands the set to the placement
    from b2d_data.collection.job import CollectConfig
    from b2d_data.collection.plan import plan_collection

    seen = []

    def fake(world_map, scenario, count, seed, weathers, params):
        seen.append(params)
        raise placement.PlacementError("stop here")

    monkeypatch.setattr(placement, "make_routes", fake)
    config = CollectConfig(out=tmp_path / "p", scenarios=("Accident",), n=1, params="bench2drive220", sensors=False)
    plan_collection(config)
    assert seen and set(seen) == {"bench2drive220"}


def test_expert_success_script_params_option(monkeypatch):
    path = Path(__file__).resolve().parents[2] / "scripts" / "expert_success.py"
    spec = importlib.util.spec_from_file_location("expert_success", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    seen = []
    monkeypatch.setattr(module, "generated_tasks", lambda *a, **k: seen.append(a[-1]) or ([], {}))
    monkeypatch.setattr(module, "run_tasks", lambda *a: [])
    module.main(["--scenario", "Accident", "--params", "bench2drive220", "--towns", "all"])
    module.main(["--scenario", "Accident", "--towns", "all"])
    assert seen == ["bench2drive220", "training"]
    with pytest.raises(SystemExit):
        module.main(["--params", "nope"])


def test_pinned_keeps_one_side_and_the_other_parameters() -> None:
    from b2d_data.scenarios.param_ranges import TRAINING

    left = TRAINING.pinned("ParkingCrossingPedestrian", "direction", "left")
    assert left.name == "training" and left.choices("ParkingCrossingPedestrian", "direction") == ("left",)
    # the other types and parameters are the set's own (36 of 126 routes draw left unpinned)
    assert left.choices("ParkingCutIn", "direction") == ("right", "left")
    assert left.int_range("ParkingCrossingPedestrian", "distance") == TRAINING.int_range(
        "ParkingCrossingPedestrian", "distance"
    )
    rng = np.random.default_rng(0)
    assert {left.draw("ParkingCrossingPedestrian", rng)["direction"]["value"] for _ in range(20)} == {"left"}
    with pytest.raises(ValueError, match="opposite"):
        TRAINING.pinned("ParkingCutIn", "direction", "opposite")
