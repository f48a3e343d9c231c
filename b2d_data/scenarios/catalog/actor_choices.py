"""Which CARLA blueprints the scenarios draw their actors from (seeded picks from the shared blueprint library)."""

from __future__ import annotations

import numpy as np

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.sim import blueprints

#: The police car of the Accident scenario.
POLICE_CAR = "vehicle.dodge.charger_police_2020"
#: The adversary of the red-light runner scenario.
#: Warning sign near an accident or a parked obstacle.
WARNING_ACCIDENT = "static.prop.warningaccident"
#: Construction site props (LB2.0 ConstructionObstacle): the sign at the road's edge, the board on the lane,
#: the debris behind it and the cones.
WARNING_CONSTRUCTION = "static.prop.warningconstruction"
TRAFFIC_WARNING = "static.prop.trafficwarning"
DEBRIS = "static.prop.dirtdebris02"
CONSTRUCTION_CONE = "static.prop.constructioncone"
#: Light state names (CARLA's VehicleLightState flags, ``sim/light_state.py``) LB2.0 sets: emergency vehicles
#: (YieldToEmergencyVehicle, OppositeVehicleRunningRedLight/TakingPriority) ``Special1 | Special2``; Accident's
#: police car adds ``Position`` (route_obstacles.py ``Accident._lights``); ParkedObstacle's car its hazard
#: blinkers and ``Position`` (``ParkedObstacle._lights``).
SIREN_LIGHTS = "Special1|Special2"
POLICE_ACCIDENT_LIGHTS = "Special1|Special2|Position"
HAZARD_LIGHTS = "RightBlinker|LeftBlinker|Position"
#: DynamicObjectCrossing blocker props (XML ``blocker_model``) that bench2drive220-range routes draw from.
BLOCKER_MODELS = ("static.prop.advertisement", "static.prop.container")
#: DynamicObjectCrossing's ``blocker_model`` in LB2.0's routes_training.xml with how often each occurs (351
#: scenarios). The blueprint library lacks three, drawn as their nearest: ``static.prop.foodcart`` (57) as the
#: street-food kiosk, ``static.prop.busstoplb`` (57) and ``static.prop.haybalelb`` (33), the large-map variants, as
#: the bus stop and the hay bale.
TRAINING_BLOCKER_MODELS: tuple[tuple[str, int], ...] = (
    ("static.prop.advertisement", 84),
    ("static.prop.container", 99),
    ("static.prop.kiosk_01", 57),
    ("static.prop.busstop", 57),
    ("static.prop.haybale", 33),
    ("vehicle.mini.cooper_s", 6),
    ("vehicle.nissan.patrol_2021", 6),
    ("vehicle.tesla.model3", 6),
    ("vehicle.audi.tt", 3),
)
#: DynamicObjectCrossing's blocker when the XML gives none: LB2.0's default (object_crash_vehicle.py).
DEFAULT_BLOCKER_MODEL = "static.prop.vendingmachine"


def _pick(ids: list[str], rng: np.random.Generator) -> str:
    if not ids:
        raise RuntimeError("the blueprint library has no blueprint of the requested kind")
    return ids[int(rng.integers(len(ids)))]


def parked_car_ids() -> list[str]:
    """Ordinary generation-2 cars (no police, taxi or ego model), as LB2.0's obstacle filter picks."""
    return [
        t
        for t in blueprints.filter_ids("vehicle.*", base_type="car", generation="2", special_type="")
        if t != EGO_TYPE_ID
    ]


def random_parked_car(rng: np.random.Generator) -> str:
    """A seeded pick among :func:`parked_car_ids`."""
    return _pick(parked_car_ids(), rng)


def random_car_with_doors(rng: np.random.Generator) -> str:
    """A seeded pick among the parked cars whose doors open (VehicleOpensDoorTwoWays)."""
    return _pick([t for t in parked_car_ids() if blueprints.find(t).has_dynamic_doors], rng)


def random_bicycle(rng: np.random.Generator) -> str:
    """A seeded bicycle blueprint."""
    return _pick(blueprints.filter_ids("vehicle.*", base_type="bicycle"), rng)


def emergency_vehicle_ids() -> list[str]:
    """Vehicles with ``special_type`` emergency (police cars, ambulance, fire truck)."""
    return blueprints.filter_ids("vehicle.*", special_type="emergency")


def random_emergency_vehicle(rng: np.random.Generator) -> str:
    """A seeded emergency vehicle."""
    return _pick(emergency_vehicle_ids(), rng)


def random_walker(rng: np.random.Generator) -> str:
    """A seeded adult pedestrian blueprint."""
    return blueprints.random_walker(rng, adults_only=True).type_id


def half_extent(type_id: str) -> tuple[float, float, float]:
    """The blueprint's bounding-box half extents (m)."""
    return blueprints.find(type_id).extent
