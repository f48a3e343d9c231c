"""Traffic lights and signs of a map, as the :class:`FurnitureSpec` the world turns into actors.

Reads ``Map.signals()`` / ``Map.speed_limit_signs()`` (each signal's CARLA actor pose, its governed lanes with
CARLA's generated trigger boxes and stop waypoints) and ``Map.controllers()`` (which lights switch together
and in which order within their junction).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from b2d_data.sim import blueprints
from b2d_data.sim.builtin.traffic_lights import (
    LIGHT_HEAD_HALF,
    LIGHT_HEAD_HEIGHT,
    SIGN_PLATE_HALF,
    SIGN_PLATE_HEIGHT,
    FurnitureSpec,
    furniture_spec,
)

if TYPE_CHECKING:
    from b2d_data.maps import Map

log = logging.getLogger(__name__)

#: How far past a stop waypoint to look for the junction a light governs, when the map names none (m).
_JUNCTION_SEARCH = 30.0


def _junction_after(stop_waypoints: tuple[Any, ...]) -> int | None:
    """Id of the first junction reached driving on from the stop waypoints (None if none within 30 m)."""
    for wp in stop_waypoints:
        current, travelled = wp, 0.0
        while travelled <= _JUNCTION_SEARCH:
            if current.is_junction:
                return int(current.junction_id)
            nxt = current.next(1.0)
            if not nxt:
                break
            current, travelled = nxt[0], travelled + 1.0
    return None


@dataclass(frozen=True)
class Mounting:
    """Where a signal's head (plate) and pole go: half extents, world z of the head centre (``None``: the
    standard height above the governed lane) and of the pole foot."""

    head_half: tuple[float, float, float]
    head_z: float | None
    pole_z: float


def signal_mounting(signal: Any, default: tuple[float, float, float]) -> Mounting:
    """The head (plate) box and pole foot of a map signal, from its ``<signal>`` record.

    OpenDRIVE's zOffset is the height of the signal's bottom above the road's reference line and ``height`` its
    height; the landmark pose (``signal.transform``, as CARLA computes it) is already lifted by zOffset, so a
    signal with zOffset > 0 and a height spans [transform z, transform z + height] and its pole stands on the
    reference line. A record that does not lift its signal describes the pole foot: CARLA's exported towns give
    their lights zOffset −0.7…0 and their speed signs ±0.2 m and no height, and the generated towns give lights 0;
    those keep the standard head height above the lane (CARLA's own heads hang there, not at the foot).
    """
    width, height = float(signal.width or 0.0), float(signal.height or 0.0)
    z_offset = float(getattr(signal, "z_offset", 0.0))
    foot = signal.transform.location.z - max(z_offset, 0.0)
    half_y = 0.5 * width if width > 0.0 else default[1]
    if z_offset > 0.0 and height > 0.0:
        return Mounting((default[0], half_y, 0.5 * height), signal.transform.location.z + 0.5 * height, foot)
    if width <= 0.0 or height <= 0.0:
        return Mounting(default, None, foot)
    return Mounting((default[0], half_y, 0.5 * height), None, foot)


def furniture_from_map(town: Map) -> tuple[list[FurnitureSpec], list[FurnitureSpec]]:
    """(light specs, sign specs) for every traffic light, stop, yield and speed-limit signal of the map."""
    sequence: dict[str, tuple[int, str]] = {}
    for controller in town.controllers():
        key = (controller.sequence if controller.sequence is not None else 0, str(controller.id))
        for signal_id in controller.signal_ids:
            sequence.setdefault(str(signal_id), key)
    lights: list[FurnitureSpec] = []
    signs: list[FurnitureSpec] = []
    skipped = 0
    for index, signal in enumerate(town.signals()):
        if not (signal.is_traffic_light or signal.is_stop or signal.is_yield):
            continue
        if not signal.lanes:
            skipped += 1
            continue
        boxes = [lane.trigger_box for lane in signal.lanes]
        if signal.is_traffic_light:
            junction = signal.junction_id if signal.junction_id != -1 else _junction_after(signal.stop_waypoints)
            mount = signal_mounting(signal, LIGHT_HEAD_HALF)
            lights.append(furniture_spec(
                blueprints.TRAFFIC_LIGHT_TYPE_ID, signal.id, signal.actor_transform, boxes, signal.stop_waypoints,
                signal.affected_lane_waypoints, mount.head_half, LIGHT_HEAD_HEIGHT,
                group_key=junction if junction is not None else -1 - index,
                pole_key=sequence.get(str(signal.id), (0, f"signal:{signal.id}")),
                head_z=mount.head_z, pole_z=mount.pole_z,
            ))  # fmt: skip
        else:
            type_id = blueprints.STOP_TYPE_ID if signal.is_stop else blueprints.YIELD_TYPE_ID
            mount = signal_mounting(signal, SIGN_PLATE_HALF)
            signs.append(furniture_spec(
                type_id, signal.id, signal.actor_transform, boxes, signal.stop_waypoints,
                signal.affected_lane_waypoints, mount.head_half, SIGN_PLATE_HEIGHT, head_z=mount.head_z,
                pole_z=mount.pole_z,
            ))  # fmt: skip
    for signal in town.speed_limit_signs():
        if not signal.lanes:
            skipped += 1
            continue
        kmh = float(signal.speed_limit)
        mount = signal_mounting(signal, SIGN_PLATE_HALF)
        signs.append(furniture_spec(
            blueprints.speed_limit_type_id(kmh), signal.id, signal.actor_transform,
            [lane.trigger_box for lane in signal.lanes], signal.stop_waypoints, signal.affected_lane_waypoints,
            mount.head_half, SIGN_PLATE_HEIGHT, speed_limit=kmh, head_z=mount.head_z, pole_z=mount.pole_z,
        ))  # fmt: skip
    if skipped:
        log.info("%s: %d signals govern no lane and get no actor", town.name, skipped)
    return lights, signs
