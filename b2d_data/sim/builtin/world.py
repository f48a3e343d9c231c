"""The builtin simulator: a synchronous, deterministic 20 Hz world implementing :class:`~b2d_data.sim.api.Simulator`.

One :meth:`BuiltinSimulator.tick`:

1. the background-traffic manager computes its vehicles' controls from the previous snapshot (and spawns or
   removes vehicles);
2. traffic-light cycles advance;
3. vehicles move on the kinematic bicycle (kinematic_bicycle.py), walkers along their control, children with
   their parents; vehicles and walkers follow the road surface (z and pitch from the map's lanes);
4. collisions are detected between every pair of actors that can collide (oriented boxes, collisions.py)
   and resolved simply (see :meth:`BuiltinSimulator._resolve_collisions`);
5. a new immutable :class:`~b2d_data.sim.api.Snapshot` is built.

Every random draw comes from generators seeded by the world's seed, and nothing iterates over hash-ordered
containers, so two worlds with the same seed and the same calls produce identical snapshots.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial import cKDTree

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D, wrap_degrees
from b2d_data.format.weather import ROUTE_DEFAULT, WeatherParameters
from b2d_data.sim import blueprints
from b2d_data.sim.api import (
    FIXED_DELTA_SECONDS,
    ActorKind,
    ActorSpec,
    ActorState,
    CollisionEvent,
    RigConfig,
    SensorData,
    SensorMount,
    SimulatorError,
    Snapshot,
    SpawnError,
    TrafficLightState,
    VehicleControl,
    VehicleDoor,
    WalkerControl,
)
from b2d_data.sim.builtin import collisions, kinematic_bicycle, walkers
from b2d_data.sim.builtin.furniture import furniture_from_map
from b2d_data.sim.builtin.ground import GroundModel, ground_from_map
from b2d_data.sim.builtin.traffic_lights import FurnitureSpec, LightTiming, TrafficLightController, sign_info

if TYPE_CHECKING:
    from b2d_data.maps import Map
    from b2d_data.sim.builtin.background_traffic import BackgroundTrafficManager

log = logging.getLogger(__name__)

#: How far an open door sticks out of the side of the car (m): it widens the collision box by this much.
DOOR_OPEN_WIDTH = 0.9
#: Rough masses (kg) for collision impulses.
_MASS_BY_BASE_TYPE = {"car": 1600.0, "": 1600.0, "van": 2400.0, "truck": 9000.0, "bus": 12000.0,
                      "motorcycle": 250.0, "bicycle": 100.0}  # fmt: skip
_WALKER_MASS = 80.0
_STATIC_MASS = math.inf


class PlaceTakenError(SpawnError):
    """The spawn transform overlaps an existing actor."""


@dataclass(eq=False)
class _Actor:
    """The world's mutable record of one actor (clients only ever see :class:`ActorState`)."""

    id: int
    spec: ActorSpec
    blueprint: blueprints.Blueprint
    attributes: dict[str, str]
    x: float
    y: float
    z: float
    pitch: float = 0.0
    yaw: float = 0.0
    roll: float = 0.0
    speed: float = 0.0  # vehicles: signed speed along the heading
    steer: float = 0.0  # vehicles: applied steer after the rate limit
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # deg/s
    acceleration: np.ndarray = field(default_factory=lambda: np.zeros(3))
    control: VehicleControl | WalkerControl | None = None
    physics: bool = True
    light_state: str = "NONE"
    open_doors: tuple[VehicleDoor, ...] = ()
    parent_id: int | None = None
    relative: Transform | None = None  # pose relative to the parent
    children: list[int] = field(default_factory=list)
    target_velocity: np.ndarray | None = None  # forced for the next tick only
    stop_next: bool = False  # first contact in the last tick: stop at the start of the next one
    bbox: BoundingBox | None = None
    mass: float = 0.0
    params: np.ndarray | None = None  # vehicles: dynamics + geometry row for VehicleArrays
    cached_state: ActorState | None = None

    @property
    def kind(self) -> ActorKind:
        return self.blueprint.kind

    @property
    def frozen_attributes(self) -> dict[str, str]:
        """A copy of the attributes for a snapshot (a client changing it cannot change the world; picklable)."""
        return dict(self.attributes)

    @property
    def moves(self) -> bool:
        """Vehicles and walkers with physics on move by themselves."""
        return self.physics and self.parent_id is None and self.kind in (ActorKind.VEHICLE, ActorKind.WALKER)

    def transform(self) -> Transform:
        return Transform(Location(self.x, self.y, self.z), Rotation(pitch=self.pitch, yaw=self.yaw, roll=self.roll))

    def invalidate(self) -> None:
        self.cached_state = None


