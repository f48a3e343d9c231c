"""The implemented scenario types, one module per behaviour family; importing this package registers them."""

from b2d_data.scenarios.catalog.crossing import DynamicObjectCrossing
from b2d_data.scenarios.catalog.crossing_bicycles import CrossingBicycleFlow
from b2d_data.scenarios.catalog.enter_flow import EnterActorFlow
from b2d_data.scenarios.catalog.hard_break import HardBreakRoute
from b2d_data.scenarios.catalog.hazard_side_lane import HazardAtSideLane, HazardAtSideLaneTwoWays
from b2d_data.scenarios.catalog.highway import HighwayCutIn
from b2d_data.scenarios.catalog.interurban import InterurbanActorFlow, InterurbanAdvancedActorFlow
from b2d_data.scenarios.catalog.invading_turn import InvadingTurn
from b2d_data.scenarios.catalog.junction_turns import (
    NonSignalizedJunctionLeftTurn,
    NonSignalizedJunctionLeftTurnEnterFlow,
    NonSignalizedJunctionRightTurn,
    SignalizedJunctionLeftTurn,
    SignalizedJunctionLeftTurnEnterFlow,
    SignalizedJunctionRightTurn,
)
from b2d_data.scenarios.catalog.obstacles import (
    Accident,
    AccidentTwoWays,
    ConstructionObstacle,
    ConstructionObstacleTwoWays,
    ParkedObstacle,
    ParkedObstacleTwoWays,
)
from b2d_data.scenarios.catalog.parking_exit import ParkingExit
from b2d_data.scenarios.catalog.red_light_runner import OppositeVehicleRunningRedLight
from b2d_data.scenarios.catalog.vanilla_turns import (
    VanillaNonSignalizedTurnEncounterStopsign,
    VanillaSignalizedTurnEncounterRedLight,
)
from b2d_data.scenarios.catalog.vehicle_opens_door import VehicleOpensDoorTwoWays
from b2d_data.scenarios.catalog.yield_emergency import YieldToEmergencyVehicle

__all__ = [
    "Accident", "AccidentTwoWays", "ConstructionObstacle", "ConstructionObstacleTwoWays", "CrossingBicycleFlow",
    "DynamicObjectCrossing", "EnterActorFlow", "HardBreakRoute", "HazardAtSideLane", "HazardAtSideLaneTwoWays",
    "HighwayCutIn", "InterurbanActorFlow", "InterurbanAdvancedActorFlow", "InvadingTurn",
    "NonSignalizedJunctionLeftTurn", "NonSignalizedJunctionLeftTurnEnterFlow", "NonSignalizedJunctionRightTurn",
    "OppositeVehicleRunningRedLight", "ParkedObstacle", "ParkedObstacleTwoWays", "ParkingExit",
    "SignalizedJunctionLeftTurn", "SignalizedJunctionLeftTurnEnterFlow", "SignalizedJunctionRightTurn",
    "VanillaNonSignalizedTurnEncounterStopsign", "VanillaSignalizedTurnEncounterRedLight", "VehicleOpensDoorTwoWays",
    "YieldToEmergencyVehicle",
]  # fmt: skip
