"""The blueprint library shared by every backend: CARLA 0.9.15 type ids and what an actor of each is.

For each blueprint id this module knows the actor kind, CARLA's ``base_type`` attribute, the bounding box
(centre in the actor frame and **half** extents, as ``actor.bounding_box`` reports them in CARLA 0.9.15),
the semantic tags its mesh carries, and for vehicles the dynamics class the builtin simulator drives it with.

Sources: vehicle and walker boxes are CARLA 0.9.15 ``actor.bounding_box`` dumps; prop boxes are half of the
sizes CARLA's blueprint catalogue reports (props stand on their origin, so the centre is at ``z = extent.z``).
The ego ``vehicle.lincoln.mkz_2020`` uses the project's ego extent (:data:`b2d_data.format.rig.EGO_HALF_EXTENT`,
the value PDM-Lite and Bench2Drive use) rather than the slightly narrower dump.
"""

from __future__ import annotations

import difflib
import fnmatch
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from b2d_data.format.rig import EGO_HALF_EXTENT, EGO_TYPE_ID
from b2d_data.format.semantic import SemanticTag
from b2d_data.format.transform import BoundingBox, Location
from b2d_data.sim.api import ActorKind, ActorSpec, SpawnError

__all__ = [
    "EGO_TYPE_ID",
    "Blueprint",
    "BicycleGeometry",
    "LongitudinalLaw",
    "LongitudinalModel",
    "EGO_DYNAMICS",
    "UnknownBlueprintError",
    "BLUEPRINTS",
    "PARKED_VEHICLE_MESHES",
    "find",
    "resolve",
    "filter_ids",
    "background_car_ids",
    "random_background_car",
    "random_walker",
    "random_color",
]


@dataclass(frozen=True)
class BicycleGeometry:
    """Kinematic bicycle geometry of expert-and-scenarios.md §1.6 (PDM-Lite's fitted CARLA model).

    ``rear_length`` (l_r) is the distance from the rear axle to the reference point (the actor origin),
    ``front_length`` (l_f) the fitted front term; the wheel angle is ``steer_to_wheel × steer`` radians.
    Every vehicle uses these numbers so that the expert's forecasts of other vehicles match the simulator.
    """

    rear_length: float = 1.41783
    front_length: float = -0.09077
    steer_to_wheel: float = 0.36848

    @property
    def wheelbase(self) -> float:
        """Effective wheelbase l_f + l_r of the fitted model (m)."""
        return self.front_length + self.rear_length

    def slip_angle(self, steer: float) -> float:
        """Slip angle β (rad) at the reference point for a normalised steer in [−1, 1]."""
        wheel = self.steer_to_wheel * max(-1.0, min(1.0, steer))
        return float(np.arctan(self.rear_length / self.wheelbase * np.tan(wheel)))

    def turn_radius(self, steer: float) -> float:
        """Radius (m) of the circle the reference point drives at a constant steer (inf for 0)."""
        beta = self.slip_angle(steer)
        return float("inf") if beta == 0.0 else self.rear_length / abs(np.sin(beta))

    def steer_for_curvature(self, curvature: float) -> float:
        """Normalised steer that makes the reference point drive a path of the given curvature (1/m)."""
        sin_beta = max(-0.999, min(0.999, curvature * self.rear_length))
        beta = np.arcsin(sin_beta)
        wheel = np.arctan(np.tan(beta) * self.wheelbase / self.rear_length)
        return float(max(-1.0, min(1.0, wheel / self.steer_to_wheel)))


class LongitudinalLaw(IntEnum):
    """Which throttle/brake → acceleration law a vehicle follows (its value is a column of the simulator's rows)."""

    #: drive = throttle · (max_accel − accel_falloff·|v|), resistance = brake · max_brake + rolling + drag · v².
    LINEAR = 0
    #: PDM-Lite's fitted polynomials of CARLA's Lincoln MKZ 2020 (expert-and-scenarios.md §1.6) for forward driving,
    #: the linear law in reverse; see ``b2d_data/sim/builtin/kinematic_bicycle.py``.
    CARLA_LINCOLN = 1