def _load_map(town: Map | str | Path) -> Map:
    """A Map from a Map, an .xodr path, a generated preset or a CARLA town name (see ``maps.towns``)."""
    from b2d_data.maps.towns import UnknownTownError, resolve_town

    try:
        return resolve_town(town)
    except UnknownTownError as exc:
        raise SimulatorError(str(exc)) from None


class BuiltinSimulator:
    """A synchronous, deterministic 20 Hz world over an OpenDRIVE town (implements ``Simulator``)."""

    def __init__(self, town: Map | str | Path, seed: int = 0, weather: WeatherParameters | None = None,
                 light_timing: LightTiming = LightTiming()) -> None:
        self._map = _load_map(town)
        self._seed = int(seed)
        streams = np.random.SeedSequence(self._seed).spawn(3)
        self._light_rng = np.random.default_rng(streams[0])
        self._background_rng = np.random.default_rng(streams[1])
        self._weather = weather if weather is not None else ROUTE_DEFAULT
        self._frame = 0
        self._time = 0.0
        self._next_id = 1
        self._actors: dict[int, _Actor] = {}
        self._contacts: set[tuple[int, int]] = set()
        # caches rebuilt when actors are added, removed, teleported or (un)frozen (see _layout_changed)
        self._movers: tuple[list[_Actor], list[_Actor]] | None = None
        self._static: tuple[list[_Actor], collisions.Boxes, Any, float] | None = None
        self._dynamic: list[_Actor] | None = None
        self._ground: GroundModel = ground_from_map(self._map)
        self._sensors: Any = None
        self._rig_ego: int | None = None
        self._agent_sensors: Any = None  # an agent's own rig (attach_sensors), apart from the Bench2Drive one
        self._agent_ego: int | None = None
        self._closed = False

        light_specs, sign_specs = furniture_from_map(self._map)
        lights = [(self._add_furniture(spec), spec) for spec in light_specs]
        self._signs = {}
        for spec in sign_specs:
            actor_id = self._add_furniture(spec)
            self._signs[actor_id] = sign_info(actor_id, spec)
        self._lights = TrafficLightController(lights, light_timing, rng=self._light_rng)
        self._background_manager: BackgroundTrafficManager | None = None
        self._snapshot = self._build_snapshot([])
        log.info("builtin world on %s: %d traffic lights, %d signs, seed %d",
                 getattr(self._map, "name", "?"), len(lights), len(self._signs), self._seed)

    # -- Simulator protocol: properties --------------------------------------------------------------------
    @property
    def map(self) -> Map:
        """The loaded town."""
        return self._map

    @property
    def background(self) -> BackgroundTrafficManager:
        """The background-traffic manager (created on first use)."""
        if self._background_manager is None:
            from b2d_data.sim.builtin.background_traffic import BackgroundTrafficManager

            self._background_manager = BackgroundTrafficManager(self, rng=self._background_rng)
        return self._background_manager

    @property
    def seed(self) -> int:
        """The seed the world was created with."""
        return self._seed

    @property
    def ground(self) -> GroundModel:
        """Road-surface height lookup (shared with background traffic and tests)."""
        return self._ground

    def snapshot(self) -> Snapshot:
        """The state after the last tick (or after loading)."""
        return self._snapshot

    def actor_ids(self) -> set[int]:
        """Ids of every live actor, including those spawned since the last snapshot."""
        return set(self._actors)

    # -- Simulator protocol: the tick ---------------------------------------------------------------------
    def tick(self) -> Snapshot:
        """Advance by :data:`FIXED_DELTA_SECONDS` and return the new state."""
        self._check_open()
        dt = FIXED_DELTA_SECONDS
        if self._background_manager is not None:
            self._background_manager.update(self._snapshot)
        self._frame += 1
        self._time = self._frame * dt
        self._lights.advance(dt)
        vehicles, walkers_ = self._mover_lists()
        start = {a.id: (a.x, a.y, a.z, a.pitch, a.yaw, a.roll, a.speed) for a in (*vehicles, *walkers_)}
        self._step_vehicles(dt)
        self._step_walkers(dt)
        self._update_children()
        events = self._resolve_collisions(start)
        self._snapshot = self._build_snapshot(events)
        return self._snapshot

    # -- Simulator protocol: actors ------------------------------------------------------------------------
    def spawn_actor(self, spec: ActorSpec, transform: Transform, attach_to: int | None = None) -> int:
        """Spawn an actor and return its id; raises :class:`SpawnError` when the place is taken."""
        self._check_open()
        blueprint = blueprints.resolve(spec)
        if blueprint.kind in (ActorKind.TRAFFIC_LIGHT, ActorKind.TRAFFIC_SIGN):
            raise SpawnError(f"{spec.type_id}: traffic lights and signs come from the map's signals, not spawn_actor")
        parent = None
        if attach_to is not None:
            parent = self._actors.get(attach_to)
            if parent is None:
                raise SpawnError(f"cannot attach {spec.type_id} to actor {attach_to}: no such actor")
        attributes = blueprint.default_attributes()
        attributes.update({k: str(v) for k, v in spec.attributes.items()})
        attributes["role_name"] = spec.role_name
        rot = transform.rotation
        actor = _Actor(
            id=0, spec=spec, blueprint=blueprint, attributes=attributes,
            x=transform.location.x, y=transform.location.y, z=transform.location.z,
            pitch=rot.pitch, yaw=wrap_degrees(rot.yaw), roll=rot.roll,
            bbox=blueprint.bounding_box, mass=_mass_of(blueprint),
            physics=blueprint.kind in (ActorKind.VEHICLE, ActorKind.WALKER),
        )  # fmt: skip
        if blueprint.kind is ActorKind.VEHICLE:
            actor.control = VehicleControl()
        elif blueprint.kind is ActorKind.WALKER:
            actor.control = WalkerControl()
        if parent is not None:
            actor.parent_id = parent.id
            actor.relative = transform
            self._place_child(actor, parent)
        else:
            self._snap_to_ground([actor])
            if blueprint.collides:
                blocking = self._blocking(actor)
                if blocking:
                    names = ", ".join(f"{a.id} ({a.blueprint.type_id})" for a in blocking[:3])
                    raise PlaceTakenError(
                        f"cannot spawn {spec.type_id} at ({actor.x:.2f}, {actor.y:.2f}, {actor.z:.2f}): "
                        f"overlaps actor {names}"
                    )
        actor.id = self._new_id()
        if blueprint.kind is ActorKind.VEHICLE:
            actor.params = kinematic_bicycle.param_row(blueprint.dynamics or blueprints.CAR_DYNAMICS,
                                                       blueprint.geometry or blueprints.DEFAULT_GEOMETRY)
        self._actors[actor.id] = actor
        if parent is not None:
            parent.children.append(actor.id)
        self._layout_changed()
        return actor.id

    def try_spawn_actor(self, spec: ActorSpec, transform: Transform) -> int | None:
        """Spawn an actor, or return ``None`` when the place is taken."""
        try:
            return self.spawn_actor(spec, transform)
        except PlaceTakenError:
            return None

    def destroy_actor(self, actor_id: int) -> None:
        """Remove an actor and the actors attached to it (unknown ids raise :class:`SimulatorError`)."""
        actor = self._actor(actor_id)
        if actor.kind in (ActorKind.TRAFFIC_LIGHT, ActorKind.TRAFFIC_SIGN):
            raise SimulatorError(f"actor {actor_id} ({actor.blueprint.type_id}) belongs to the map and cannot be destroyed")
        for child in list(actor.children):
            if child in self._actors:
                self.destroy_actor(child)
        if actor.parent_id is not None and actor.parent_id in self._actors:
            self._actors[actor.parent_id].children.remove(actor_id)
        del self._actors[actor_id]
        self._layout_changed()
        if self._rig_ego == actor_id and self._sensors is not None:
            self._sensors.close()
            self._sensors, self._rig_ego = None, None
        if self._agent_ego == actor_id:
            self._release_agent_sensors()

    def apply_control(self, actor_id: int, control: VehicleControl | WalkerControl) -> None:
        """Set the control a vehicle or walker applies from the next tick on."""
        actor = self._actor(actor_id)
        if actor.kind is ActorKind.VEHICLE and isinstance(control, VehicleControl):
            actor.control = control
        elif actor.kind is ActorKind.WALKER and isinstance(control, WalkerControl):
            actor.control = control
        else:
            raise SimulatorError(
                f"actor {actor_id} ({actor.blueprint.type_id}) cannot take a {type(control).__name__}"
            )
        actor.invalidate()

    def set_transform(self, actor_id: int, transform: Transform) -> None:
        """Teleport an actor (it keeps its speed; vehicles and walkers settle on the road at the next tick)."""
        actor = self._actor(actor_id)
        if actor.kind in (ActorKind.TRAFFIC_LIGHT, ActorKind.TRAFFIC_SIGN):
            raise SimulatorError(f"actor {actor_id} ({actor.blueprint.type_id}) belongs to the map and cannot move")
        if actor.parent_id is not None:
            actor.relative = transform
            self._place_child(actor, self._actors[actor.parent_id])
        else:
            loc, rot = transform.location, transform.rotation
            actor.x, actor.y, actor.z = loc.x, loc.y, loc.z
            actor.pitch, actor.yaw, actor.roll = rot.pitch, wrap_degrees(rot.yaw), rot.roll
        self._contacts = {p for p in self._contacts if actor_id not in p}
        actor.invalidate()
        self._layout_changed()

    def set_target_velocity(self, actor_id: int, velocity: Vector3D) -> None:
        """Force an actor's velocity (world frame) for the next tick.

        The actor then moves exactly ``velocity · dt`` in that tick and reports that velocity; a vehicle's
        heading still turns with its steer, and its speed afterwards is the velocity's forward component.
        Actors with physics off and props ignore it (as in CARLA).
        """
        actor = self._actor(actor_id)
        if actor.moves:
            actor.target_velocity = np.array([velocity.x, velocity.y, velocity.z], dtype=np.float64)

    def set_simulate_physics(self, actor_id: int, enabled: bool) -> None:
        """Freeze (False: the actor stays put unless teleported) or release (True) a vehicle or walker."""
        actor = self._actor(actor_id)
        if actor.kind not in (ActorKind.VEHICLE, ActorKind.WALKER):
            return  # props and furniture never move
        actor.physics = bool(enabled)
        if not enabled:
            actor.speed = 0.0
            actor.velocity = np.zeros(3)
            actor.angular_velocity = np.zeros(3)
            actor.acceleration = np.zeros(3)
            actor.target_velocity = None
        actor.invalidate()
        self._layout_changed()

    def set_light_state(self, actor_id: int, light_state: str) -> None:
        """Set a vehicle's light state name (``sim.light_state``; Special1 or Special2: sirens)."""
        actor = self._actor(actor_id)
        if actor.kind is not ActorKind.VEHICLE:
            raise SimulatorError(f"actor {actor_id} ({actor.blueprint.type_id}) is not a vehicle and has no lights")
        actor.light_state = str(light_state)
        actor.invalidate()

    def open_door(self, actor_id: int, door: VehicleDoor) -> None:
        """Open a vehicle door: its collision (and reported) box widens by :data:`DOOR_OPEN_WIDTH` on that side."""
        actor = self._actor(actor_id)
        if actor.kind is not ActorKind.VEHICLE or not actor.blueprint.has_dynamic_doors:
            with_doors = ", ".join(blueprints.filter_ids("vehicle.*", has_dynamic_doors=True))
            raise SimulatorError(
                f"actor {actor_id} ({actor.blueprint.type_id}) has no doors that open; blueprints with doors: {with_doors}"
            )
        door = VehicleDoor(door)
        opened = set(actor.open_doors) | ({VehicleDoor.FL, VehicleDoor.FR, VehicleDoor.RL, VehicleDoor.RR}
                                          if door is VehicleDoor.ALL else {door})
        actor.open_doors = tuple(sorted(opened))
        actor.bbox = _door_box(actor.blueprint.bounding_box, actor.open_doors)
        actor.invalidate()
        self._layout_changed()

    def set_traffic_light_state(self, light_id: int, state: TrafficLightState, freeze: bool = True) -> None:
        """Force a light's state; a frozen light keeps it until released."""
        self._actor(light_id)
        self._lights.set_state(light_id, state, freeze)

    def freeze_traffic_lights(self, frozen: bool) -> None:
        """Stop (True) or resume every light's cycle (resuming also releases individually frozen lights)."""
        self._lights.freeze_all(frozen)

    def traffic_light_group(self, light_id: int) -> list[int]:
        """Ids of the lights of the junction group ``light_id`` belongs to (CARLA's ``get_group_traffic_lights``)."""
        self._actor(light_id)
        return self._lights.group_members(light_id)

    def set_weather(self, weather: WeatherParameters) -> None:
        """Change the weather (affects rendering)."""
        self._weather = weather
        self._snapshot = Snapshot(
            frame=self._snapshot.frame, timestamp=self._snapshot.timestamp, actors=self._snapshot.actors,
            traffic_lights=self._snapshot.traffic_lights, traffic_signs=self._snapshot.traffic_signs,
            collisions=self._snapshot.collisions, weather=weather,
        )  # fmt: skip

    # -- sensors ---------------------------------------------------------------------------------------------
    def attach_rig(self, ego_id: int, config: RigConfig = RigConfig()) -> None:
        """Mount the Bench2Drive sensor rig on the ego (the sensor suite is imported on first use)."""
        self._actor(ego_id)
        try:
            from b2d_data.sim.builtin.sensors import SensorSuite
        except ImportError as exc:
            raise SimulatorError(f"the builtin sensor suite is not available: {exc}") from exc
        if self._sensors is not None:
            self._sensors.close()
        self._sensors = SensorSuite(self._map, config, self._seed)
        self._rig_ego = ego_id

    def read_sensors(self) -> SensorData:
        """Capture every mounted sensor at the current tick."""
        if self._sensors is None or self._rig_ego is None:
            raise SimulatorError("no sensor rig mounted: call attach_rig(ego_id) first")
        return self._sensors.capture(self._snapshot, self._rig_ego)

    def attach_sensors(self, ego_id: int, mounts: Sequence[SensorMount]) -> None:
        """Mount an agent's own sensors on the ego, replacing any mounted before (imported on first use)."""
        self._actor(ego_id)
        try:
            from b2d_data.sim.builtin.sensors.mounted import MountedSensors
        except ImportError as exc:
            raise SimulatorError(f"the builtin sensor suite is not available: {exc}") from exc
        # Built before the old rig goes, so that a rejected list leaves the mounted sensors as they were.
        sensors = MountedSensors(self._map, mounts, self._seed, start_frame=self._snapshot.frame)
        self._release_agent_sensors()
        self._agent_sensors, self._agent_ego = sensors, ego_id

    def read_attached_sensors(self) -> dict[str, Any]:
        """Every sensor of :meth:`attach_sensors` at the current tick, keyed by sensor id, as CARLA delivers them."""
        if self._agent_sensors is None or self._agent_ego is None:
            raise SimulatorError("no agent sensors mounted: call attach_sensors(ego_id, mounts) first")
        return self._agent_sensors.capture(self._snapshot, self._agent_ego)

    def _release_agent_sensors(self) -> None:
        if self._agent_sensors is not None:
            self._agent_sensors.close()
        self._agent_sensors, self._agent_ego = None, None

    def close(self) -> None:
        """Release both sensor rigs and forget every actor."""
        if self._sensors is not None:
            self._sensors.close()
            self._sensors = None
        self._release_agent_sensors()
        if self._background_manager is not None:
            self._background_manager.forget()
        self._actors.clear()
        self._closed = True

    def __enter__(self) -> BuiltinSimulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- internals: bookkeeping ------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise SimulatorError("the simulator was closed")

    def _new_id(self) -> int:
        actor_id = self._next_id
        self._next_id += 1
        return actor_id

    def _actor(self, actor_id: int) -> _Actor:
        try:
            return self._actors[actor_id]
        except KeyError:
            raise SimulatorError(f"no actor with id {actor_id!r} in the world") from None

    def _layout_changed(self) -> None:
        self._movers = None
        self._static = None
        self._dynamic = None

    def _mover_lists(self) -> tuple[list[_Actor], list[_Actor]]:
        """(vehicles, walkers) that move by themselves, in id order (cached until the layout changes)."""
        if self._movers is None:
            movers = [a for a in self._actors.values() if a.moves]
            self._movers = ([a for a in movers if a.kind is ActorKind.VEHICLE],
                            [a for a in movers if a.kind is ActorKind.WALKER])
        return self._movers

    def _static_set(self) -> tuple[list[_Actor], collisions.Boxes, Any, float]:
        """Colliding actors that never move by themselves, their boxes, a k-d tree of them, their max radius."""
        if self._static is None:
            actors = [a for a in self._actors.values()
                      if a.blueprint.collides and not a.moves and a.parent_id is None]
            boxes = self._boxes(actors)
            tree = cKDTree(np.column_stack([boxes.cx, boxes.cy])) if actors else None
            radius = float(boxes.radius.max()) if actors else 0.0
            self._static = (actors, boxes, tree, radius)
        return self._static

    def _add_furniture(self, spec: FurnitureSpec) -> int:
        blueprint = blueprints.find(spec.type_id)
        loc, rot = spec.transform.location, spec.transform.rotation
        actor = _Actor(
            id=self._new_id(), spec=ActorSpec(spec.type_id), blueprint=blueprint,
            attributes={"role_name": "", "opendrive_id": spec.opendrive_id},
            x=loc.x, y=loc.y, z=loc.z, pitch=rot.pitch, yaw=rot.yaw, roll=rot.roll,
            bbox=blueprint.bounding_box, mass=_STATIC_MASS, physics=False,
        )  # fmt: skip
        self._actors[actor.id] = actor
        return actor.id

    def _place_child(self, child: _Actor, parent: _Actor) -> None:
        m = parent.transform().matrix() @ (child.relative or Transform()).matrix()
        pose = Transform.from_matrix(m)
        child.x, child.y, child.z = pose.location.x, pose.location.y, pose.location.z
        child.pitch, child.yaw, child.roll = pose.rotation.pitch, pose.rotation.yaw, pose.rotation.roll
        child.velocity = parent.velocity.copy()
        child.invalidate()

    def _update_children(self) -> None:
        for actor in self._actors.values():
            if actor.parent_id is not None:
                self._place_child(actor, self._actors[actor.parent_id])

    def _snap_to_ground(self, actors: Sequence[_Actor]) -> None:
        """Put vehicles, walkers and props on the road surface; vehicles also take its pitch."""
        if self._ground.empty or not actors:
            return
        lift = np.array([a.bbox.extent.z if a.kind is ActorKind.WALKER else 0.0 for a in actors])
        base = np.array([a.z for a in actors]) - lift
        z, pitch, found = self._ground.query(
            np.array([a.x for a in actors]), np.array([a.y for a in actors]), base, np.array([a.yaw for a in actors])
        )
        for k, actor in enumerate(actors):
            if not found[k]:
                continue
            actor.z = float(z[k] + lift[k])
            if actor.kind is ActorKind.VEHICLE:
                actor.pitch = float(pitch[k])

    # -- internals: motion -----------------------------------------------------------------------------------
    def _step_vehicles(self, dt: float) -> None:
        movers = self._mover_lists()[0]
        if not movers:
            return
        rows = []
        for a in movers:
            if a.stop_next:
                a.speed, a.stop_next = 0.0, False
            c = a.control if isinstance(a.control, VehicleControl) else _NO_CONTROL
            rows.append((a.x, a.y, a.yaw, a.speed, a.steer, c.throttle, c.steer, c.brake, c.hand_brake, c.reverse))
        state = np.array(rows, dtype=np.float64)
        state[:, 2] = np.radians(state[:, 2])
        arr = kinematic_bicycle.VehicleArrays.from_rows(state, np.array([a.params for a in movers]))
        x0, y0, yaw0 = state[:, 0], state[:, 1], state[:, 2]
        beta = kinematic_bicycle.step(arr, dt)
        forced = [i for i, a in enumerate(movers) if a.target_velocity is not None]
        for i in forced:
            # forced velocity: exact translation, heading from the steer, speed = forward component
            tv = movers[i].target_velocity
            arr.x[i], arr.y[i] = x0[i] + tv[0] * dt, y0[i] + tv[1] * dt
            arr.speed[i] = tv[0] * math.cos(arr.yaw[i]) + tv[1] * math.sin(arr.yaw[i])
        z_old = np.array([a.z for a in movers])
        yaw_deg = (np.degrees(arr.yaw) + 180.0) % 360.0 - 180.0
        for i, a in enumerate(movers):
            a.x, a.y, a.yaw = float(arr.x[i]), float(arr.y[i]), float(yaw_deg[i])
            a.speed, a.steer = float(arr.speed[i]), float(arr.steer[i])
        self._snap_to_ground(movers)
        heading = arr.yaw + beta
        vel = np.column_stack([arr.speed * np.cos(heading), arr.speed * np.sin(heading),
                               (np.array([a.z for a in movers]) - z_old) / dt])
        for i in forced:
            vel[i] = movers[i].target_velocity
            movers[i].target_velocity = None
        yaw_rate = np.degrees(np.remainder(arr.yaw - yaw0 + math.pi, 2.0 * math.pi) - math.pi) / dt
        # every vehicle's rows at once; each actor keeps its rows (views), which are only ever replaced, not changed
        acceleration = (vel - np.array([a.velocity for a in movers])) / dt
        spin = np.zeros((len(movers), 3))
        spin[:, 2] = yaw_rate
        for i, a in enumerate(movers):
            a.acceleration = acceleration[i]
            a.velocity = vel[i]
            a.angular_velocity = spin[i]
            a.cached_state = None

    def _step_walkers(self, dt: float) -> None:
        movers = self._mover_lists()[1]
        if not movers:
            return
        direction = np.zeros((len(movers), 3))
        speed = np.zeros(len(movers))
        for i, a in enumerate(movers):
            if a.stop_next:
                a.stop_next = False
                continue
            c = a.control if isinstance(a.control, WalkerControl) else WalkerControl()
            direction[i] = (c.direction.x, c.direction.y, c.direction.z)
            speed[i] = c.speed
        velocity = walkers.walker_velocity(direction, speed)
        for i, a in enumerate(movers):
            if a.target_velocity is not None:
                velocity[i] = a.target_velocity[:2]
                a.target_velocity = None
        yaw0 = np.array([a.yaw for a in movers])
        x, y, yaw = walkers.step_walkers(np.array([a.x for a in movers]), np.array([a.y for a in movers]), yaw0,
                                         velocity, dt)
        z_old = np.array([a.z for a in movers])
        for i, a in enumerate(movers):
            a.x, a.y, a.yaw = float(x[i]), float(y[i]), wrap_degrees(float(yaw[i]))
        self._snap_to_ground(movers)
        for i, a in enumerate(movers):
            v = np.array([velocity[i, 0], velocity[i, 1], (a.z - z_old[i]) / dt])
            a.acceleration = (v - a.velocity) / dt
            a.velocity = v
            a.speed = float(np.hypot(v[0], v[1]))
            a.angular_velocity = np.array([0.0, 0.0, wrap_degrees(a.yaw - yaw0[i]) / dt])
            a.cached_state = None

    # -- internals: collisions -------------------------------------------------------------------------------
    def _boxes(self, actors: Sequence[_Actor]) -> collisions.Boxes:
        rows = []
        for a in actors:
            box = a.bbox or a.blueprint.bounding_box
            rad = math.radians(a.yaw)
            c, s = math.cos(rad), math.sin(rad)
            bx, by = box.location.x, box.location.y
            cz = a.z + box.location.z
            rows.append((a.x + c * bx - s * by, a.y + s * bx + c * by, rad + math.radians(box.rotation.yaw),
                         box.extent.x, box.extent.y, cz - box.extent.z, cz + box.extent.z))
        return collisions.Boxes.from_rows(rows)

    def _dynamic_colliders(self) -> list[_Actor]:
        """Colliding actors that move by themselves or with a parent, in id order (cached until the layout changes)."""
        if self._dynamic is None:
            self._dynamic = [a for a in self._actors.values()
                             if a.blueprint.collides and (a.moves or a.parent_id is not None)]
        return self._dynamic

    def _blocking(self, actor: _Actor) -> list[_Actor]:
        """Existing actors whose boxes overlap the (not yet registered) actor's box."""
        box = self._boxes([actor])
        static, static_boxes, _, _ = self._static_set()
        dynamic = self._dynamic_colliders()
        hits = [static[int(k)] for k in collisions.overlaps_any(box, static_boxes)]
        if dynamic:
            hits += [dynamic[int(k)] for k in collisions.overlaps_any(box, self._boxes(dynamic))]
        return sorted(hits, key=lambda a: a.id)

    def _overlapping(self) -> list[tuple[_Actor, _Actor, float, float, float]]:
        """Overlapping (a, b, contact x, y, z) among moving actors and between moving and static ones."""
        dynamic = self._dynamic_colliders()
        if not dynamic:
            return []
        dyn = self._boxes(dynamic)
        out = []
        pairs = collisions.candidate_pairs(dyn)
        if pairs.size:
            family = np.array([a.parent_id if a.parent_id is not None else a.id for a in dynamic])
            pairs = pairs[family[pairs[:, 0]] != family[pairs[:, 1]]]
            pairs = pairs[collisions.overlap(dyn, pairs[:, 0], dyn, pairs[:, 1])]
            for i, j in pairs.tolist():
                out.append((dynamic[i], dynamic[j], *_contact(dyn, i, dyn, j)))
        static, sta, tree, static_radius = self._static_set()
        if tree is not None:
            lists = tree.query_ball_point(np.column_stack([dyn.cx, dyn.cy]), dyn.radius + static_radius)
            ia = np.array([i for i, hits in enumerate(lists) for _ in hits], dtype=np.int64)
            ib = np.array([k for hits in lists for k in hits], dtype=np.int64)
            if ia.size:
                hit = collisions.overlap(dyn, ia, sta, ib)
                for i, k in zip(ia[hit].tolist(), ib[hit].tolist()):
                    if dynamic[i].parent_id == static[k].id:
                        continue
                    out.append((dynamic[i], static[k], *_contact(dyn, i, sta, k)))
        return out

    def _resolve_collisions(self, start: dict[int, tuple[float, ...]]) -> list[CollisionEvent]:
        """Detect overlaps and report them for both actors; stop actors that drove into something.

        Resolution (kept simple on purpose): an actor that moved into another one this tick keeps its new pose
        and reported velocity at first contact (so criteria see the impact speed) and is stopped at the start
        of the next tick; if it was already touching that actor and its own motion brought it closer, its
        move is undone and its velocity zeroed. Actors are never pushed; moving away is always allowed.
        """
        events: list[CollisionEvent] = []
        contacts: set[tuple[int, int]] = set()
        undo: set[int] = set()
        for a, b, cx, cy, cz in self._overlapping():
            key = (min(a.id, b.id), max(a.id, b.id))
            contacts.add(key)
            touching_before = key in self._contacts
            for me, other in ((a, b), (b, a)):
                if me.id not in start or not _moved_closer(me, other, start[me.id]):
                    continue
                if touching_before:
                    undo.add(me.id)
                else:
                    me.stop_next = True
            loc = Location(cx, cy, cz)
            for me, other in ((a, b), (b, a)):
                events.append(CollisionEvent(
                    frame=self._frame, actor_id=me.id, other_id=other.id, other_type_id=other.blueprint.type_id,
                    location=loc, normal_impulse=_impulse(me, other),
                ))  # fmt: skip
        for actor_id in sorted(undo):
            a = self._actors[actor_id]
            a.x, a.y, a.z, a.pitch, a.yaw, a.roll, _ = start[actor_id]
            a.speed, a.stop_next = 0.0, False
            a.acceleration = a.acceleration - a.velocity / FIXED_DELTA_SECONDS
            a.velocity = np.zeros(3)
            a.angular_velocity = np.zeros(3)
            a.invalidate()
        self._contacts = contacts
        events.sort(key=lambda e: (e.actor_id, e.other_id))
        return events

    # -- internals: snapshots --------------------------------------------------------------------------------
    def _state(self, a: _Actor) -> ActorState:
        if a.cached_state is not None:
            return a.cached_state
        blueprint = a.blueprint
        state = ActorState(
            id=a.id,
            type_id=blueprint.type_id,
            kind=blueprint.kind,
            transform=a.transform(),
            velocity=Vector3D(*a.velocity.tolist()),
            angular_velocity=Vector3D(*a.angular_velocity.tolist()),
            acceleration=Vector3D(*a.acceleration.tolist()),
            bounding_box=a.bbox or blueprint.bounding_box,
            semantic_tags=blueprint.semantic_tags,
            role_name=a.spec.role_name,
            base_type=blueprint.base_type,
            attributes=a.frozen_attributes,
            control=a.control,
            light_state=a.light_state,
            open_doors=a.open_doors,
            is_static=not a.physics,
            parent_id=a.parent_id,
        )
        a.cached_state = state
        return state

    def _build_snapshot(self, events: list[CollisionEvent]) -> Snapshot:
        return Snapshot(
            frame=self._frame,
            timestamp=self._time,
            actors={actor_id: self._state(a) for actor_id, a in self._actors.items()},
            traffic_lights=self._lights.infos(),
            traffic_signs=dict(self._signs),
            collisions=tuple(events),
            weather=self._weather,
        )


