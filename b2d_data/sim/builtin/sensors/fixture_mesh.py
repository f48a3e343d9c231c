"""Traffic lights and signs: poles, heads and plates (static) and the lit lamps of each light (per tick).

A :class:`Fixture` is built from the snapshot's :class:`TrafficLightInfo` / :class:`TrafficSignInfo`: the head or
plate fills the level bounding box the annotations report (so boxes, rendered pixels, depth and LiDAR agree) and
the pole stands on the road at ``pole_base``. Heads carry the traffic-light tag (7), plates the
traffic-sign tag (8), poles the pole tag (6); all carry the light/sign id as instance id.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from b2d_data.format.semantic import SemanticTag
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform
from b2d_data.sim.api import Snapshot, TrafficLightInfo, TrafficLightState, TrafficSignInfo
from b2d_data.sim.builtin.sensors.scene_mesh import Material, TriangleMesh, box, cylinder, merge, prism

_POLE = (95, 98, 100)
_POLE_RADIUS = 0.09  # m
_LAMP_DEPTH = 0.02  # m, the lamps' slice of a light's head box
_HEAD = (38, 40, 36)
_LAMP_OFF = (30, 30, 28)
_LAMP_ON = {
    TrafficLightState.RED: (255, 45, 30),
    TrafficLightState.YELLOW: (255, 185, 20),
    TrafficLightState.GREEN: (40, 255, 120),
}
# Lamp order from the top: red, yellow, green.
_LAMP_SLOTS = (TrafficLightState.RED, TrafficLightState.YELLOW, TrafficLightState.GREEN)


@dataclass(frozen=True)
class Fixture:
    """A light or sign to mesh, in world coordinates.

    ``kind`` is ``traffic_light``, ``stop``, ``yield``, ``speed_limit`` or ``sign``; ``base`` the pole foot;
    ``head`` the head/plate box (centre, half extents, yaw in degrees); ``facing`` the horizontal unit vector
    its lamps or face point to (towards the traffic it governs).
    """

    kind: str
    instance_id: int
    base: np.ndarray
    head_center: np.ndarray
    head_half: np.ndarray
    head_yaw: float
    facing: np.ndarray


def _box_world(box_: BoundingBox, frame: Transform, near: Location) -> tuple[np.ndarray, float]:
    """World centre and yaw of a level box given either in world coordinates or relative to ``frame``."""
    loc = box_.location
    if loc.distance(near) < 30.0:
        centre = loc.to_array()
        yaw = box_.rotation.yaw if box_.rotation != Rotation() else frame.rotation.yaw
    else:
        centre = frame.transform_point(loc).to_array()
        yaw = frame.rotation.yaw + box_.rotation.yaw
    return centre, yaw


def _facing_of(info: TrafficLightInfo | TrafficSignInfo, centre: np.ndarray, yaw_deg: float) -> np.ndarray:
    """Horizontal unit vector the lamps / plate face.

    The builtin world turns a level box's +x axis towards the approaching traffic. A box without rotation (also
    one facing yaw 0 exactly) faces along its thinner horizontal axis, on the side of the stop line (or trigger
    volume) it governs: the direction to that line itself is mostly across the road, not along the plate's normal.
    """
    a = math.radians(yaw_deg)
    x_axis = np.array([math.cos(a), math.sin(a)])
    if info.level_bbox.rotation != Rotation():
        return x_axis
    ext = info.level_bbox.extent
    normal = x_axis if ext.x <= ext.y else np.array([-x_axis[1], x_axis[0]])
    stops = getattr(info, "stop_waypoints", ())
    if stops:
        target = np.mean([w.transform.location.to_array() for w in stops], axis=0)
    else:
        target = info.transform.transform_point(info.trigger_volume.location).to_array()
    return -normal if float((target[:2] - centre[:2]) @ normal) < 0.0 else normal


def _sane(half: np.ndarray) -> bool:
    return bool(np.all(half > 0.02) and np.all(half < 3.0))


def _pole_base(info: TrafficLightInfo | TrafficSignInfo) -> np.ndarray:
    return (info.pole_base if info.pole_base is not None else info.transform.location).to_array()


def fixture_of_light(info: TrafficLightInfo) -> Fixture:
    """A traffic light's fixture; the head fills ``level_bbox`` whenever its extents are plausible."""
    base = _pole_base(info)
    centre, yaw = _box_world(info.level_bbox, info.level_bbox_transform, info.transform.location)
    half = info.level_bbox.extent.to_array()
    if not _sane(half):
        # No usable level box: a standard three-lamp head on top of a 4 m pole.
        half = np.array([0.18, 0.18, 0.5])
        centre = base + np.array([0.0, 0.0, 4.0 + half[2]])
        yaw = info.transform.rotation.yaw
    return Fixture("traffic_light", info.id, base, centre, half, yaw, _facing_of(info, centre, yaw))