@dataclass(frozen=True)
class LongitudinalModel:
    """Throttle/brake → acceleration of one vehicle class (SI units; see kinematic_bicycle.py for the laws)."""

    max_accel: float = 3.8  # m/s² at standstill, full throttle
    accel_falloff: float = 0.075  # m/s² lost per m/s of speed (engine power limit)
    max_brake: float = 8.0  # m/s² at brake = 1
    hand_brake: float = 6.0  # m/s² with the hand brake pulled
    rolling: float = 0.25  # m/s² rolling resistance + engine braking when coasting
    drag: float = 4.0e-4  # 1/m, aerodynamic term (× v²)
    max_reverse_speed: float = 8.0  # m/s
    max_steer_rate: float = 5.0  # normalised steer units per second
    law: LongitudinalLaw = LongitudinalLaw.LINEAR


CAR_DYNAMICS = LongitudinalModel()
VAN_DYNAMICS = LongitudinalModel(max_accel=3.0, accel_falloff=0.06, max_brake=7.0, hand_brake=5.5)
TRUCK_DYNAMICS = LongitudinalModel(max_accel=2.2, accel_falloff=0.045, max_brake=6.0, hand_brake=5.0, rolling=0.3)
BUS_DYNAMICS = LongitudinalModel(max_accel=1.8, accel_falloff=0.04, max_brake=5.5, hand_brake=5.0, rolling=0.3)
MOTORCYCLE_DYNAMICS = LongitudinalModel(max_accel=5.0, accel_falloff=0.1, max_brake=8.0, hand_brake=6.0)
BICYCLE_DYNAMICS = LongitudinalModel(
    max_accel=1.8, accel_falloff=0.2, max_brake=5.0, hand_brake=4.0, rolling=0.15, drag=1.0e-3, max_reverse_speed=1.5
)
#: The Lincoln MKZ 2020 (``vehicle.lincoln.mkz_2020``, the ego's car) drives forward like the CARLA Lincoln that
#: PDM-Lite's ego forecast describes (expert-and-scenarios.md §1.6, ``ExpertConfig.ego_throttle_poly`` and
#: ``ego_brake_poly``): Leaderboard 2.0 agents' controllers (UniAD, VAD, TCP PIDs and throttle caps) are tuned on that
#: car, so throttle 0.5 must give what it gives in CARLA (1.4 m/s² from rest, not the 3.6 a linear law gives).
#: LB2.0's gaps assume it too: a SignalizedJunctionLeftTurn flow at 9 m/s with 22 m headways leaves 2.0 s to cross
#: its lane from a standstill (about 10 m), 1.8 s at this car's full throttle, 2.5 s with the generic car's.
#: ``kinematic_bicycle.py`` says where the law leaves the polynomials (throttle < 0.3, partial brake, above their
#: fitted speeds). ``max_accel``/``accel_falloff`` serve the reverse gear only: the least-squares line of the
#: full-throttle polynomial plus rolling and drag over 0–15 m/s, as before the polynomial law.
#: ``rolling``/``drag`` are the generic car's coasting terms, which the law uses at throttle 0 where the polynomial
#: at throttle 0.3 does not already decelerate harder.
EGO_DYNAMICS = LongitudinalModel(max_accel=7.711, accel_falloff=0.2413, law=LongitudinalLaw.CARLA_LINCOLN)
_DYNAMICS_BY_BASE_TYPE: dict[str, LongitudinalModel] = {
    "car": CAR_DYNAMICS,
    "van": VAN_DYNAMICS,
    "truck": TRUCK_DYNAMICS,
    "bus": BUS_DYNAMICS,
    "motorcycle": MOTORCYCLE_DYNAMICS,
    "bicycle": BICYCLE_DYNAMICS,
}
#: Blueprints whose dynamics differ from their base type's.
_DYNAMICS_BY_TYPE_ID: dict[str, LongitudinalModel] = {EGO_TYPE_ID: EGO_DYNAMICS}

DEFAULT_GEOMETRY = BicycleGeometry()


