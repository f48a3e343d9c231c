"""The implemented scenario types, one module per behaviour family; importing this package registers them.

Each family also registers its types' placement layouts (:mod:`.layout`), in its module or, where that would grow
too long, in a sibling ``<family>_placement`` module imported here.
"""

from b2d_data.scenarios.catalog.blocked_intersection import BlockedIntersection
from b2d_data.scenarios.catalog.control_loss import ControlLoss
from b2d_data.scenarios.catalog.crossing import DynamicObjectCrossing
from b2d_data.scenarios.catalog.crossing_bicycles import CrossingBicycleFlow
from b2d_data.scenarios.catalog.cut_ins import ParkingCutIn, StaticCutIn
from b2d_data.scenarios.catalog.enter_flow import EnterActorFlow
from b2d_data.scenarios.catalog.enter_flow_v2 import EnterActorFlowV2
from b2d_data.scenarios.catalog.hard_break import HardBreakRoute
from b2d_data.scenarios.catalog.hazard_side_lane import HazardAtSideLane, HazardAtSideLaneTwoWays
from b2d_data.scenarios.catalog.highway import HighwayCutIn
from b2d_data.scenarios.catalog.highway_exit import HighwayExit
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
from b2d_data.scenarios.catalog.lane_change import SequentialLaneChange
from b2d_data.scenarios.catalog.obstacles import (
    Accident,
    AccidentTwoWays,
    ConstructionObstacle,
    ConstructionObstacleTwoWays,
    ParkedObstacle,
    ParkedObstacleTwoWays,
)
from b2d_data.scenarios.catalog.parking_crossing import ParkingCrossingPedestrian
from b2d_data.scenarios.catalog.parking_exit import ParkingExit
from b2d_data.scenarios.catalog.pedestrian_crossing import PedestrianCrossing
from b2d_data.scenarios.catalog.priority_at_junction import PriorityAtJunction
from b2d_data.scenarios.catalog.red_light_runner import OppositeVehicleRunningRedLight
from b2d_data.scenarios.catalog.t_junction import TJunction
from b2d_data.scenarios.catalog.taking_priority import OppositeVehicleTakingPriority
from b2d_data.scenarios.catalog.turning_route import VehicleTurningRoute, VehicleTurningRoutePedestrian
from b2d_data.scenarios.catalog.vanilla_turns import (
    VanillaNonSignalizedTurn,
    VanillaNonSignalizedTurnEncounterStopsign,
    VanillaSignalizedTurnEncounterGreenLight,
    VanillaSignalizedTurnEncounterRedLight,
)
from b2d_data.scenarios.catalog.vehicle_opens_door import VehicleOpensDoorTwoWays
from b2d_data.scenarios.catalog.yield_emergency import YieldToEmergencyVehicle

# layouts registered outside the family modules
from b2d_data.scenarios.catalog import highway_placement, no_scenario, obstacles_placement  # noqa: F401

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
# Issue 14: emergency brakes, cut-ins, pedestrians, the remaining sign scenarios.
__all__ += [
    "BlockedIntersection", "ControlLoss", "OppositeVehicleTakingPriority", "ParkingCrossingPedestrian",
    "ParkingCutIn", "PedestrianCrossing", "StaticCutIn", "TJunction", "VanillaNonSignalizedTurn",
    "VanillaSignalizedTurnEncounterGreenLight", "VehicleTurningRoute", "VehicleTurningRoutePedestrian",
]  # fmt: skip
# Issue 13: highway lane changes.
__all__ += [
    "SequentialLaneChange",
]  # fmt: skip

# Issue 13: the highway exit across a flow.
__all__ += ["HighwayExit"]

# Issue 23: the two LB2.0 training types Bench2Drive drops (format.scenario_types.LB2_ONLY_TYPES).
__all__ += ["EnterActorFlowV2", "PriorityAtJunction"]