def _sign_kind(type_id: str) -> str:
    t = type_id.lower()
    if "stop" in t:
        return "stop"
    if "yield" in t:
        return "yield"
    if "speed_limit" in t:
        return "speed_limit"
    return "sign"


def fixture_of_sign(info: TrafficSignInfo) -> Fixture:
    """A sign's fixture; the plate fills ``level_bbox`` whenever its extents are plausible, its pole behind it."""
    base = _pole_base(info)
    centre, yaw = _box_world(info.level_bbox, info.level_bbox_transform, info.transform.location)
    half = info.level_bbox.extent.to_array()
    if not _sane(half):
        half = np.array([0.03, 0.4, 0.4])
        centre = base + np.array([0.0, 0.0, 2.2])
        yaw = info.transform.rotation.yaw
    facing = _facing_of(info, centre, yaw)
    # The pole stands just behind the plate, so that the plate's face shows whole (traffic-sign pixels and LiDAR
    # returns over the whole box) instead of a pole across its lower half.
    behind = centre[:2] - facing * (_extent_along(half, yaw, facing) + _POLE_RADIUS)
    base = np.array([behind[0], behind[1], base[2]])
    return Fixture(_sign_kind(info.type_id), info.id, base, centre, half, yaw, facing)


def _extent_along(half: np.ndarray, yaw_deg: float, direction: np.ndarray) -> float:
    """Half length of a level box (half extents, yaw) along a horizontal unit vector."""
    r = _rot_z(yaw_deg)
    return float(abs(r[:2, 0] @ direction) * half[0] + abs(r[:2, 1] @ direction) * half[1])


def fixtures_of_snapshot(snapshot: Snapshot) -> list[Fixture]:
    """Fixtures of every traffic light and sign of a snapshot."""
    out = [fixture_of_light(t) for t in snapshot.traffic_lights.values()]
    out += [fixture_of_sign(s) for s in snapshot.traffic_signs.values()]
    return out


def fixture_key(snapshot: Snapshot) -> tuple:
    """Identity of the snapshot's fixtures (ids and poses) so that their static mesh is rebuilt only on change."""
    lights = tuple(sorted((t.id, t.transform.location.to_list().__repr__()) for t in snapshot.traffic_lights.values()))
    signs = tuple(sorted((s.id, s.transform.location.to_list().__repr__()) for s in snapshot.traffic_signs.values()))
    return lights, signs


