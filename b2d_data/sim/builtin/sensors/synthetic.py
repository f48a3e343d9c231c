"""Small hand-made scenes for tests, benchmarks and previews: a crossroads layout, flat ground and actor states.

:func:`crossroads_layout` is a four-arm junction of two-way roads with sidewalks, lane lines and crosswalks, in
CARLA's frame (right-hand traffic: eastbound lanes lie at +y, south of the centre line). :func:`actor_state`
builds an :class:`ActorState` from the blueprint library, standing on the ground at a given place;
:func:`box_prop` a prop whose mesh is exactly its bounding box; :func:`snapshot_of` wraps actors in a snapshot.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorKind, ActorState, Snapshot, TrafficLightInfo, TrafficSignInfo
from b2d_data.sim.builtin.sensors.map_mesh import (
    WHITE_PAINT,
    YELLOW_PAINT,
    LaneStrip,
    PaintLine,
    RoadLayout,
    StaticScene,
    ground_plane,
)


def _straight(x0: float, x1: float, y: float, step: float = 2.0) -> np.ndarray:
    n = max(2, int(math.ceil(abs(x1 - x0) / step)) + 1)
    xs = np.linspace(x0, x1, n)
    return np.column_stack([xs, np.full(n, y), np.zeros(n)])


def _rotate(points: np.ndarray, quarter_turns: int) -> np.ndarray:
    a = quarter_turns * math.pi / 2
    c, s = round(math.cos(a)), round(math.sin(a))
    out = points.copy()
    out[:, 0] = c * points[:, 0] - s * points[:, 1]
    out[:, 1] = s * points[:, 0] + c * points[:, 1]
    return out


def crossroads_layout(
    arm_length: float = 120.0, lanes_per_direction: int = 2, lane_width: float = 3.5, sidewalk_width: float = 3.0
) -> RoadLayout:
    """Two two-way roads crossing at the origin, with sidewalks, lines and a crosswalk on every arm."""
    n, w, sw = lanes_per_direction, lane_width, sidewalk_width
    half_road = n * w
    j = half_road + sw  # junction half size
    lanes: list[LaneStrip] = []
    lines: list[PaintLine] = []
    crosswalks: list[np.ndarray] = []
    for turn in range(4):
        for side in (1, -1):
            for k in range(1, n + 1):
                inner = _straight(j, arm_length, side * (k - 1) * w)
                outer = _straight(j, arm_length, side * k * w)
                lanes.append(LaneStrip(_rotate(inner, turn), _rotate(outer, turn), "road"))
                if k < n:
                    lines.append(PaintLine(_rotate(outer, turn), "broken", WHITE_PAINT))
            inner = _straight(j, arm_length, side * half_road)
            outer = _straight(j, arm_length, side * (half_road + sw))
            lanes.append(LaneStrip(_rotate(inner, turn), _rotate(outer, turn), "sidewalk", outermost=True))
        lines.append(PaintLine(_rotate(_straight(j + 6.0, arm_length, 0.0), turn), "solidsolid", YELLOW_PAINT))
        cw = np.array([[j + 1.0, -half_road, 0.0], [j + 4.0, -half_road, 0.0], [j + 4.0, half_road, 0.0],
                       [j + 1.0, half_road, 0.0]])  # fmt: skip
        crosswalks.append(_rotate(cw, turn))
    junction_l = _straight(-j, j, -j)
    junction_r = _straight(-j, j, j)
    lanes.append(LaneStrip(junction_l, junction_r, "road", junction_id=0))
    return RoadLayout(lanes, lines, crosswalks)


def flat_scene(half_size: float = 200.0, cell: float = 10.0) -> StaticScene:
    """A static scene that is only flat terrain at z = 0 (tag 10)."""
    lo, hi = np.array([-half_size, -half_size, 0.0]), np.array([half_size, half_size, 0.0])
    return StaticScene(ground_plane(half_size, cell), np.zeros((0, 3)), lo, hi)


def box_prop(
    actor_id: int,
    x: float,
    y: float,
    half: tuple[float, float, float],
    yaw: float = 0.0,
    tag: int = 20,
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ground_z: float = 0.0,
) -> ActorState:
    """A prop standing on the ground whose mesh is exactly its bounding box (half extents ``half``)."""
    return ActorState(
        id=actor_id,
        type_id="static.prop.box01",
        kind=ActorKind.PROP,
        transform=Transform(Location(x, y, ground_z), Rotation(yaw=yaw)),
        velocity=Vector3D(*velocity),
        angular_velocity=Vector3D(),
        acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0.0, 0.0, half[2]), Location(*half)),
        semantic_tags=(tag,),
    )


def actor_state(
    actor_id: int,
    type_id: str,
    x: float,
    y: float,
    yaw: float = 0.0,
    ground_z: float = 0.0,
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0),
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0),
    acceleration: tuple[float, float, float] = (0.0, 0.0, 0.0),
    role_name: str = "",
    attributes: Mapping[str, str] | None = None,
    **changes: object,
) -> ActorState:
    """An actor of a blueprint standing on the ground at (x, y) with a yaw in degrees (CARLA frame)."""
    bp = blueprints.find(type_id)
    attrs = bp.default_attributes()
    attrs.update(attributes or {})
    # Walkers have their origin at the capsule centre; everything else stands on its origin.
    z = ground_z + (bp.extent[2] if bp.kind is ActorKind.WALKER else 0.0)
    return ActorState(
        id=actor_id,
        type_id=type_id,
        kind=bp.kind,
        transform=Transform(Location(x, y, z), Rotation(yaw=yaw)),
        velocity=Vector3D(*velocity),
        angular_velocity=Vector3D(*angular_velocity),
        acceleration=Vector3D(*acceleration),
        bounding_box=bp.bounding_box,
        semantic_tags=bp.semantic_tags,
        role_name=role_name,
        base_type=bp.base_type,
        attributes=attrs,
        **changes,  # type: ignore[arg-type]
    )


def snapshot_of(
    actors: list[ActorState],
    weather: WeatherParameters = WeatherParameters(cloudiness=10.0, sun_altitude_angle=60.0),
    frame: int = 0,
    timestamp: float = 0.0,
    traffic_lights: Mapping[int, TrafficLightInfo] | None = None,
    traffic_signs: Mapping[int, TrafficSignInfo] | None = None,
) -> Snapshot:
    """A snapshot holding ``actors`` (and optionally lights and signs)."""
    return Snapshot(
        frame=frame,
        timestamp=timestamp,
        actors={a.id: a for a in actors},
        traffic_lights=dict(traffic_lights or {}),
        traffic_signs=dict(traffic_signs or {}),
        collisions=(),
        weather=weather,
    )
