"""Per-tick meshes of the actors of a :class:`~b2d_data.sim.api.Snapshot`.

Each actor becomes a low-poly shape fitted to its bounding box (cars: body + glass cabin + wheels + lights;
trucks, vans and buses taller; two-wheelers with a rider; walkers with swinging limbs; props as cones, boards or
boxes), tagged with its CARLA semantic tag and carrying its actor id as instance id. Shapes are built in the
actor frame, cached, and moved to the world with the actor transform every tick.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from b2d_data.format.semantic import SemanticTag
from b2d_data.sim.api import ActorKind, ActorState, VehicleControl, VehicleDoor
from b2d_data.sim.builtin.sensors.scene_mesh import (
    Material,
    TriangleMesh,
    box,
    cylinder,
    ellipsoid,
    horizontal_cylinder,
    merge,
    prism,
)
from b2d_data.sim.light_state import VEHICLE_LIGHT_BITS, light_bits, sirens_on

#: Realistic car paints, picked by actor id when the blueprint gives no colour.
CAR_PAINTS: tuple[tuple[int, int, int], ...] = (
    (200, 200, 205), (30, 30, 35), (120, 122, 128), (160, 20, 25), (20, 45, 110), (235, 235, 230),
    (70, 80, 60), (180, 150, 90), (40, 90, 140), (90, 20, 30), (210, 120, 20), (60, 60, 70),
)  # fmt: skip
_CLOTHES: tuple[tuple[int, int, int], ...] = (
    (40, 50, 90), (150, 30, 40), (60, 60, 60), (200, 190, 170), (30, 90, 60), (120, 80, 50), (220, 220, 220),
)
_SKIN: tuple[tuple[int, int, int], ...] = ((230, 190, 160), (190, 140, 100), (120, 80, 55), (245, 210, 185))
_TYRE = (25, 25, 25)
_GLASS = (40, 55, 70)
_HEADLIGHT_ON = (255, 250, 225)
_HEADLIGHT_OFF = (200, 200, 195)
_TAIL_ON = (255, 30, 20)
_TAIL_OFF = (120, 20, 20)
_BRAKE_ON = (255, 40, 30)


@dataclass(frozen=True)
class _Box:
    """An actor's bounding box in its own frame: centre and half extents."""

    cx: float
    cy: float
    cz: float
    ex: float
    ey: float
    ez: float

    @property
    def z0(self) -> float:
        return self.cz - self.ez

    @property
    def height(self) -> float:
        return 2.0 * self.ez


def is_vehicle_shaped(actor: ActorState) -> bool:
    """Vehicles, and parked-vehicle props (``static.prop.mesh`` with a car base type)."""
    if actor.kind is ActorKind.VEHICLE:
        return True
    base = (actor.base_type or actor.attributes.get("base_type", "")).lower()
    if actor.kind is not ActorKind.PROP:
        return False
    return actor.type_id == "static.prop.mesh" or base in ("car", "van", "truck", "bus")


def vehicle_class(actor: ActorState) -> str:
    """``car``, ``van``, ``truck``, ``bus``, ``motorcycle`` or ``bicycle`` from base_type, type id and size."""
    base = (actor.base_type or actor.attributes.get("base_type", "")).lower()
    tid = actor.type_id.lower()
    if base in {"car", "van", "truck", "bus", "motorcycle", "bicycle"}:
        return base
    for key, cls in (
        ("bus", "bus"), ("fusorosa", "bus"), ("truck", "truck"), ("firetruck", "truck"), ("carlacola", "truck"),
        ("cybertruck", "car"), ("sprinter", "van"), ("van", "van"), ("ambulance", "van"), ("t2", "van"),
        ("crossbike", "bicycle"), ("century", "bicycle"), ("omafiets", "bicycle"), ("bike", "bicycle"),
        ("harley", "motorcycle"), ("ninja", "motorcycle"), ("vespa", "motorcycle"), ("yamaha", "motorcycle"),
        ("kawasaki", "motorcycle"),
    ):  # fmt: skip
        if key in tid:
            return cls
    e = actor.bounding_box.extent
    if e.x > 4.0:
        return "bus" if e.z > 1.3 else "truck"
    if e.z > 1.05:
        return "van"
    if e.y < 0.6:
        return "bicycle"
    return "car"


