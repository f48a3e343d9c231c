"""Traffic lights and signs: their actors' geometry (from the map's signals) and the lights' cycles.

Geometry follows CARLA, whose generated trigger boxes the map already computes (``b2d_data.maps.signals``):

- the actor transform is CARLA's sign/light actor pose (``Signal.actor_transform``: the landmark position,
  yaw + 90°, level);
- the trigger volume is the governed lanes' trigger boxes (one per lane; their union in the lane frame when a
  signal governs several lanes), expressed in the actor frame like ``actor.trigger_volume``;
- ``stop_waypoints`` are the lane waypoints at the box centres (``TrafficLight.get_stop_waypoints``) and
  ``affected_lane_waypoints`` the lane waypoints at the signal references;
- the level bounding box is the light head (sign plate) in world coordinates, facing the approaching traffic:
  where the map's ``<signal>`` lifts it (zOffset > 0 and a height, ``b2d_data.sim.builtin.furniture``) it spans
  zOffset to zOffset + height above the road's reference line as OpenDRIVE defines them, else it is centred
  :data:`LIGHT_HEAD_HEIGHT` (:data:`SIGN_PLATE_HEIGHT`) above the governed lane;
- the pole stands on the road under the actor (``pole_base``): the actor pose itself is CARLA's landmark pose,
  which zOffset lifts.

Cycles follow CARLA's traffic-light groups: all lights governing one junction form a group whose poles (one
OpenDRIVE controller each) take turns in controller-sequence order; the active pole shows green for ``green``
s, yellow for ``yellow`` s and red for ``red`` s (all-red clearance), then the next pole starts; every other
pole is red. CARLA's defaults are 10 s / 3 s / 2 s.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, wrap_degrees
from b2d_data.sim.api import SimulatorError, TrafficLightInfo, TrafficLightState, TrafficSignInfo

#: Height (m) of a light head's / sign plate's centre above the governed lane where the map does not lift it.
LIGHT_HEAD_HEIGHT = 3.0
SIGN_PLATE_HEIGHT = 2.1
#: Default head / plate half extents when the map gives no signal size (depth, width, height).
LIGHT_HEAD_HALF = (0.25, 0.3, 0.6)
SIGN_PLATE_HALF = (0.05, 0.4, 0.4)


@dataclass(frozen=True)
class LightTiming:
    """Seconds of green, yellow and all-red per pole (CARLA's defaults)."""

    green: float = 10.0
    yellow: float = 3.0
    red: float = 2.0


@dataclass(frozen=True)
class FurnitureSpec:
    """One light or sign to create: everything but its actor id and (for lights) its state."""

    type_id: str
    opendrive_id: str
    transform: Transform
    trigger_volume: BoundingBox
    stop_waypoints: tuple[Any, ...]
    affected_lane_waypoints: tuple[Any, ...]
    level_bbox: BoundingBox
    level_bbox_transform: Transform
    pole_base: Location
    group_key: int = -1  # lights: junction id (or a negative key of its own when not at a junction)
    pole_key: tuple[int, str] = (0, "")  # lights with the same key switch together; keys sort in cycle order
    speed_limit: float | None = None


def union_box(boxes: Sequence[BoundingBox]) -> BoundingBox:
    """The smallest box, in the first box's orientation, holding every (world) box of the list."""
    first = boxes[0]
    yaw = math.radians(first.rotation.yaw)
    c, s = math.cos(yaw), math.sin(yaw)
    lo = np.array([math.inf, math.inf, math.inf])
    hi = -lo
    origin = np.array([first.location.x, first.location.y, first.location.z])
    for box in boxes:
        by = math.radians(box.rotation.yaw)
        bc, bs = math.cos(by), math.sin(by)
        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                wx = box.location.x + bc * sx * box.extent.x - bs * sy * box.extent.y
                wy = box.location.y + bs * sx * box.extent.x + bc * sy * box.extent.y
                d = np.array([wx, wy]) - origin[:2]
                local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
                lo[:2], hi[:2] = np.minimum(lo[:2], local), np.maximum(hi[:2], local)
        lo[2] = min(lo[2], box.location.z - box.extent.z - origin[2])
        hi[2] = max(hi[2], box.location.z + box.extent.z - origin[2])
    mid = (lo + hi) / 2.0
    centre = origin + np.array([c * mid[0] - s * mid[1], s * mid[0] + c * mid[1], mid[2]])
    half = (hi - lo) / 2.0
    return BoundingBox(Location.from_array(centre), Location.from_array(half), first.rotation)


def furniture_spec(type_id: str, opendrive_id: str, actor: Transform, trigger_boxes: Sequence[BoundingBox],
                   stop_waypoints: Sequence[Any], affected: Sequence[Any], head_half: tuple[float, float, float],
                   head_height: float, group_key: int = -1, pole_key: tuple[int, str] = (0, ""),
                   speed_limit: float | None = None, head_z: float | None = None,
                   pole_z: float | None = None) -> FurnitureSpec:
    """Light/sign geometry from its actor pose and its governed lanes' world trigger boxes.

    The head (plate) is centred at world height ``head_z`` when given, else ``head_height`` above the first
    stop waypoint; the pole stands at the actor's x, y at height ``pole_z`` (default: the actor's z).
    """
    if not trigger_boxes or not stop_waypoints:
        raise SimulatorError(f"signal {opendrive_id}: no governed lane, cannot place its trigger volume")
    world_box = union_box(trigger_boxes)
    local = actor.inverse_transform_points(world_box.location.to_array()[None, :])[0]
    relative = Rotation(yaw=wrap_degrees(world_box.rotation.yaw - actor.rotation.yaw))
    trigger = BoundingBox(Location.from_array(local), world_box.extent, relative)
    lane_yaw = stop_waypoints[0].transform.rotation.yaw
    facing = Rotation(yaw=wrap_degrees(lane_yaw + 180.0))
    if head_z is None:
        head_z = stop_waypoints[0].transform.location.z + head_height
    head_centre = Location(actor.location.x, actor.location.y, head_z)
    pole_base = Location(actor.location.x, actor.location.y, actor.location.z if pole_z is None else pole_z)
    level = BoundingBox(head_centre, Location(*head_half), facing)
    return FurnitureSpec(
        type_id=type_id,
        opendrive_id=str(opendrive_id),
        transform=actor,
        trigger_volume=trigger,
        stop_waypoints=tuple(stop_waypoints),
        affected_lane_waypoints=tuple(affected),
        level_bbox=level,
        level_bbox_transform=Transform(head_centre, facing),
        pole_base=pole_base,
        group_key=group_key,
        pole_key=pole_key if pole_key[1] else (0, str(opendrive_id)),
        speed_limit=speed_limit,
    )


# -- light cycles ---------------------------------------------------------------------------------------


@dataclass
class _Light:
    info: TrafficLightInfo
    state: TrafficLightState
    elapsed: float = 0.0
    frozen: bool = False  # held by set_state(freeze=True) until released
    held: bool = False  # set_state(freeze=False): held until the group's next stage change


@dataclass
class _Group:
    group_id: int
    poles: list[list[int]]  # light actor ids per pole, in cycle order
    active: int = 0
    stage: TrafficLightState = TrafficLightState.GREEN
    stage_elapsed: float = 0.0
    members: list[int] = field(default_factory=list)


def _updated(info: TrafficLightInfo, state: TrafficLightState, elapsed: float, frozen: bool) -> TrafficLightInfo:
    """A copy of a frozen info with three fields changed.

    Equivalent to ``dataclasses.replace`` but several times cheaper: every light's elapsed time changes every
    tick, so this runs ~40 times per tick on a CARLA town.
    """
    new = object.__new__(TrafficLightInfo)
    new.__dict__.update(info.__dict__)
    new.__dict__.update(state=state, elapsed_time=elapsed, frozen=frozen)
    return new


_NEXT_STAGE = {
    TrafficLightState.GREEN: TrafficLightState.YELLOW,
    TrafficLightState.YELLOW: TrafficLightState.RED,
}


class TrafficLightController:
    """Runs every group's cycle; holds state overrides and freezes."""

    def __init__(self, lights: Iterable[tuple[int, FurnitureSpec]], timing: LightTiming = LightTiming(),
                 rng: np.random.Generator | None = None) -> None:
        self.timing = timing
        self._lights: dict[int, _Light] = {}
        self._groups: dict[int, _Group] = {}
        self._frozen_all = False
        by_group: dict[int, dict[tuple[int, str], list[int]]] = {}
        specs: dict[int, FurnitureSpec] = {}
        for actor_id, spec in lights:
            specs[actor_id] = spec
            by_group.setdefault(spec.group_key, {}).setdefault(spec.pole_key, []).append(actor_id)
        for gid, (group_key, poles) in enumerate(sorted(by_group.items())):
            ordered = _order_poles(poles)
            group = _Group(group_id=gid, poles=ordered, members=[i for p in ordered for i in p])
            if rng is not None:
                # every junction starts at a seeded point of its cycle, as if the town had been running
                group.active = int(rng.integers(len(ordered)))
                group.stage_elapsed = float(rng.uniform(0.0, timing.green))
            self._groups[gid] = group
            for actor_id in group.members:
                spec = specs[actor_id]
                info = TrafficLightInfo(
                    id=actor_id, transform=spec.transform, state=TrafficLightState.RED,
                    trigger_volume=spec.trigger_volume, stop_waypoints=spec.stop_waypoints,
                    affected_lane_waypoints=spec.affected_lane_waypoints, group_id=gid,
                    opendrive_id=spec.opendrive_id, level_bbox=spec.level_bbox,
                    level_bbox_transform=spec.level_bbox_transform, pole_base=spec.pole_base,
                )  # fmt: skip
                self._lights[actor_id] = _Light(info=info, state=TrafficLightState.RED)
            self._apply_group(group, initial=True)

    # -- queries ---------------------------------------------------------------------------------------
    def __contains__(self, actor_id: int) -> bool:
        return actor_id in self._lights

    def state(self, actor_id: int) -> TrafficLightState:
        """Current state of one light."""
        return self._light(actor_id).state

    def group_members(self, actor_id: int) -> list[int]:
        """All light ids of the group (junction) a light belongs to, in cycle order."""
        return list(self._groups[self._light(actor_id).info.group_id].members)

    def infos(self) -> dict[int, TrafficLightInfo]:
        """A :class:`TrafficLightInfo` per light, reflecting the current states."""
        out = {}
        for actor_id, light in self._lights.items():
            frozen = light.frozen or self._frozen_all
            info = light.info
            if info.state is not light.state or info.elapsed_time != light.elapsed or info.frozen != frozen:
                info = _updated(info, light.state, light.elapsed, frozen)
                light.info = info
            out[actor_id] = info
        return out

    # -- changes ---------------------------------------------------------------------------------------
    def set_state(self, actor_id: int, state: TrafficLightState, freeze: bool = True) -> None:
        """Force a light's state; frozen it keeps it, otherwise until its group next changes stage."""
        light = self._light(actor_id)
        if light.state is not state:
            light.elapsed = 0.0
        light.state = TrafficLightState(state)
        light.frozen = bool(freeze)
        light.held = not freeze

    def freeze_all(self, frozen: bool) -> None:
        """Stop every cycle (True) or resume them all, releasing individual freezes too (False)."""
        self._frozen_all = bool(frozen)
        if not frozen:
            for light in self._lights.values():
                if light.frozen:
                    light.frozen = False
                    light.held = True  # keeps its forced state until its group's next stage change

    def advance(self, dt: float) -> None:
        """Advance every running cycle by dt seconds."""
        for light in self._lights.values():
            light.elapsed += dt
        if self._frozen_all:
            return
        for group in self._groups.values():
            group.stage_elapsed += dt
            duration = self._duration(group.stage)
            if group.stage_elapsed + 1e-9 < duration:
                continue
            group.stage_elapsed -= duration
            if group.stage is TrafficLightState.RED or group.stage not in _NEXT_STAGE:
                group.active = (group.active + 1) % len(group.poles)
                group.stage = TrafficLightState.GREEN
            else:
                group.stage = _NEXT_STAGE[group.stage]
            for actor_id in group.members:
                self._lights[actor_id].held = False
            self._apply_group(group)

    # -- internals -------------------------------------------------------------------------------------
    def _duration(self, stage: TrafficLightState) -> float:
        if stage is TrafficLightState.GREEN:
            return self.timing.green
        if stage is TrafficLightState.YELLOW:
            return self.timing.yellow
        return self.timing.red

    def _apply_group(self, group: _Group, initial: bool = False) -> None:
        active = set(group.poles[group.active])
        for actor_id in group.members:
            light = self._lights[actor_id]
            if light.frozen or light.held:
                continue
            state = group.stage if actor_id in active else TrafficLightState.RED
            if state is not light.state:
                light.state = state
                light.elapsed = group.stage_elapsed if initial else 0.0

    def _light(self, actor_id: int) -> _Light:
        try:
            return self._lights[actor_id]
        except KeyError:
            raise SimulatorError(f"actor {actor_id} is not a traffic light") from None


def _order_poles(poles: dict[tuple[int, str], list[int]]) -> list[list[int]]:
    """Poles in cycle order: by (controller sequence, controller id), as CARLA sequences a junction's lights."""
    return [sorted(poles[key]) for key in sorted(poles)]


def sign_info(actor_id: int, spec: FurnitureSpec) -> TrafficSignInfo:
    """The :class:`TrafficSignInfo` of a sign actor."""
    return TrafficSignInfo(
        id=actor_id, type_id=spec.type_id, transform=spec.transform, trigger_volume=spec.trigger_volume,
        level_bbox=spec.level_bbox, level_bbox_transform=spec.level_bbox_transform,
        opendrive_id=spec.opendrive_id, speed_limit=spec.speed_limit, pole_base=spec.pole_base,
    )  # fmt: skip