@dataclass(frozen=True)
class Blueprint:
    """What an actor of one blueprint id is (CARLA 0.9.15 semantics)."""

    type_id: str
    kind: ActorKind
    extent: tuple[float, float, float]  # half extents (m)
    center: tuple[float, float, float]  # bounding-box centre in the actor frame (m)
    semantic_tags: tuple[int, ...]
    base_type: str = ""
    special_type: str = ""  # "emergency", "taxi", "electric" or ""
    generation: int = 0
    has_lights: bool = False
    has_dynamic_doors: bool = False
    collides: bool = True  # False for flat props the wheels roll over (dirt debris)
    attributes: Mapping[str, str] = field(default_factory=dict)
    dynamics: LongitudinalModel | None = None
    geometry: BicycleGeometry | None = None
    colors: tuple[str, ...] = ()  # recommended values of the ``color`` attribute ("R,G,B")

    @property
    def bounding_box(self) -> BoundingBox:
        """The CARLA ``actor.bounding_box`` (centre in the actor frame, half extents)."""
        return BoundingBox(Location(*self.center), Location(*self.extent))

    @property
    def is_vehicle(self) -> bool:
        """Driven by the kinematic bicycle model (cars, trucks, motorcycles, bicycles)."""
        return self.kind is ActorKind.VEHICLE

    @property
    def number_of_wheels(self) -> int:
        """2 for bicycles and motorcycles, 4 for other vehicles, 0 otherwise."""
        if not self.is_vehicle:
            return 0
        return 2 if self.base_type in ("bicycle", "motorcycle") else 4

    def default_attributes(self) -> dict[str, str]:
        """The attribute dict an actor of this blueprint reports when nothing was overridden."""
        out = dict(self.attributes)
        if self.is_vehicle:
            out.setdefault("base_type", self.base_type)
            out.setdefault("special_type", self.special_type)
            out.setdefault("generation", str(self.generation))
            out.setdefault("has_lights", str(self.has_lights).lower())
            out.setdefault("has_dynamic_doors", str(self.has_dynamic_doors).lower())
            out.setdefault("number_of_wheels", str(self.number_of_wheels))
            if self.colors:
                out.setdefault("color", self.colors[0])
        return out


class UnknownBlueprintError(SpawnError, KeyError):
    """A blueprint id that the library does not know."""

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0]) if self.args else ""