_CLASS_TAG = {
    "car": SemanticTag.CAR,
    "van": SemanticTag.CAR,
    "truck": SemanticTag.TRUCK,
    "bus": SemanticTag.BUS,
    "motorcycle": SemanticTag.MOTORCYCLE,
    "bicycle": SemanticTag.BICYCLE,
}


def actor_tag(actor: ActorState) -> int:
    """The actor's main CARLA semantic tag (its own ``semantic_tags`` first, else from its class)."""
    if actor.semantic_tags:
        return int(actor.semantic_tags[0])
    if actor.kind is ActorKind.VEHICLE:
        return int(_CLASS_TAG[vehicle_class(actor)])
    if actor.kind is ActorKind.WALKER:
        return int(SemanticTag.PEDESTRIAN)
    if actor.kind is ActorKind.TRAFFIC_LIGHT:
        return int(SemanticTag.TRAFFIC_LIGHT)
    if actor.kind is ActorKind.TRAFFIC_SIGN:
        return int(SemanticTag.TRAFFIC_SIGN)
    return int(SemanticTag.STATIC)


def paint_of(actor: ActorState) -> tuple[int, int, int]:
    """The blueprint ``color`` attribute ("r,g,b") or a paint chosen by actor id."""
    text = actor.attributes.get("color", "")
    parts = [p.strip() for p in text.split(",")]
    if len(parts) == 3 and all(p.lstrip("-").isdigit() for p in parts):
        r, g, b = (max(0, min(255, int(p))) for p in parts)
        return (r, g, b)
    return CAR_PAINTS[(actor.id * 7919) % len(CAR_PAINTS)]


@dataclass(frozen=True)
class LightFlags:
    """Which vehicle lamps glow: head/position lights, brake lights, the siren bar (phase 0/1).

    ``beam``: the low beam lights the scene (``vehicle_lights``); position lights only glow.
    """

    head: bool = False
    brake: bool = False
    siren: int = -1
    beam: bool = False


def light_flags(actor: ActorState, night: bool, timestamp: float) -> LightFlags:
    """Lamp state from the light-state flags, the brake and the time of day."""
    bits = light_bits(actor.light_state)
    beam = night or bool(bits & (VEHICLE_LIGHT_BITS["LowBeam"] | VEHICLE_LIGHT_BITS["HighBeam"]))
    head = beam or bool(bits & VEHICLE_LIGHT_BITS["Position"])
    brake = bool(bits & VEHICLE_LIGHT_BITS["Brake"])
    control = actor.control
    if isinstance(control, VehicleControl) and control.brake > 0.1:
        brake = True
    # LB2.0 sets Special1 | Special2 on emergency vehicles; either bit lights the siren bar.
    siren = int(timestamp * 4.0) % 2 if sirens_on(bits) else -1
    return LightFlags(head, brake, siren, beam)


