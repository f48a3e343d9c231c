"""Traffic lights and signs of a map, as the :class:`FurnitureSpec` the world turns into actors.

Reads ``Map.signals()`` / ``Map.speed_limit_signs()`` (each signal's CARLA actor pose, its governed lanes with
CARLA's generated trigger boxes and stop waypoints) and ``Map.controllers()`` (which lights switch together
and in which order within their junction).
"""

from __future__ import annotations

import logging
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


def _half_extents(signal: Any, default: tuple[float, float, float]) -> tuple[float, float, float]:
    width, height = float(signal.width or 0.0), float(signal.height or 0.0)
    if width <= 0.0 or height <= 0.0:
        return default
    return (default[0], 0.5 * width, 0.5 * height)


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
            lights.append(furniture_spec(
                blueprints.TRAFFIC_LIGHT_TYPE_ID, signal.id, signal.actor_transform, boxes, signal.stop_waypoints,
                signal.affected_lane_waypoints, _half_extents(signal, LIGHT_HEAD_HALF), LIGHT_HEAD_HEIGHT,
                group_key=junction if junction is not None else -1 - index,
                pole_key=sequence.get(str(signal.id), (0, f"signal:{signal.id}")),
            ))  # fmt: skip
        else:
            type_id = blueprints.STOP_TYPE_ID if signal.is_stop else blueprints.YIELD_TYPE_ID
            signs.append(furniture_spec(
                type_id, signal.id, signal.actor_transform, boxes, signal.stop_waypoints,
                signal.affected_lane_waypoints, _half_extents(signal, SIGN_PLATE_HALF), SIGN_PLATE_HEIGHT,
            ))  # fmt: skip
    for signal in town.speed_limit_signs():
        if not signal.lanes:
            skipped += 1
            continue
        kmh = float(signal.speed_limit)
        signs.append(furniture_spec(
            blueprints.speed_limit_type_id(kmh), signal.id, signal.actor_transform,
            [lane.trigger_box for lane in signal.lanes], signal.stop_waypoints, signal.affected_lane_waypoints,
            _half_extents(signal, SIGN_PLATE_HALF), SIGN_PLATE_HEIGHT, speed_limit=kmh,
        ))  # fmt: skip
    if skipped:
        log.info("%s: %d signals govern no lane and get no actor", town.name, skipped)
    return lights, signs