# -- vehicles -------------------------------------------------------------------------------------------
# (type_id, base_type, half extent, bbox centre, generation, special_type)
# base_type is CARLA 0.9.15's attribute, including its two content quirks ("" for the Mini Cooper S and the
# BMW Grand Tourer, carla-simulator/carla#9397) so that annotations match data recorded on CARLA.
_VEHICLES: tuple[tuple[str, str, tuple[float, float, float], tuple[float, float, float], int, str], ...] = (
    ("vehicle.audi.a2", "car", (1.8527, 0.8943, 0.7745), (0.0, 0.0003, 0.7818), 1, ""),
    ("vehicle.audi.etron", "car", (2.4279, 1.0164, 0.8247), (-0.0036, 0.0, 0.8205), 1, "electric"),
    ("vehicle.audi.tt", "car", (2.0906, 0.9971, 0.6926), (-0.0004, 0.0, 0.6926), 1, ""),
    ("vehicle.bmw.grandtourer", "", (2.3055, 1.1209, 0.8336), (0.0, -0.0005, 0.7651), 1, ""),
    ("vehicle.chevrolet.impala", "car", (2.6787, 1.0166, 0.7053), (0.0001, 0.0018, 0.7015), 1, ""),
    ("vehicle.citroen.c3", "car", (1.9938, 0.9254, 0.8086), (0.0, 0.0024, 0.7619), 1, ""),
    ("vehicle.dodge.charger_2020", "car", (2.5039, 0.9408, 0.7674), (-0.0053, 0.0, 0.7656), 2, ""),
    ("vehicle.dodge.charger_police", "car", (2.4871, 1.0192, 0.7711), (0.0236, 0.0006, 0.7927), 1, "emergency"),
    ("vehicle.dodge.charger_police_2020", "car", (2.6188, 0.9649, 0.8192), (0.1095, 0.0, 0.8174), 2, "emergency"),
    ("vehicle.ford.crown", "car", (2.6828, 0.9004, 0.7875), (0.1854, 0.0, 0.7684), 2, "taxi"),
    ("vehicle.ford.mustang", "car", (2.3588, 0.9474, 0.6505), (0.0321, 0.0, 0.6505), 1, ""),
    ("vehicle.jeep.wrangler_rubicon", "car", (1.9331, 0.9526, 0.9390), (0.0002, 0.0010, 0.9323), 1, ""),
    ("vehicle.lincoln.mkz_2017", "car", (2.4508, 1.0642, 0.7554), (0.0040, 0.0, 0.7189), 1, ""),
    (EGO_TYPE_ID, "car", EGO_HALF_EXTENT, (-0.0063, 0.0, EGO_HALF_EXTENT[2]), 2, ""),
    ("vehicle.mercedes.coupe", "car", (2.5134, 1.0758, 0.8253), (0.0, -0.0008, 0.6668), 1, ""),
    ("vehicle.mercedes.coupe_2020", "car", (2.3368, 0.9059, 0.7210), (-0.0026, 0.0, 0.7204), 2, ""),
    ("vehicle.micro.microlino", "car", (1.1036, 0.7405, 0.6880), (0.0, -0.0001, 0.6772), 2, "electric"),
    ("vehicle.mini.cooper_s", "", (1.9029, 0.9851, 0.7375), (0.0, -0.0001, 0.6930), 1, ""),
    ("vehicle.mini.cooper_s_2021", "car", (2.2763, 1.0485, 0.8836), (-0.0313, 0.0, 0.8910), 2, ""),
    ("vehicle.nissan.micra", "car", (1.8167, 0.9226, 0.7506), (0.0, 0.0010, 0.7812), 1, ""),
    ("vehicle.nissan.patrol", "car", (2.3023, 0.9658, 0.9274), (-0.0574, 0.0002, 0.9351), 1, ""),
    ("vehicle.nissan.patrol_2021", "car", (2.7829, 1.0750, 1.0226), (0.0284, 0.0, 1.0167), 2, ""),
    ("vehicle.seat.leon", "car", (2.0964, 0.9081, 0.7369), (-0.0002, -0.0016, 0.7396), 1, ""),
    ("vehicle.tesla.model3", "car", (2.3959, 1.0817, 0.7438), (0.0292, 0.0, 0.7359), 1, "electric"),
    ("vehicle.toyota.prius", "car", (2.2568, 1.0034, 0.7624), (0.0020, -0.0004, 0.7242), 1, "electric"),
    ("vehicle.ford.ambulance", "van", (3.1828, 1.1756, 1.2157), (-0.2886, 0.0019, 1.2156), 2, "emergency"),
    ("vehicle.mercedes.sprinter", "van", (2.9576, 0.9942, 1.2803), (-0.0105, 0.0041, 1.2882), 2, ""),
    ("vehicle.volkswagen.t2", "van", (2.2402, 1.0347, 1.0189), (0.0013, -0.0005, 1.0145), 1, ""),
    ("vehicle.volkswagen.t2_2021", "van", (2.2211, 0.8873, 0.9936), (0.1167, -0.0004, 0.9912), 2, ""),
    ("vehicle.carlamotors.carlacola", "truck", (2.6019, 1.3135, 1.2337), (0.0, 0.0, 1.2337), 1, ""),
    ("vehicle.carlamotors.european_hgv", "truck", (3.9679, 1.4455, 1.7310), (0.0127, 0.0053, 1.7306), 2, ""),
    ("vehicle.carlamotors.firetruck", "truck", (4.2340, 1.4455, 1.9137), (-0.2534, 0.0053, 1.9133), 2, "emergency"),
    ("vehicle.tesla.cybertruck", "truck", (3.1368, 1.1948, 1.0491), (0.0, 0.0, 1.0491), 1, "electric"),
    ("vehicle.mitsubishi.fusorosa", "bus", (5.1363, 1.9721, 2.1264), (-0.4452, -0.1209, 2.1274), 2, ""),
    ("vehicle.harley-davidson.low_rider", "motorcycle", (1.1751, 0.3831, 0.8247), (0.0, 0.0, 0.8246), 1, ""),
    ("vehicle.kawasaki.ninja", "motorcycle", (1.0218, 0.3985, 0.7616), (0.0, 0.0, 0.7689), 1, ""),
    ("vehicle.vespa.zx125", "motorcycle", (0.9086, 0.4330, 0.7950), (0.0100, 0.0, 0.7946), 1, ""),
    ("vehicle.yamaha.yzf", "motorcycle", (1.0954, 0.4330, 0.7652), (0.0, 0.0, 0.7746), 1, ""),
    ("vehicle.bh.crossbike", "bicycle", (0.7547, 0.4330, 0.8062), (0.0, 0.0, 0.8082), 1, ""),
    ("vehicle.diamondback.century", "bicycle", (0.8281, 0.2912, 0.8099), (0.0, 0.0, 0.8157), 1, ""),
    ("vehicle.gazelle.omafiets", "bicycle", (0.9217, 0.3295, 0.8879), (-0.0100, 0.0, 0.8946), 1, ""),
)