# --------------------------------------------------------------------------------------------- vehicles
def _car_body(b: _Box, paint: tuple[int, int, int], tag: int, kind: str, roof_drop: float = 0.0) -> list[TriangleMesh]:
    """Lower body (hood sloping down at the front), glass cabin and roof (``roof_drop`` below the box top)."""
    h = b.height
    r = _wheel_radius(b, kind)
    zc = b.z0 + 0.45 * r
    if kind == "van":
        zb = b.z0 + 0.48 * h
        cab_rear, cab_front, roof_rear, roof_front = -0.97, 0.55, -0.97, 0.30
    else:
        zb = b.z0 + 0.56 * h
        cab_rear, cab_front, roof_rear, roof_front = -0.62, 0.38, -0.42, 0.05
    ex, ey = b.ex - 0.01, b.ey
    profile = np.array(
        [
            (-ex, zc), (-ex, zb - 0.06 * h), (-ex + 0.12 * ex, zb), (ex - 0.3 * ex, zb),
            (ex, zb - 0.12 * h), (ex, zc),
        ]
    )  # fmt: skip
    left = np.column_stack([profile[:, 0] + b.cx, np.full(len(profile), b.cy - ey), profile[:, 1]])
    right = left.copy()
    right[:, 1] = b.cy + ey
    body = prism(left, right, paint, tag, Material.PAINT, cap_top=True, cap_bottom=True)
    top = b.z0 + h - roof_drop
    wb = ey * 0.93
    wr = ey * 0.80
    belt = np.array(
        [
            (b.cx + cab_rear * ex, b.cy - wb, zb), (b.cx + cab_front * ex, b.cy - wb, zb),
            (b.cx + cab_front * ex, b.cy + wb, zb), (b.cx + cab_rear * ex, b.cy + wb, zb),
        ]
    )  # fmt: skip
    roof = np.array(
        [
            (b.cx + roof_rear * ex, b.cy - wr, top), (b.cx + roof_front * ex, b.cy - wr, top),
            (b.cx + roof_front * ex, b.cy + wr, top), (b.cx + roof_rear * ex, b.cy + wr, top),
        ]
    )  # fmt: skip
    cabin = prism(belt, roof, _GLASS, tag, Material.GLASS, cap_top=False)
    roof_mesh = TriangleMesh.from_triangles(
        np.array([[roof[0], roof[1], roof[2]], [roof[0], roof[2], roof[3]]]), paint, tag, 0, Material.PAINT
    )
    return [body, cabin, roof_mesh]


def _slab(
    b: _Box, x0: float, x1: float, half_y: float, z0: float, z1: float, color, tag: int, material: int
) -> TriangleMesh:
    """An axis-aligned box over [x0, x1] × [cy ± half_y] × [z0, z1] in the actor frame."""
    return box(((x0 + x1) / 2, b.cy, (z0 + z1) / 2), ((x1 - x0) / 2, half_y, (z1 - z0) / 2), color, tag, material)


def _truck_body(b: _Box, paint: tuple[int, int, int], tag: int) -> list[TriangleMesh]:
    """A cab at the front and a cargo box behind it."""
    h = b.height
    zc = b.z0 + 0.5 * _wheel_radius(b, "truck")
    cab_len = min(2.4, 0.35 * 2 * b.ex)
    xf = b.cx + b.ex - 0.01  # 1 cm short of the lamps, see _lamps
    xr = b.cx - b.ex + 0.01
    cab0 = xf - cab_len
    wind_z0, wind_z1 = b.z0 + 0.55 * h, b.z0 + 0.8 * h
    cargo_col = tuple(int(0.5 * c + 0.5 * 225) for c in paint)
    return [
        _slab(b, cab0, xf, b.ey, zc, wind_z0, paint, tag, Material.PAINT),
        _slab(b, cab0 + 0.02, xf - 0.02, b.ey * 0.97, wind_z0, wind_z1, _GLASS, tag, Material.GLASS),
        _slab(b, cab0, xf, b.ey, wind_z1, b.z0 + 0.85 * h, paint, tag, Material.PAINT),
        _slab(b, xr, cab0 - 0.15, b.ey, zc, b.z0 + h, cargo_col, tag, Material.PAINT),
    ]


def _bus_body(b: _Box, paint: tuple[int, int, int], tag: int) -> list[TriangleMesh]:
    """A long box with a band of windows."""
    h = b.height
    zc = b.z0 + 0.5 * _wheel_radius(b, "bus")
    z_win0, z_win1 = b.z0 + 0.42 * h, b.z0 + 0.85 * h
    x0, x1 = b.cx - b.ex + 0.01, b.cx + b.ex - 0.01
    return [
        _slab(b, x0, x1, b.ey, zc, z_win0, paint, tag, Material.PAINT),
        _slab(b, x0 + 0.02, x1 - 0.02, b.ey - 0.02, z_win0, z_win1, _GLASS, tag, Material.GLASS),
        _slab(b, x0, x1, b.ey, z_win1, b.z0 + h, paint, tag, Material.PAINT),
    ]