_NO_CONTROL = VehicleControl()


def _contact(a: collisions.Boxes, i: int, b: collisions.Boxes, j: int) -> tuple[float, float, float]:
    """A contact point for two overlapping boxes: between their centres, mid-height of the overlap."""
    z = (max(a.z_low[i], b.z_low[j]) + min(a.z_high[i], b.z_high[j])) / 2.0
    return float((a.cx[i] + b.cx[j]) / 2.0), float((a.cy[i] + b.cy[j]) / 2.0), float(z)


def _mass_of(blueprint: blueprints.Blueprint) -> float:
    if blueprint.kind is ActorKind.VEHICLE:
        return _MASS_BY_BASE_TYPE.get(blueprint.base_type, 1600.0)
    if blueprint.kind is ActorKind.WALKER:
        return _WALKER_MASS
    return _STATIC_MASS


def _door_box(box: BoundingBox, doors: tuple[VehicleDoor, ...]) -> BoundingBox:
    """The box widened on the side of each open door (left doors: −y, right doors: +y in the actor frame)."""
    left = box.location.y - box.extent.y - (DOOR_OPEN_WIDTH if {VehicleDoor.FL, VehicleDoor.RL} & set(doors) else 0.0)
    right = box.location.y + box.extent.y + (DOOR_OPEN_WIDTH if {VehicleDoor.FR, VehicleDoor.RR} & set(doors) else 0.0)
    return BoundingBox(
        Location(box.location.x, (left + right) / 2.0, box.location.z),
        Location(box.extent.x, (right - left) / 2.0, box.extent.z),
        box.rotation,
    )


def _moved_closer(me: _Actor, other: _Actor, start: tuple[float, ...]) -> bool:
    """Did ``me``'s own motion this tick bring its origin closer to ``other``'s current origin?"""
    before = math.hypot(start[0] - other.x, start[1] - other.y)
    after = math.hypot(me.x - other.x, me.y - other.y)
    return after < before - 1e-9


def _impulse(me: _Actor, other: _Actor) -> Vector3D:
    """Impulse on ``me`` along the line of centres: reduced mass × closing speed (N·s)."""
    d = np.array([me.x - other.x, me.y - other.y, 0.0])
    norm = float(np.linalg.norm(d))
    if norm < 1e-9:
        return Vector3D()
    n = d / norm
    closing = max(0.0, float((other.velocity - me.velocity) @ n))
    m1, m2 = me.mass, other.mass
    if math.isinf(m1) and math.isinf(m2):
        reduced = 0.0
    elif math.isinf(m1):
        reduced = m2
    elif math.isinf(m2):
        reduced = m1
    else:
        reduced = m1 * m2 / (m1 + m2)
    j = n * reduced * closing
    return Vector3D(float(j[0]), float(j[1]), float(j[2]))