# CARLA tags a vehicle by its mesh folder: cars 14; trucks and vans 15; the bus 16; motorcycles 18 and
# bicycles 19, both carrying a rider (13).
_TAGS_BY_BASE_TYPE: dict[str, tuple[int, ...]] = {
    "car": (int(SemanticTag.CAR),),
    "": (int(SemanticTag.CAR),),
    "van": (int(SemanticTag.TRUCK),),
    "truck": (int(SemanticTag.TRUCK),),
    "bus": (int(SemanticTag.BUS),),
    "motorcycle": (int(SemanticTag.MOTORCYCLE), int(SemanticTag.RIDER)),
    "bicycle": (int(SemanticTag.BICYCLE), int(SemanticTag.RIDER)),
}

# A palette of paint colours ("R,G,B") offered for vehicles whose paint is selectable.
_PAINT: tuple[str, ...] = (
    "17,37,103", "220,220,220", "26,26,26", "145,12,12", "60,60,60", "183,187,162", "115,87,32",
    "201,201,201", "51,79,122", "120,0,28", "230,230,226", "89,103,78",
)  # fmt: skip
_FIXED_PAINT: dict[str, tuple[str, ...]] = {
    "vehicle.dodge.charger_police": ("0,0,0",),
    "vehicle.dodge.charger_police_2020": ("0,0,0",),
    "vehicle.ford.ambulance": ("255,255,255",),
    "vehicle.carlamotors.firetruck": ("200,16,16",),
    "vehicle.ford.crown": ("255,200,0",),
    "vehicle.mitsubishi.fusorosa": ("255,255,255",),
}


def _vehicle_blueprints() -> dict[str, Blueprint]:
    out: dict[str, Blueprint] = {}
    for type_id, base_type, extent, center, generation, special in _VEHICLES:
        dynamics_key = base_type or "car"
        has_lights = generation == 2 or special == "emergency"
        doors = generation == 2 and dynamics_key in ("car", "van") and special != "emergency"
        out[type_id] = Blueprint(
            type_id=type_id,
            kind=ActorKind.VEHICLE,
            extent=tuple(float(v) for v in extent),  # type: ignore[arg-type]
            center=center,
            semantic_tags=_TAGS_BY_BASE_TYPE[base_type],
            base_type=base_type,
            special_type=special,
            generation=generation,
            has_lights=has_lights and dynamics_key not in ("bicycle",),
            has_dynamic_doors=doors,
            dynamics=_DYNAMICS_BY_TYPE_ID.get(type_id, _DYNAMICS_BY_BASE_TYPE[dynamics_key]),
            geometry=DEFAULT_GEOMETRY,
            colors=_FIXED_PAINT.get(type_id, _PAINT if dynamics_key not in ("bicycle",) else ()),
        )
    return out


# -- walkers --------------------------------------------------------------------------------------------
# Extents are CARLA's walker capsules: adults 0.1877 × 0.1877 × 0.93, small children 0.25 × 0.25 × 0.55,
# older children 0.1877 × 0.1877 × 0.65. The walker origin is the capsule centre (bbox centre (0, 0, 0)).
_CHILDREN_SMALL = {9, 10, 11, 48, 49}
_CHILDREN_TALL = {12, 13, 14}
# Gender per model: our assignment from CARLA's pedestrian catalogue pictures (not a CARLA attribute dump).
_FEMALE = {1, 2, 5, 8, 9, 11, 13, 15, 16, 19, 21, 22, 24, 36, 38, 40, 47, 49, 50}


def _walker_blueprints() -> dict[str, Blueprint]:
    out: dict[str, Blueprint] = {}
    for number in range(1, 52):
        type_id = f"walker.pedestrian.{number:04d}"
        if number in _CHILDREN_SMALL:
            extent, age = (0.25, 0.25, 0.55), "child"
        elif number in _CHILDREN_TALL:
            extent, age = (0.1877, 0.1877, 0.65), "child"
        else:
            extent, age = (0.1877, 0.1877, 0.93), "adult"
        out[type_id] = Blueprint(
            type_id=type_id,
            kind=ActorKind.WALKER,
            extent=extent,
            center=(0.0, 0.0, 0.0),
            semantic_tags=(int(SemanticTag.PEDESTRIAN),),
            attributes={
                "gender": "female" if number in _FEMALE else "male",
                "age": age,
                "speed": "1.1,2.0" if age == "child" else "1.4,2.5",  # walking, running (m/s)
                "is_invincible": "false",
            },
        )
    return out