def _wheel_radius(b: _Box, kind: str) -> float:
    if kind in ("truck", "bus"):
        return min(0.55, 0.2 * b.height)
    return max(0.22, min(0.38, 0.22 * b.height))


def _wheels(b: _Box, kind: str, tag: int) -> list[TriangleMesh]:
    r = _wheel_radius(b, kind)
    half_w = 0.11 if kind in ("car", "van") else 0.16
    xs = (b.cx + 0.62 * b.ex, b.cx - 0.62 * b.ex)
    if kind in ("truck", "bus"):
        xs = (b.cx + b.ex - 1.3, b.cx - 0.55 * b.ex)
    out = []
    for x in xs:
        for side in (-1.0, 1.0):
            y = b.cy + side * (b.ey - half_w - 0.02)
            out.append(horizontal_cylinder((x, y, b.z0 + r), r, half_w, _TYRE, tag, sides=8))
    return out


def _lamps(b: _Box, tag: int, flags: LightFlags, kind: str) -> list[TriangleMesh]:
    """Head lamps on the front face, tail lamps on the rear face (tiny boxes, emissive when on)."""
    h = b.height
    z = b.z0 + (0.42 if kind in ("car", "van") else 0.25) * h
    # Lamps are flush with the box ends; the bodies stop 1 cm short of them so their faces do not z-fight.
    lamp_half = (0.015, min(0.16, 0.15 * b.ey), 0.05)
    out = []
    head_col, head_mat = (_HEADLIGHT_ON, Material.EMISSIVE) if flags.head else (_HEADLIGHT_OFF, Material.PAINT)
    if flags.brake:
        tail_col, tail_mat = _BRAKE_ON, Material.EMISSIVE
    elif flags.head:
        tail_col, tail_mat = _TAIL_ON, Material.EMISSIVE
    else:
        tail_col, tail_mat = _TAIL_OFF, Material.PAINT
    for side in (-1.0, 1.0):
        y = b.cy + side * 0.72 * b.ey
        out.append(box((b.cx + b.ex - 0.015, y, z), lamp_half, head_col, tag, head_mat))
        out.append(box((b.cx - b.ex + 0.015, y, z + 0.05), lamp_half, tail_col, tag, tail_mat))
    if flags.siren >= 0:
        top = b.z0 + h
        for k, side in enumerate((-1.0, 1.0)):
            col = (40, 60, 255) if (k + flags.siren) % 2 else (255, 30, 30)
            centre = (b.cx - 0.15 * b.ex, b.cy + side * 0.3 * b.ey, top - 0.06)
            out.append(box(centre, (0.12, 0.25 * b.ey, 0.06), col, tag, Material.EMISSIVE))
    return out


