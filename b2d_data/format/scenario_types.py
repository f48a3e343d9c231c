"""The 44 Bench2Drive scenario types, their clip-name prefixes and skill groups (format.md §9, §8.5), and the two
Leaderboard 2.0 training types Bench2Drive drops.

``SCENARIO_TYPES`` is Bench2Drive's list and stays exactly that (44 entries: splits, ability scores, synthetic
corpora). ``LB2_ONLY_TYPES`` is the one place that names the types of LB2.0's ``routes_training.xml`` that Bench2Drive
has no route of (expert-and-scenarios.md §2.1: it drops ``EnterActorFlowV2`` and ``PriorityAtJunction``). They count
in no Bench2Drive ability (its ``ability_benchmark.py`` maps only its own 44), and their clip prefix is the class name
as for every Bench2Drive type whose name holds no underscore. ``BY_XML_TYPE`` / ``BY_CLIP_PREFIX`` know all 46, so
that route files, clip names and ``b2d-collect --scenario`` accept them.
"""

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

#: LB2.0 training types absent from Bench2Drive: generatable, in no ability, clip prefix = XML type.
LB2_ONLY_TYPES: tuple[ScenarioType, ...] = (
    ScenarioType("EnterActorFlowV2", "EnterActorFlowV2", ()),
    ScenarioType("PriorityAtJunction", "PriorityAtJunction", ()),
)
#: Every type this package knows: Bench2Drive's 44, then the LB2.0-only ones.
ALL_SCENARIO_TYPES: tuple[ScenarioType, ...] = SCENARIO_TYPES + LB2_ONLY_TYPES

#: Clip prefix of clips that hold no scenario (Full set only).
NO_SCENARIO = "NoScenario"

BY_XML_TYPE: dict[str, ScenarioType] = {s.xml_type: s for s in ALL_SCENARIO_TYPES}
BY_CLIP_PREFIX: dict[str, ScenarioType] = {s.clip_prefix: s for s in ALL_SCENARIO_TYPES}


def scenario_type(name: str) -> ScenarioType:
    """Look a scenario up by XML type or clip prefix; raise ``KeyError`` naming close matches."""
    if name in BY_XML_TYPE:
        return BY_XML_TYPE[name]
    if name in BY_CLIP_PREFIX:
        return BY_CLIP_PREFIX[name]
    import difflib

    close = difflib.get_close_matches(name, list(BY_XML_TYPE) + list(BY_CLIP_PREFIX), n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise KeyError(
        f"unknown scenario type {name!r}{hint} ({len(ALL_SCENARIO_TYPES)} types are known: Bench2Drive's "
        f"{len(SCENARIO_TYPES)} in b2d_data.format.SCENARIO_TYPES and LB2.0's LB2_ONLY_TYPES)"
    )


def abilities_of(xml_type: str) -> tuple[Ability, ...]:
    """Skill groups of an XML scenario type (empty for unknown and LB2.0-only types)."""
    entry = BY_XML_TYPE.get(xml_type)
    return entry.abilities if entry else ()