# -- props ----------------------------------------------------------------------------------------------
# (type_id, half extent, collides). Props stand on their origin (bbox centre z = extent z).
_PROPS: tuple[tuple[str, tuple[float, float, float], bool], ...] = (
    ("static.prop.trafficcone01", (0.4414, 0.4411, 0.5666), True),
    ("static.prop.trafficcone02", (0.2278, 0.1973, 0.5914), True),
    ("static.prop.constructioncone", (0.1720, 0.1720, 0.2929), True),
    ("static.prop.warningconstruction", (0.6525, 0.5275, 0.9301), True),
    ("static.prop.warningaccident", (0.6525, 0.5275, 0.9301), True),
    ("static.prop.trafficwarning", (1.1867, 1.4353, 1.7848), True),
    ("static.prop.dirtdebris01", (0.9287, 0.7570, 0.0745), False),
    ("static.prop.dirtdebris02", (0.9287, 0.7570, 0.0745), False),
    ("static.prop.dirtdebris03", (0.9287, 0.7570, 0.0942), False),
    ("static.prop.advertisement", (0.7746, 0.1434, 1.2214), True),
    ("static.prop.container", (0.9659, 0.5062, 0.8571), True),
    ("static.prop.clothcontainer", (0.6197, 0.9433, 0.9051), True),
    ("static.prop.glasscontainer", (0.9774, 1.0044, 0.8942), True),
    ("static.prop.streetbarrier", (0.6075, 0.1858, 0.5346), True),
    ("static.prop.chainbarrier", (0.7471, 0.1193, 0.4444), True),
    ("static.prop.chainbarrierend", (0.1193, 0.1193, 0.4444), True),
    ("static.prop.vendingmachine", (0.4364, 0.5510, 1.0541), True),
    ("static.prop.barrel", (0.2298, 0.2357, 0.4034), True),
    ("static.prop.box01", (0.3261, 0.3261, 0.3458), True),
    ("static.prop.box02", (0.3243, 0.3243, 0.3243), True),
    ("static.prop.box03", (0.3304, 0.3350, 0.3243), True),
    ("static.prop.busstop", (1.9380, 0.9468, 1.3695), True),
    ("static.prop.mailbox", (0.2633, 0.2192, 0.5786), True),
    ("static.prop.trashcan01", (0.3176, 0.2839, 0.4241), True),
    ("static.prop.bench01", (0.7720, 0.3679, 0.4849), True),
    ("static.prop.kiosk_01", (0.8126, 0.8270, 1.6227), True),
    ("static.prop.ironplank", (0.7259, 0.5872, 0.0103), False),
    ("static.prop.streetsign", (0.5322, 0.0626, 1.0772), True),
    ("static.prop.streetsign01", (1.2352, 0.1515, 1.9390), True),
    ("static.prop.streetsign04", (0.5854, 0.0624, 1.3864), True),
    ("static.prop.haybale", (0.6239, 0.5967, 0.5975), True),
    ("static.prop.plantpot01", (0.5446, 0.2379, 0.2787), True),
    ("static.prop.gnome", (0.1833, 0.1878, 0.4415), True),
)

#: Parked-vehicle meshes for ``static.prop.mesh`` (``mesh_path`` attribute) with their half extents at the
#: route runner's scale 0.9 (the LB2.0 parked cars); other scales rescale these.
_PARKED = "/Game/Carla/Static/Car/4Wheeled/ParkedVehicles/"
PARKED_VEHICLE_MESHES: dict[str, tuple[float, float, float]] = {
    _PARKED + "MercedesCCC/SM_MercedesCCC_Parked.SM_MercedesCCC_Parked": (2.103, 0.8155, 0.649),
    _PARKED + "FordCrown/SM_FordCrown_parked.SM_FordCrown_parked": (2.4145, 0.8105, 0.7085),
    _PARKED + "Lincoln/SM_LincolnParked.SM_LincolnParked": (2.2015, 0.8265, 0.6705),
    _PARKED + "Mini2021/SM_Mini2021_parked.SM_Mini2021_parked": (2.0485, 0.9435, 0.795),
    _PARKED + "VolkswagenT2/SM_VolkswagenT2_2021_Parked.SM_VolkswagenT2_2021_Parked": (2.016, 0.931, 0.917),
    _PARKED + "NissanPatrol2021/SM_NissanPatrol2021_parked.SM_NissanPatrol2021_parked": (2.5045, 0.9675, 0.9205),
    _PARKED + "Charger/SM_ChargerParked.SM_ChargerParked": (2.2535, 0.8465, 0.6905),
    _PARKED + "TeslaM3/SM_TeslaM3_parked.SM_TeslaM3_parked": (2.1565, 0.9735, 0.6695),
}  # fmt: skip
PARKED_MESH_SCALE = 0.9
MESH_TYPE_ID = "static.prop.mesh"