def _doors(
    b: _Box, doors: Iterable[VehicleDoor], paint: tuple[int, int, int], tag: int, kind: str
) -> list[TriangleMesh]:
    """Open doors: panels hinged at their front edge, swung 60° outwards."""
    wanted: set[int] = set()
    for d in doors:
        if d == VehicleDoor.ALL:
            wanted.update({0, 1, 2, 3})
        else:
            wanted.add(int(d))
    if not wanted:
        return []
    h = b.height
    z0 = b.z0 + 0.2 * h
    z1 = b.z0 + (0.8 if kind == "car" else 0.7) * h
    out = []
    for door in sorted(wanted):
        front = door in (0, 1)
        side = -1.0 if door in (0, 2) else 1.0  # CARLA y points right: left doors are at −y
        hinge_x = b.cx + (0.3 if front else -0.12) * b.ex
        length = 0.42 * b.ex if front else 0.36 * b.ex
        ang = math.radians(60.0)
        hinge = np.array([hinge_x, b.cy + side * b.ey, 0.0])
        tip = hinge + np.array([-length * math.cos(ang), side * length * math.sin(ang), 0.0])
        normal = np.array([math.sin(ang), side * math.cos(ang), 0.0]) * 0.03
        lo_a, lo_b = hinge + [0, 0, z0], tip + [0, 0, z0]
        hi_a, hi_b = hinge + [0, 0, z1], tip + [0, 0, z1]
        bottom = np.array([lo_a - normal, lo_b - normal, lo_b + normal, lo_a + normal])
        top = np.array([hi_a - normal, hi_b - normal, hi_b + normal, hi_a + normal])
        out.append(prism(bottom, top, paint, tag, Material.PAINT, cap_top=True, cap_bottom=True))
    return out


def _two_wheeler(b: _Box, paint: tuple[int, int, int], tag: int, kind: str, rider_id: int) -> list[TriangleMesh]:
    """Two thin wheels, a frame and a seated rider (tagged rider)."""
    h = b.height
    r = min(0.34, 0.22 * h) if kind == "bicycle" else min(0.32, 0.2 * h)
    out = []
    for x in (b.cx + b.ex - r, b.cx - b.ex + r):
        half_width = 0.04 if kind == "bicycle" else 0.07
        out.append(horizontal_cylinder((x, b.cy, b.z0 + r), r, half_width, _TYRE, tag, sides=10))
    frame_h = 0.12 if kind == "bicycle" else 0.35
    frame_half = (b.ex - r, 0.05 if kind == "bicycle" else 0.16, frame_h / 2)
    out.append(box((b.cx, b.cy, b.z0 + r + frame_h / 2 + 0.05), frame_half, paint, tag, Material.PAINT))
    out.extend(_rider(b, r, rider_id))
    return out


def _rider(b: _Box, wheel_r: float, seed: int) -> list[TriangleMesh]:
    tag = int(SemanticTag.RIDER)
    cloth = _CLOTHES[seed % len(_CLOTHES)]
    skin = _SKIN[seed % len(_SKIN)]
    top = b.z0 + b.height
    seat_z = b.z0 + wheel_r * 2.0 + 0.05
    torso_top = top - 0.3
    parts = [
        box((b.cx - 0.1, b.cy, (seat_z + torso_top) / 2), (0.14, 0.18, (torso_top - seat_z) / 2), cloth, tag),
        ellipsoid((b.cx - 0.05, b.cy, top - 0.14), (0.11, 0.1, 0.13), skin, tag),
        box((b.cx + 0.1, b.cy - 0.12, seat_z - 0.25), (0.06, 0.06, 0.28), (40, 40, 50), tag),
        box((b.cx + 0.1, b.cy + 0.12, seat_z - 0.25), (0.06, 0.06, 0.28), (40, 40, 50), tag),
        box((b.cx + 0.25, b.cy - 0.2, torso_top - 0.2), (0.22, 0.04, 0.04), cloth, tag),
        box((b.cx + 0.25, b.cy + 0.2, torso_top - 0.2), (0.22, 0.04, 0.04), cloth, tag),
    ]
    return parts


def _rot_y_about(pivot: np.ndarray, angle: float) -> np.ndarray:
    """Rotation about the local y axis (a swing in the x-z plane) around ``pivot``."""
    c, s = math.cos(angle), math.sin(angle)
    r = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = pivot - r @ pivot
    return m


