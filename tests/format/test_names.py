"""Clip names: parsing, aliases, errors, and every name of the three official split files."""

from __future__ import annotations

import json
from collections import Counter

import pytest

from b2d_data.format import ClipName, ClipNameError
from b2d_data.format.scenario_types import SCENARIO_TYPES

# format.md §9: clips per prefix in the Base and Full(+Sup) lists (Base excludes the one truncated name).
EXPECTED_COUNTS = {
    "Accident": (28, 221), "AccidentTwoWays": (35, 262), "BlockedIntersection": (23, 952),
    "ConstructionObstacle": (27, 362), "ConstructionObstacleTwoWays": (27, 171), "ControlLoss": (13, 19),
    "CrossingBicycleFlow": (26, 200), "DynamicObjectCrossing": (26, 409), "EnterActorFlow": (15, 614),
    "HardBreakRoute": (35, 537), "HazardAtSideLane": (43, 238), "HazardAtSideLaneTwoWays": (27, 515),
    "HighwayCutIn": (27, 160), "HighwayExit": (29, 108), "InterurbanActorFlow": (13, 76),
    "InterurbanAdvancedActorFlow": (15, 77), "InvadingTurn": (13, 37), "MergerIntoSlowTraffic": (8, 32),
    "MergerIntoSlowTrafficV2": (18, 92), "NonSignalizedJunctionLeftTurn": (34, 170),
    "NonSignalizedJunctionLeftTurnEnterFlow": (18, 143), "NonSignalizedJunctionRightTurn": (14, 195),
    "OppositeVehicleRunningRedLight": (21, 856), "OppositeVehicleTakingPriority": (21, 763),
    "ParkedObstacle": (28, 198), "ParkedObstacleTwoWays": (23, 118), "ParkingCrossingPedestrian": (20, 150),
    "ParkingCutIn": (38, 145), "ParkingExit": (27, 122), "PedestrianCrossing": (20, 556), "LaneChange": (15, 52),
    "SignalizedJunctionLeftTurn": (21, 148), "SignalizedJunctionLeftTurnEnterFlow": (27, 143),
    "SignalizedJunctionRightTurn": (15, 303), "StaticCutIn": (24, 493), "TJunction": (32, 164),
    "VanillaNonSignalizedTurn": (0, 123), "VanillaNonSignalizedTurnEncounterStopsign": (30, 256),
    "VanillaSignalizedTurnEncounterGreenLight": (27, 1010), "VanillaSignalizedTurnEncounterRedLight": (30, 860),
    "VehicleOpensDoorTwoWays": (3, 71), "VehicleTurningRoute": (27, 297), "VehicleTurningRoutePedestrian": (17, 394),
    "YieldToEmergencyVehicle": (19, 85), "NoScenario": (0, 741),
}  # fmt: skip


def test_parse_and_format_round_trip():
    name = ClipName.parse("Accident_Town03_Route156_Weather0")
    assert (name.scenario, name.town, name.route_id, name.weather_id) == ("Accident", "Town03", 156, 0)
    assert str(name) == "Accident_Town03_Route156_Weather0"
    assert name.archive_name == "Accident_Town03_Route156_Weather0.tar.gz"


def test_aliases_and_town10hd():
    lane = ClipName.parse("SequentialLaneChange_Town12_Route7_Weather3")
    assert lane.scenario == "LaneChange" and lane.xml_type == "SequentialLaneChange"
    tj = ClipName.parse("v1/TJunction_Town10HD_Route371_Weather7.tar.gz")
    assert tj.xml_type == "T_Junction" and tj.town == "Town10HD" and tj.route_id == 371
    assert ClipName.parse("T_Junction_Town01_Route1_Weather1").scenario == "TJunction"
    assert ClipName.parse("NoScenario_Town12_Route0_Weather26").is_known_scenario


def test_truncated_weather_is_unknown():
    name = ClipName.parse("VehicleTurningRoutePedestrian_Town15_Route523_Weathe.tar.gz")
    assert name.weather_id is None and name.route_id == 523


@pytest.mark.parametrize(
    "bad", ["Accident_Town03_Route156", "Accident_Town03_RouteX_Weather0", "Accident-Town03-Route1-Weather2",
            "Accident_Town03_Route1_Wind3", "", "Accident_City03_Route1_Weather0"],
)  # fmt: skip
def test_malformed_names_raise_naming_the_text(bad):
    with pytest.raises(ClipNameError, match="malformed clip name"):
        ClipName.parse(bad)


def _split_names(path):
    return list(json.loads(path.read_text()))


def test_every_official_name_parses_and_counts_match(b2d_data_dir):
    mini = _split_names(b2d_data_dir / "bench2drive_mini_10.json")
    base = _split_names(b2d_data_dir / "bench2drive_base_1000.json")
    full = _split_names(b2d_data_dir / "bench2drive_full+sup_13638.json")
    assert (len(mini), len(base), len(full)) == (10, 1000, 13638)
    parsed = {key: [ClipName.parse(n) for n in names] for key, names in (("mini", mini), ("base", base), ("full", full))}
    assert all(n.is_known_scenario for names in parsed.values() for n in names)
    base_counts = Counter(n.scenario for n in parsed["base"] if n.weather_id is not None)
    full_counts = Counter(n.scenario for n in parsed["full"])
    assert sum(1 for n in parsed["base"] if n.weather_id is None) == 1
    for prefix, (n_base, n_full) in EXPECTED_COUNTS.items():
        assert base_counts.get(prefix, 0) == n_base, prefix
        assert full_counts.get(prefix, 0) == n_full, prefix
    assert set(full_counts) <= set(EXPECTED_COUNTS)
    assert len(EXPECTED_COUNTS) == len(SCENARIO_TYPES) + 1