def _prop_blueprints() -> dict[str, Blueprint]:
    out: dict[str, Blueprint] = {}
    for type_id, extent, collides in _PROPS:
        out[type_id] = Blueprint(
            type_id=type_id,
            kind=ActorKind.PROP,
            extent=extent,
            center=(0.0, 0.0, extent[2]),
            semantic_tags=(int(SemanticTag.STATIC),),
            collides=collides,
            attributes={"size": "medium"},
        )
    first_mesh = next(iter(PARKED_VEHICLE_MESHES.values()))
    out[MESH_TYPE_ID] = Blueprint(
        type_id=MESH_TYPE_ID,
        kind=ActorKind.PROP,
        extent=first_mesh,
        center=(0.0, 0.0, first_mesh[2]),
        semantic_tags=(int(SemanticTag.CAR),),
        base_type="car",
        attributes={"mesh_path": next(iter(PARKED_VEHICLE_MESHES)), "scale": str(PARKED_MESH_SCALE)},
    )
    return out


# -- traffic furniture ----------------------------------------------------------------------------------
SPEED_LIMIT_VALUES = (30, 40, 50, 60, 70, 80, 90, 100, 110, 120, 130)
# Light actors: a pole-mounted head; signs: a plate on a pole. The pole itself is the actor's collision box.
TRAFFIC_LIGHT_TYPE_ID = "traffic.traffic_light"
STOP_TYPE_ID = "traffic.stop"
YIELD_TYPE_ID = "traffic.yield"
POLE_HALF_EXTENT = (0.15, 0.15, 1.5)


def speed_limit_type_id(kmh: float) -> str:
    """``traffic.speed_limit.<v>`` for a limit in km/h (rounded to the nearest catalogue value)."""
    nearest = min(SPEED_LIMIT_VALUES, key=lambda v: abs(v - kmh))
    return f"traffic.speed_limit.{nearest}"


def _traffic_blueprints() -> dict[str, Blueprint]:
    pole = dict(extent=POLE_HALF_EXTENT, center=(0.0, 0.0, POLE_HALF_EXTENT[2]))
    out: dict[str, Blueprint] = {
        TRAFFIC_LIGHT_TYPE_ID: Blueprint(
            type_id=TRAFFIC_LIGHT_TYPE_ID, kind=ActorKind.TRAFFIC_LIGHT,
            semantic_tags=(int(SemanticTag.TRAFFIC_LIGHT),), **pole,  # type: ignore[arg-type]
        ),
        STOP_TYPE_ID: Blueprint(
            type_id=STOP_TYPE_ID, kind=ActorKind.TRAFFIC_SIGN,
            semantic_tags=(int(SemanticTag.TRAFFIC_SIGN),), **pole,  # type: ignore[arg-type]
        ),
        YIELD_TYPE_ID: Blueprint(
            type_id=YIELD_TYPE_ID, kind=ActorKind.TRAFFIC_SIGN,
            semantic_tags=(int(SemanticTag.TRAFFIC_SIGN),), **pole,  # type: ignore[arg-type]
        ),
    }  # fmt: skip
    for value in SPEED_LIMIT_VALUES:
        type_id = f"traffic.speed_limit.{value}"
        out[type_id] = Blueprint(
            type_id=type_id, kind=ActorKind.TRAFFIC_SIGN, semantic_tags=(int(SemanticTag.TRAFFIC_SIGN),),
            **pole,  # type: ignore[arg-type]
        )
    return out