# --------------------------------------------------------------------------------------------- walkers
def _walker(b: _Box, seed: int, phase: float) -> list[TriangleMesh]:
    """A pedestrian: legs and arms swinging with ``phase`` (radians), torso, head."""
    tag = int(SemanticTag.PEDESTRIAN)
    h = b.height
    cloth = _CLOTHES[seed % len(_CLOTHES)]
    pants = _CLOTHES[(seed // 7 + 3) % len(_CLOTHES)]
    skin = _SKIN[(seed // 3) % len(_SKIN)]
    z0 = b.z0
    hip = z0 + 0.47 * h
    shoulder = z0 + 0.8 * h
    head_r = 0.065 * h
    half_w = min(b.ey, 0.22)
    leg_half = (0.07, 0.075, (hip - z0) / 2)
    swing = 0.45 * math.sin(phase)
    parts: list[TriangleMesh] = []
    for side, sgn in ((-1.0, 1.0), (1.0, -1.0)):
        y = b.cy + side * 0.45 * half_w
        leg = box((b.cx, y, (z0 + hip) / 2), leg_half, pants, tag)
        parts.append(leg.transformed(_rot_y_about(np.array([b.cx, y, hip]), sgn * swing)))
        arm_y = b.cy + side * (half_w * 0.95)
        arm = box((b.cx, arm_y, shoulder - 0.17 * h), (0.05, 0.05, 0.17 * h), cloth, tag)
        parts.append(arm.transformed(_rot_y_about(np.array([b.cx, arm_y, shoulder]), -sgn * swing * 0.8)))
    torso_half = (0.11, half_w * 0.75, (shoulder - hip) / 2 + 0.02)
    parts.append(box((b.cx, b.cy, (hip + shoulder) / 2 + 0.02), torso_half, cloth, tag))
    head_radii = (head_r * 0.9, head_r * 0.85, head_r)
    parts.append(ellipsoid((b.cx, b.cy, shoulder + head_r + 0.02 * h), head_radii, skin, tag))
    return parts


# --------------------------------------------------------------------------------------------- props
def _prop(actor: ActorState, b: _Box, tag: int) -> list[TriangleMesh]:
    tid = actor.type_id.lower()
    if "cone" in tid:
        h = b.height
        r = min(b.ex, b.ey)
        base = box((b.cx, b.cy, b.z0 + 0.015), (r, r, 0.015), (30, 30, 30), tag)
        orange, white = (250, 100, 10), (245, 245, 245)
        cone = cylinder((b.cx, b.cy, b.z0 + 0.03), r * 0.75, h - 0.03, orange, tag, sides=10, top_radius=r * 0.12)
        band = cylinder(
            (b.cx, b.cy, b.z0 + 0.5 * h), r * 0.455, 0.12 * h, white, tag, sides=10, top_radius=r * 0.345, cap_top=False
        )
        return [base, cone, band]
    if "warning" in tid or "construction" in tid or "sign" in tid:
        h = b.height
        board_z0 = b.z0 + 0.35 * h
        top = b.z0 + h
        board = box(
            (b.cx, b.cy, (board_z0 + top) / 2), (min(b.ex, 0.05), b.ey, (top - board_z0) / 2), (250, 190, 20), tag,
            Material.PAINT,
        )  # fmt: skip
        leg_half = (0.03, 0.03, (board_z0 - b.z0) / 2)
        legs = [
            box((b.cx, b.cy + s * 0.8 * b.ey, (b.z0 + board_z0) / 2), leg_half, (70, 70, 70), tag) for s in (-1, 1)
        ]
        return [board, *legs]
    if "debris" in tid:
        return [box((b.cx, b.cy, b.z0 + 0.04), (b.ex, b.ey, 0.04), (95, 80, 65), tag)]
    return [box((b.cx, b.cy, b.cz), (b.ex, b.ey, b.ez), (140, 120, 100), tag, Material.PAINT)]


# --------------------------------------------------------------------------------------------- assembly
def _local_box(actor: ActorState) -> _Box:
    bb = actor.bounding_box
    e = bb.extent
    return _Box(bb.location.x, bb.location.y, bb.location.z, max(e.x, 0.05), max(e.y, 0.05), max(e.z, 0.05))


@dataclass
class _Placed:
    """An actor's world mesh of the last tick, with the shape and the transform matrix (bytes) it came from."""

    shape: TriangleMesh
    matrix: bytes
    world: TriangleMesh


class ActorMeshBuilder:
    """Builds the dynamic mesh of a snapshot, caching each vehicle/prop shape in its actor frame."""

    def __init__(self) -> None:
        self._cache: dict[tuple, TriangleMesh] = {}
        # By actor id. An actor that keeps its shape and its pose (parked, queued, waiting at a light) keeps its
        # world mesh: moving the shape again would give the same arrays.
        self._placed: dict[int, _Placed] = {}

    def local_mesh(self, actor: ActorState, night: bool, timestamp: float) -> TriangleMesh:
        """The actor's shape in its own frame (instance id already set)."""
        return self._shape(actor, night, timestamp).with_instance(actor.id)

    def _shape(self, actor: ActorState, night: bool, timestamp: float) -> TriangleMesh:
        """The actor's shape in its own frame, instance ids unset (vehicles and props: the cached mesh itself)."""
        b = _local_box(actor)
        tag = actor_tag(actor)
        if actor.kind is ActorKind.WALKER:
            # Walk cycle: ~1.8 rad per metre walked, from the speed and the game time.
            phase = timestamp * actor.speed() * 1.8 + (actor.id % 17)
            return merge(_walker(b, actor.id, phase))
        if is_vehicle_shaped(actor):
            kind = vehicle_class(actor)
            flags = light_flags(actor, night, timestamp) if actor.kind is ActorKind.VEHICLE else LightFlags()
            key = ("v", kind, b, paint_of(actor), tag, flags, tuple(sorted(int(d) for d in actor.open_doors)))
        else:
            key = ("p", actor.type_id, b, tag)
        mesh = self._cache.get(key)
        if mesh is None:
            if key[0] == "v":
                mesh = merge(self._vehicle_parts(actor, b, tag, kind, flags))
            else:
                mesh = merge(_prop(actor, b, tag))
            if len(self._cache) > 4096:
                self._cache.clear()
            self._cache[key] = mesh
        return mesh

    def _vehicle_parts(self, actor: ActorState, b: _Box, tag: int, kind: str, flags: LightFlags) -> list[TriangleMesh]:
        paint = paint_of(actor)
        if kind in ("bicycle", "motorcycle"):
            return _two_wheeler(b, paint, tag, kind, actor.id)
        if kind == "truck":
            parts = _truck_body(b, paint, tag)
        elif kind == "bus":
            parts = _bus_body(b, paint, tag)
        else:
            # A siren bar sits on the roof inside the box: the roof comes down to make room for it.
            parts = _car_body(b, paint, tag, kind, roof_drop=0.12 if flags.siren >= 0 else 0.0)
        parts += _wheels(b, kind, tag)
        parts += _lamps(b, tag, flags, kind)
        parts += _doors(b, actor.open_doors, paint, tag, kind)
        return parts

    def build_parts(
        self,
        actors: Mapping[int, ActorState] | Iterable[ActorState],
        night: bool,
        timestamp: float,
    ) -> list[tuple[int, TriangleMesh]]:
        """(actor id, world-frame mesh) of every vehicle, walker and prop.

        Traffic lights and signs are fixtures (see ``fixture_mesh``), not meshed here.
        """
        items = actors.values() if isinstance(actors, Mapping) else actors
        out = []
        placed: dict[int, _Placed] = {}
        for actor in items:
            if actor.kind in (ActorKind.TRAFFIC_LIGHT, ActorKind.TRAFFIC_SIGN):
                continue
            shape = self._shape(actor, night, timestamp)
            matrix = actor.transform.matrix()
            key = matrix.tobytes()
            last = self._placed.get(actor.id)
            if last is not None and last.shape is shape and last.matrix == key:
                world = last.world
            else:
                world = shape.with_instance(actor.id).transformed(matrix)
            placed[actor.id] = _Placed(shape, key, world)
            out.append((actor.id, world))
        self._placed = placed
        return out