# --------------------------------------------------------------------------------------------- meshing
def _rot_z(yaw_deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _head_box(f: Fixture, color: tuple[int, int, int], tag: int, material: int = Material.MATTE) -> TriangleMesh:
    """A light's housing: the level box less the lamps' depth on their face (the lamps fill that slice)."""
    m = np.eye(4)
    m[:3, :3] = _rot_z(f.head_yaw)
    m[:3, 3] = f.head_center
    normal_axis, sign = _lamp_layout(f)[:2]
    centre, half = np.zeros(3), np.array(f.head_half, dtype=np.float64)
    centre[normal_axis] = -sign * _LAMP_DEPTH / 2.0
    half[normal_axis] -= _LAMP_DEPTH / 2.0
    return box(centre, half, color, tag, material).transformed(m)


def _pole_and_arm(f: Fixture, top_z: float) -> list[TriangleMesh]:
    """A pole from the base up to ``top_z`` plus, when the head hangs away from it, a horizontal arm."""
    tag = int(SemanticTag.POLE)
    base = f.base.copy()
    height = max(0.5, top_z - base[2])
    parts = [cylinder(base, _POLE_RADIUS, height, _POLE, tag, sides=6)]
    reach = f.head_center[:2] - base[:2]
    dist = float(np.linalg.norm(reach))
    if dist > 0.4:
        d = reach / dist
        p0 = np.array([base[0], base[1], top_z - 0.06])
        p1 = np.array([f.head_center[0] - d[0] * 0.1, f.head_center[1] - d[1] * 0.1, top_z - 0.06])
        side = np.array([-d[1], d[0], 0.0]) * 0.05
        up = np.array([0.0, 0.0, 0.06])
        bottom = np.array([p0 - side - up, p1 - side - up, p1 + side - up, p0 + side - up])
        parts.append(prism(bottom, bottom + 2 * up, _POLE, tag, cap_top=True, cap_bottom=True))
    return parts


def _lamp_layout(f: Fixture) -> tuple[int, float, int, float, float]:
    """In the head frame: (normal axis, normal sign, lamp axis, half length along it, half width across)."""
    r = _rot_z(f.head_yaw)
    best: tuple[float, int, float] | None = None
    for axis in (0, 1):
        for sign in (1.0, -1.0):
            score = float(r[:2, axis] @ f.facing) * sign
            if best is None or score > best[0]:
                best = (score, axis, sign)
    _, normal_axis, sign = best
    other = 1 - normal_axis
    if f.head_half[2] >= f.head_half[other]:
        return normal_axis, sign, 2, float(f.head_half[2]), float(f.head_half[other])
    return normal_axis, sign, other, float(f.head_half[other]), float(f.head_half[2])


def lamp_mesh(fixtures: Iterable[Fixture], states: Mapping[int, TrafficLightState]) -> TriangleMesh:
    """The three lamps of every light: the one of its state lit (emissive), the others dark."""
    tag = int(SemanticTag.TRAFFIC_LIGHT)
    parts = []
    for f in fixtures:
        if f.kind != "traffic_light":
            continue
        state = states.get(f.instance_id, TrafficLightState.OFF)
        normal_axis, sign, lamp_axis, half_along, half_across = _lamp_layout(f)
        spacing = half_along * 2.0 / 3.0
        radius = max(0.03, min(half_across * 0.7, spacing * 0.4))
        to_world = np.eye(4)
        to_world[:3, :3] = _rot_z(f.head_yaw)
        to_world[:3, 3] = f.head_center
        for k, slot in enumerate(_LAMP_SLOTS):
            centre = np.zeros(3)
            # Flush with the level box's face: lamps and housing together are the box.
            centre[normal_axis] = sign * (f.head_half[normal_axis] - _LAMP_DEPTH / 2.0)
            # Red on top of vertical heads; first along the axis of horizontal ones.
            centre[lamp_axis] = (1 - k) * spacing * (1.0 if lamp_axis == 2 else -1.0)
            half = np.full(3, radius)
            half[normal_axis] = _LAMP_DEPTH / 2.0
            lit = state == slot
            color, material = (_LAMP_ON[slot], Material.EMISSIVE) if lit else (_LAMP_OFF, Material.MATTE)
            lamp = box(centre, half, color, tag, material)
            parts.append(lamp.transformed(to_world).with_instance(f.instance_id))
    return merge(parts)


def _plate(f: Fixture) -> TriangleMesh:
    """A sign plate: octagon (stop), triangle (yield), disc (speed limit) or rectangle, facing ``facing``.

    The outline spans the level box's face exactly (its width across ``facing`` and its height), so the box the
    annotation reports is the plate's bounding box.
    """
    tag = int(SemanticTag.TRAFFIC_SIGN)
    n = np.array([f.facing[0], f.facing[1], 0.0])
    u = np.array([-n[1], n[0], 0.0])
    half_u = _extent_along(f.head_half, f.head_yaw, u[:2])
    half_z = float(f.head_half[2])
    if f.kind == "stop":
        sides, color, start = 8, (200, 20, 25), math.pi / 8
    elif f.kind == "yield":
        sides, color, start = 3, (235, 235, 235), -math.pi / 2
    elif f.kind == "speed_limit":
        sides, color, start = 12, (240, 240, 240), 0.0
    else:
        sides, color, start = 4, (30, 80, 170), math.pi / 4
    a = start + np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    across, up = _unit_span(np.cos(a)), _unit_span(np.sin(a))
    ring = f.head_center + np.outer(across * half_u, u) + np.outer(up * half_z, [0.0, 0.0, 1.0])
    front = ring + n * 0.02
    back = ring - n * 0.02
    plate = prism(back, front, color, tag, Material.PAINT, cap_top=True, cap_bottom=True)
    parts = [plate]
    if f.kind == "speed_limit":
        ring_in = f.head_center + 0.82 * (ring - f.head_center)
        parts.append(prism(ring + n * 0.021, ring + n * 0.022, (200, 20, 25), tag, cap_top=False))
        parts.append(prism(ring_in + n * 0.022, ring_in + n * 0.023, (240, 240, 240), tag, cap_top=True))
    return merge(parts)


def _unit_span(values: np.ndarray) -> np.ndarray:
    """Polygon coordinates moved and scaled to span exactly [−1, 1] (the outline's bounding box is the box face)."""
    lo, hi = float(values.min()), float(values.max())
    return (2.0 * values - (lo + hi)) / (hi - lo)


def fixture_static_mesh(fixtures: Iterable[Fixture]) -> TriangleMesh:
    """Poles, arms, heads and plates of every fixture (instance id = fixture id)."""
    parts = []
    for f in fixtures:
        if f.kind == "traffic_light":
            top = f.head_center[2] + f.head_half[2]
            own = [_head_box(f, _HEAD, int(SemanticTag.TRAFFIC_LIGHT))] + _pole_and_arm(f, top)
        else:
            top = f.head_center[2] - 0.1
            own = [_plate(f)] + _pole_and_arm(f, top)
        parts.append(merge(own).with_instance(f.instance_id))
    return merge(parts)