#: Every blueprint id the library knows, in a stable order.
BLUEPRINTS: dict[str, Blueprint] = {
    **_vehicle_blueprints(),
    **_walker_blueprints(),
    **_prop_blueprints(),
    **_traffic_blueprints(),
}


def find(type_id: str) -> Blueprint:
    """The blueprint of an id; unknown ids raise :class:`UnknownBlueprintError` listing close matches."""
    try:
        return BLUEPRINTS[type_id]
    except KeyError:
        close = difflib.get_close_matches(type_id, BLUEPRINTS.keys(), n=5, cutoff=0.5)
        hint = f"; close matches: {', '.join(close)}" if close else ""
        raise UnknownBlueprintError(f"unknown blueprint id {type_id!r}{hint}") from None


def resolve(spec: ActorSpec) -> Blueprint:
    """The blueprint an :class:`ActorSpec` spawns, with attribute-dependent boxes (``static.prop.mesh``)."""
    blueprint = find(spec.type_id)
    if spec.type_id != MESH_TYPE_ID:
        return blueprint
    mesh_path = spec.attributes.get("mesh_path", blueprint.attributes["mesh_path"])
    if mesh_path not in PARKED_VEHICLE_MESHES:
        close = difflib.get_close_matches(mesh_path, PARKED_VEHICLE_MESHES.keys(), n=3, cutoff=0.3)
        hint = f"; close matches: {', '.join(close)}" if close else ""
        raise UnknownBlueprintError(f"unknown mesh_path {mesh_path!r} for {MESH_TYPE_ID}{hint}")
    try:
        scale = float(spec.attributes.get("scale", PARKED_MESH_SCALE))
    except ValueError:
        raise SpawnError(f"{MESH_TYPE_ID}: scale must be a number, got {spec.attributes['scale']!r}") from None
    factor = scale / PARKED_MESH_SCALE
    extent = tuple(round(v * factor, 6) for v in PARKED_VEHICLE_MESHES[mesh_path])
    return Blueprint(
        type_id=MESH_TYPE_ID,
        kind=ActorKind.PROP,
        extent=extent,  # type: ignore[arg-type]
        center=(0.0, 0.0, extent[2]),
        semantic_tags=blueprint.semantic_tags,
        base_type=blueprint.base_type,
        attributes={"mesh_path": mesh_path, "scale": str(scale)},
    )


def filter_ids(pattern: str = "*", **attributes: str | bool) -> list[str]:
    """Blueprint ids matching a wildcard pattern and attribute values (CARLA's ``filter`` + ``has_attribute``)."""
    out = []
    for type_id, blueprint in BLUEPRINTS.items():
        if not fnmatch.fnmatchcase(type_id, pattern):
            continue
        attrs = blueprint.default_attributes()
        if all(attrs.get(k) == (str(v).lower() if isinstance(v, bool) else v) for k, v in attributes.items()):
            out.append(type_id)
    return out


def background_car_ids() -> list[str]:
    """The cars LB2.0 background traffic draws from: base_type car, lights, no special type."""
    return filter_ids("vehicle.*", base_type="car", has_lights=True, special_type="")


def random_color(blueprint: Blueprint, rng: np.random.Generator) -> str | None:
    """A seeded pick among the blueprint's recommended colours (None when it has none)."""
    if not blueprint.colors:
        return None
    return blueprint.colors[int(rng.integers(len(blueprint.colors)))]


def random_background_car(rng: np.random.Generator, role_name: str = "background",
                          choices: Iterable[str] | None = None) -> ActorSpec:
    """A seeded background car spec (blueprint and colour drawn from ``rng``)."""
    ids = list(choices) if choices is not None else background_car_ids()
    type_id = ids[int(rng.integers(len(ids)))]
    blueprint = BLUEPRINTS[type_id]
    attributes = {}
    color = random_color(blueprint, rng)
    if color is not None:
        attributes["color"] = color
    return ActorSpec(type_id=type_id, role_name=role_name, attributes=attributes)


def random_walker(rng: np.random.Generator, role_name: str = "walker", adults_only: bool = False) -> ActorSpec:
    """A seeded pedestrian spec."""
    ids = [t for t in filter_ids("walker.pedestrian.*") if not adults_only or BLUEPRINTS[t].attributes["age"] == "adult"]
    return ActorSpec(type_id=ids[int(rng.integers(len(ids)))], role_name=role_name)
