"""The 44 Bench2Drive scenario types, their clip-name prefixes and skill groups (format.md §9, §8.5)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Ability(str, Enum):
    """Bench2Drive skill groups, spelled as tools/ability_benchmark.py reports them."""

    OVERTAKING = "Overtaking"
    MERGING = "Merging"
    EMERGENCY_BRAKE = "Emergency_Brake"
    GIVE_WAY = "Give_Way"
    TRAFFIC_SIGNS = "Traffic_Signs"


@dataclass(frozen=True)
class ScenarioType:
    """One scenario type: XML/class name, dataset clip prefix and skill groups."""

    xml_type: str
    clip_prefix: str
    abilities: tuple[Ability, ...]


_OT, _MG, _EB, _GW, _TS = (
    Ability.OVERTAKING,
    Ability.MERGING,
    Ability.EMERGENCY_BRAKE,
    Ability.GIVE_WAY,
    Ability.TRAFFIC_SIGNS,
)

SCENARIO_TYPES: tuple[ScenarioType, ...] = (
    ScenarioType("Accident", "Accident", (_OT,)),
    ScenarioType("AccidentTwoWays", "AccidentTwoWays", (_OT,)),
    ScenarioType("BlockedIntersection", "BlockedIntersection", (_EB, _TS)),
    ScenarioType("ConstructionObstacle", "ConstructionObstacle", (_OT,)),
    ScenarioType("ConstructionObstacleTwoWays", "ConstructionObstacleTwoWays", (_OT,)),
    ScenarioType("ControlLoss", "ControlLoss", (_EB,)),
    ScenarioType("CrossingBicycleFlow", "CrossingBicycleFlow", (_MG, _TS)),
    ScenarioType("DynamicObjectCrossing", "DynamicObjectCrossing", (_EB,)),
    ScenarioType("EnterActorFlow", "EnterActorFlow", (_MG, _TS)),
    ScenarioType("HardBreakRoute", "HardBreakRoute", (_EB,)),
    ScenarioType("HazardAtSideLane", "HazardAtSideLane", (_OT,)),
    ScenarioType("HazardAtSideLaneTwoWays", "HazardAtSideLaneTwoWays", (_OT,)),
    ScenarioType("HighwayCutIn", "HighwayCutIn", (_MG,)),
    ScenarioType("HighwayExit", "HighwayExit", (_MG,)),
    ScenarioType("InterurbanActorFlow", "InterurbanActorFlow", (_MG,)),
    ScenarioType("InterurbanAdvancedActorFlow", "InterurbanAdvancedActorFlow", (_MG,)),
    ScenarioType("InvadingTurn", "InvadingTurn", (_GW,)),
    ScenarioType("MergerIntoSlowTraffic", "MergerIntoSlowTraffic", (_MG,)),
    ScenarioType("MergerIntoSlowTrafficV2", "MergerIntoSlowTrafficV2", (_MG,)),
    ScenarioType("NonSignalizedJunctionLeftTurn", "NonSignalizedJunctionLeftTurn", (_MG, _TS)),
    ScenarioType("NonSignalizedJunctionLeftTurnEnterFlow", "NonSignalizedJunctionLeftTurnEnterFlow", (_MG, _TS)),
    ScenarioType("NonSignalizedJunctionRightTurn", "NonSignalizedJunctionRightTurn", (_MG, _TS)),
    ScenarioType("OppositeVehicleRunningRedLight", "OppositeVehicleRunningRedLight", (_EB, _TS)),
    ScenarioType("OppositeVehicleTakingPriority", "OppositeVehicleTakingPriority", (_EB, _TS)),
    ScenarioType("ParkedObstacle", "ParkedObstacle", (_OT,)),
    ScenarioType("ParkedObstacleTwoWays", "ParkedObstacleTwoWays", (_OT,)),
    ScenarioType("ParkingCrossingPedestrian", "ParkingCrossingPedestrian", (_EB,)),
    ScenarioType("ParkingCutIn", "ParkingCutIn", (_EB,)),
    ScenarioType("ParkingExit", "ParkingExit", (_MG,)),
    ScenarioType("PedestrianCrossing", "PedestrianCrossing", (_EB, _TS)),
    ScenarioType("SequentialLaneChange", "LaneChange", (_MG,)),
    ScenarioType("SignalizedJunctionLeftTurn", "SignalizedJunctionLeftTurn", (_MG, _TS)),
    ScenarioType("SignalizedJunctionLeftTurnEnterFlow", "SignalizedJunctionLeftTurnEnterFlow", (_MG, _TS)),
    ScenarioType("SignalizedJunctionRightTurn", "SignalizedJunctionRightTurn", (_MG, _TS)),
    ScenarioType("StaticCutIn", "StaticCutIn", (_EB,)),
    ScenarioType("T_Junction", "TJunction", (_TS,)),
    ScenarioType("VanillaNonSignalizedTurn", "VanillaNonSignalizedTurn", (_TS,)),
    ScenarioType("VanillaNonSignalizedTurnEncounterStopsign", "VanillaNonSignalizedTurnEncounterStopsign", (_TS,)),
    ScenarioType("VanillaSignalizedTurnEncounterGreenLight", "VanillaSignalizedTurnEncounterGreenLight", (_TS,)),
    ScenarioType("VanillaSignalizedTurnEncounterRedLight", "VanillaSignalizedTurnEncounterRedLight", (_TS,)),
    ScenarioType("VehicleOpensDoorTwoWays", "VehicleOpensDoorTwoWays", (_OT,)),
    ScenarioType("VehicleTurningRoute", "VehicleTurningRoute", (_EB, _TS)),
    ScenarioType("VehicleTurningRoutePedestrian", "VehicleTurningRoutePedestrian", (_EB, _TS)),
    ScenarioType("YieldToEmergencyVehicle", "YieldToEmergencyVehicle", (_GW,)),
)

#: Clip prefix of clips that hold no scenario (Full set only).
NO_SCENARIO = "NoScenario"

BY_XML_TYPE: dict[str, ScenarioType] = {s.xml_type: s for s in SCENARIO_TYPES}
BY_CLIP_PREFIX: dict[str, ScenarioType] = {s.clip_prefix: s for s in SCENARIO_TYPES}


def scenario_type(name: str) -> ScenarioType:
    """Look a scenario up by XML type or clip prefix; raise ``KeyError`` naming close matches."""
    if name in BY_XML_TYPE:
        return BY_XML_TYPE[name]
    if name in BY_CLIP_PREFIX:
        return BY_CLIP_PREFIX[name]
    import difflib

    close = difflib.get_close_matches(name, list(BY_XML_TYPE) + list(BY_CLIP_PREFIX), n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise KeyError(f"unknown scenario type {name!r}{hint} (44 types are known, see b2d_data.format.SCENARIO_TYPES)")


def abilities_of(xml_type: str) -> tuple[Ability, ...]:
    """Skill groups of an XML scenario type (empty for unknown types)."""
    entry = BY_XML_TYPE.get(xml_type)
    return entry.abilities if entry else ()
