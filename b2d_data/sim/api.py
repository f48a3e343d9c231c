"""The simulator protocol that the expert, the scenarios and the data agent use.

It is shaped after CARLA's own concepts (a synchronous world ticking at 20 Hz, actors with blueprint ids,
transforms and half-extent bounding boxes, traffic lights with trigger volumes) so that the CARLA backend
is a thin adapter. Everything a client reads comes as an immutable :class:`Snapshot` per tick; everything it
changes goes through the :class:`Simulator` methods. All poses are in CARLA's left-handed world frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum, IntEnum
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from b2d_data.format.record import CameraFrame
from b2d_data.format.transform import BoundingBox, Location, Transform, Vector3D
from b2d_data.format.weather import WeatherParameters

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint

#: Physics / control step of every backend (20 Hz), as the leaderboard runs.
FIXED_DELTA_SECONDS = 0.05


class ActorKind(str, Enum):
    """Coarse actor class, derived from the blueprint id prefix."""

    VEHICLE = "vehicle"
    WALKER = "walker"
    TRAFFIC_LIGHT = "traffic_light"
    TRAFFIC_SIGN = "traffic_sign"
    PROP = "prop"


class TrafficLightState(IntEnum):
    """carla.TrafficLightState; the int is what annotations store."""

    RED = 0
    YELLOW = 1
    GREEN = 2
    OFF = 3
    UNKNOWN = 4


class VehicleDoor(IntEnum):
    """carla.VehicleDoor."""

    FL = 0
    FR = 1
    RL = 2
    RR = 3
    ALL = 6


@dataclass(frozen=True)
class VehicleControl:
    """carla.VehicleControl."""

    throttle: float = 0.0
    steer: float = 0.0
    brake: float = 0.0
    hand_brake: bool = False
    reverse: bool = False
    manual_gear_shift: bool = False
    gear: int = 0


@dataclass(frozen=True)
class WalkerControl:
    """carla.WalkerControl: a world-frame direction and a speed in m/s."""

    direction: Vector3D = field(default_factory=Vector3D)
    speed: float = 0.0
    jump: bool = False


@dataclass(frozen=True)
class ActorSpec:
    """What to spawn: a CARLA blueprint id plus attributes (``role_name``, ``color``, ``gender``, ...)."""

    type_id: str
    role_name: str = ""
    attributes: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ActorState:
    """One actor at one tick, as a client sees it.

    ``bounding_box`` has CARLA's semantics: centre in the actor frame and **half** extents.
    ``angular_velocity`` is in deg/s (CARLA's actor API); ``acceleration`` in m/s², world frame.
    ``control`` is the last applied control (the expert forecasts other vehicles from it).
    ``light_state`` is the vehicle light state name (``NONE``, ``Special1|Special2`` for sirens, ...; ``sim.light_state``).
    ``open_doors`` lists the doors that are open. ``is_static``: physics off / parked prop.
    """

    id: int
    type_id: str
    kind: ActorKind
    transform: Transform
    velocity: Vector3D
    angular_velocity: Vector3D
    acceleration: Vector3D
    bounding_box: BoundingBox
    semantic_tags: tuple[int, ...]
    role_name: str = ""
    base_type: str = ""
    attributes: Mapping[str, str] = field(default_factory=dict)
    control: VehicleControl | WalkerControl | None = None
    light_state: str = "NONE"
    open_doors: tuple[VehicleDoor, ...] = ()
    is_static: bool = False
    parent_id: int | None = None

    @property
    def location(self) -> Location:
        """Actor origin in the world."""
        return self.transform.location

    def speed(self) -> float:
        """Norm of the velocity (m/s)."""
        return self.velocity.length()

    def forward_speed(self) -> float:
        """Signed speed along the actor's forward axis (what the speedometer reports)."""
        return self.velocity.dot(self.transform.get_forward_vector())


@dataclass(frozen=True)
class TrafficLightInfo:
    """A traffic light: its state, trigger volume (actor frame, half extents) and the lanes it governs.

    ``stop_waypoints`` are the lane waypoints at the stop line (one per governed lane), like CARLA's
    ``TrafficLight.get_stop_waypoints``; ``affected_lane_waypoints`` like ``get_affected_lane_waypoints``.
    ``level_bbox`` is the light's own (pole head) box in world coordinates, as ``world.get_level_bbs``;
    ``pole_base`` where its pole meets the road (``None``: at ``transform``, which OpenDRIVE's zOffset may lift).
    """

    id: int
    transform: Transform
    state: TrafficLightState
    trigger_volume: BoundingBox
    stop_waypoints: tuple[Waypoint, ...]
    affected_lane_waypoints: tuple[Waypoint, ...]
    group_id: int
    opendrive_id: str
    level_bbox: BoundingBox
    level_bbox_transform: Transform
    elapsed_time: float = 0.0
    frozen: bool = False
    pole_base: Location | None = None


@dataclass(frozen=True)
class TrafficSignInfo:
    """A sign with a trigger volume (``traffic.stop``, ``traffic.yield``, ``traffic.speed_limit.<v>``).

    ``level_bbox`` is the plate in world coordinates; ``pole_base`` as for :class:`TrafficLightInfo`.
    """

    id: int
    type_id: str
    transform: Transform
    trigger_volume: BoundingBox
    level_bbox: BoundingBox
    level_bbox_transform: Transform
    opendrive_id: str = ""
    speed_limit: float | None = None  # km/h for speed-limit signs
    pole_base: Location | None = None


@dataclass(frozen=True)
class CollisionEvent:
    """A collision of ``actor_id`` with ``other_id`` during the last tick (reported for both actors)."""

    frame: int
    actor_id: int
    other_id: int
    other_type_id: str
    location: Location
    normal_impulse: Vector3D = field(default_factory=Vector3D)


@dataclass(frozen=True)
class Snapshot:
    """The world at one tick. ``frame`` counts ticks since the world was loaded; ``timestamp`` is game seconds."""

    frame: int
    timestamp: float
    actors: Mapping[int, ActorState]
    traffic_lights: Mapping[int, TrafficLightInfo]
    traffic_signs: Mapping[int, TrafficSignInfo]
    collisions: Sequence[CollisionEvent]
    weather: WeatherParameters

    def vehicles(self) -> list[ActorState]:
        """All vehicle actors (including the ego)."""
        return [a for a in self.actors.values() if a.kind is ActorKind.VEHICLE]

    def walkers(self) -> list[ActorState]:
        """All walker actors."""
        return [a for a in self.actors.values() if a.kind is ActorKind.WALKER]

    def hero(self) -> ActorState | None:
        """The actor whose ``role_name`` is ``hero`` (the ego), if any."""
        for actor in self.actors.values():
            if actor.role_name == "hero":
                return actor
        return None


#: ``ScenarioHint.extra`` key of the two-way obstacles: 1 once the scenario has switched the wrong-direction test off
#: (LB2.0: 5 s after the ego came within 50 m of the obstacle), 0 before.
OPPOSITE_LANE_OPEN = "opposite_lane_open"


@dataclass(frozen=True)
class ScenarioHint:
    """What a running scenario tells the privileged expert (PDM-Lite reads the same from the scenario runner).

    ``scenario_type`` is the XML type (``Accident``, ``YieldToEmergencyVehicle`` ...); ``first_actor_id`` /
    ``last_actor_id`` are the obstacle actors the expert plans around (same id when there is one);
    ``direction`` is the obstacle side (``left`` / ``right``); ``offset`` is InvadingTurn's lateral offset (m);
    ``paths`` maps the id of an actor that drives a fixed path (a flow's car) to its path ahead, (N, 2) world x, y
    from where it is now (the scenario runner's agents hold the same plan). ``extra`` holds type-specific state,
    e.g. :data:`OPPOSITE_LANE_OPEN` of the two-way obstacles.
    """

    scenario_type: str
    first_actor_id: int | None
    last_actor_id: int | None
    direction: str = "right"
    offset: float | None = None
    extra: Mapping[str, float | int | str] = field(default_factory=dict)
    paths: Mapping[int, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class ImuReading:
    """IMU at the rig's mount: accelerometer m/s² and gyroscope rad/s in sensor axes, compass in radians."""

    accelerometer: tuple[float, float, float]
    gyroscope: tuple[float, float, float]
    compass: float


@dataclass(frozen=True)
class GnssReading:
    """GNSS fix: degrees and metres."""

    latitude: float
    longitude: float
    altitude: float


@dataclass
class SensorData:
    """One capture of the whole Bench2Drive rig at one tick.

    ``cameras`` is keyed by camera folder (``front`` … ``back_right``, ``top_down``). ``lidar`` is (N, 3)
    float32 in the **ego** frame (left-handed, as stored in LAZ), with per-point ``lidar_tags`` (CARLA semantic
    tag) and ``lidar_actor_ids`` (0 for the static map). ``radar`` maps the h5 dataset names to (N, 4)
    [depth, altitude, azimuth, velocity] in each radar's frame.
    """

    frame: int
    cameras: dict[str, CameraFrame]
    lidar: np.ndarray
    lidar_tags: np.ndarray
    lidar_actor_ids: np.ndarray
    radar: dict[str, np.ndarray]
    imu: ImuReading
    gnss: GnssReading
    speed: float
    sensor_transforms: dict[str, Transform] = field(default_factory=dict)


@dataclass(frozen=True)
class RigConfig:
    """Which sensors to run and at what size. Defaults are Bench2Drive's full rig."""

    width: int = 1600
    height: int = 900
    top_down_width: int = 1600
    top_down_height: int = 900
    cameras: tuple[str, ...] = ("front", "front_left", "front_right", "back", "back_left", "back_right", "top_down")
    dense_labels: bool = True  # depth / semantic / instance for the six surround cameras
    float_depth: bool = True  # depth as float32 metres; False: the uint8 metres the depth PNG stores (less read-back)
    # Colour as the JPEG's Y/Cb/Cr planes (CameraFrame.jpeg_planes, no rgb): "off", "on", or "gpu" (hardware only).
    jpeg_planes: str = "off"
    # Depth, semantic and instance handed over as views of their PNG scanlines (where the renderer packs its targets,
    # i.e. on a hardware GPU): the PNG encoder then deflates them without filtering them first.
    png_rows: bool = False
    lidar: bool = True
    lidar_azimuth_steps: int = 1000  # 64 channels × this many rays per sweep (600k pts/s at 10 Hz ≈ 940)
    # LiDAR and radar rays cast by a compute shader (gpu_raycast.py) instead of Embree: "off", "on", or "gpu"
    # (hardware GPU only; on llvmpipe the shader would run on the CPU, slower than Embree).
    gpu_rays: str = "gpu"
    radar: bool = True
    radar_v004_mounts: bool = False


#: Blueprint ids of the physical sensors an agent may mount (:class:`SensorMount`), as CARLA names them.
CAMERA_RGB = "sensor.camera.rgb"
LIDAR_RAY_CAST = "sensor.lidar.ray_cast"
RADAR = "sensor.other.radar"
GNSS = "sensor.other.gnss"
IMU = "sensor.other.imu"
MOUNTABLE_SENSORS: tuple[str, ...] = (CAMERA_RGB, LIDAR_RAY_CAST, RADAR, GNSS, IMU)


@dataclass(frozen=True)
class SensorMount:
    """One physical sensor of an agent's own rig, as the Leaderboard's agent wrapper spawns it.

    ``type_id`` is the CARLA blueprint id (one of :data:`MOUNTABLE_SENSORS`), ``sensor_id`` the key the agent reads
    the data by, ``transform`` the pose relative to the ego actor (CARLA ego frame: x forward, y right, z up;
    degrees) and ``attributes`` the blueprint attributes as strings, exactly as the wrapper sets them:
    ``image_size_x``, ``image_size_y``, ``fov`` for cameras; ``range``, ``rotation_frequency``, ``channels``,
    ``upper_fov``, ``lower_fov``, ``points_per_second``, ``atmosphere_attenuation_rate``, ``dropoff_general_rate``,
    ``dropoff_intensity_limit``, ``dropoff_zero_intensity`` for the LiDAR; ``horizontal_fov``, ``vertical_fov``,
    ``points_per_second``, ``range`` for radars; ``noise_*`` standard deviations and biases for GNSS and IMU.
    """

    sensor_id: str
    type_id: str
    transform: Transform = field(default_factory=Transform)
    attributes: Mapping[str, str] = field(default_factory=dict)

    def attribute(self, name: str, default: float) -> float:
        """A numeric attribute, or ``default`` when the mount does not set it."""
        value = self.attributes.get(name)
        return default if value is None else float(value)


class SimulatorError(RuntimeError):
    """A simulator request that cannot be carried out (bad actor id, blocked spawn point, ...)."""


class SpawnError(SimulatorError):
    """An actor could not be spawned where asked (occupied, off the map, unknown blueprint)."""


@runtime_checkable
class BackgroundTraffic(Protocol):
    """Leaderboard-2.0 style background activity around the ego (expert-and-scenarios.md §3.1).

    The hooks are the scenario-runner's BackgroundManager requests; each takes effect from the next tick.
    """

    def start(self, ego_id: int, route: Sequence[Waypoint]) -> None:
        """Begin managing traffic along ``route`` for the ego."""
        ...

    def stop(self) -> None:
        """Remove every background vehicle and stop spawning."""
        ...

    def leave_space_in_front(self, space: float) -> None:
        """Move or remove background vehicles so that ``space`` metres in front of the ego are free."""
        ...

    def remove_road_lane(self, lane: Waypoint) -> None:
        """Stop spawning on ``lane`` and remove its vehicles."""
        ...

    def leave_crossing_space(self, collision_wp: Waypoint) -> None:
        """Remove the opposite vehicles within 20 m of the lane left of ``collision_wp`` and stop those within 30 m."""
        ...

    def readd_road_lane(self, offset: int) -> None:
        """Spawn again on the ego-relative lane ``offset`` (0 ego lane, 1 right, -1 left)."""
        ...

    def set_max_speed(self, speed: float | None) -> None:
        """Cap background speed (m/s); ``None`` lifts the cap."""
        ...

    def stop_front_vehicles(self) -> None:
        """Brake every background vehicle in front of the ego in its lanes."""
        ...

    def start_front_vehicles(self) -> None:
        """Release the vehicles stopped by :meth:`stop_front_vehicles`."""
        ...

    def stop_back_vehicles(self) -> None:
        """Brake every background vehicle behind the ego."""
        ...

    def start_back_vehicles(self) -> None:
        """Release the vehicles stopped by :meth:`stop_back_vehicles`."""
        ...

    def change_road_behavior(self, spawn_dist: float | None = None, extra_space: float | None = None) -> None:
        """Change the 15 m spawn spacing and the radius offset of the ego's road."""
        ...

    def change_opposite_behavior(self, active: bool | None = None, spawn_dist: float | None = None) -> None:
        """Switch the opposite-direction sources on/off or change their spawn spacing."""
        ...

    def handle_junction_scenario(
        self,
        clear_junction: bool = False,
        clear_ego_entry: bool = False,
        remove_entries: Sequence[Waypoint] = (),
        remove_exits: Sequence[Waypoint] = (),
        stop_entries: bool = False,
        extend_road_exit: float = 0.0,
    ) -> None:
        """Prepare the next junction on the route for a scenario."""
        ...

    def switch_route_sources(self, enabled: bool) -> None:
        """Switch the same-direction road sources on or off."""
        ...

    def vehicle_ids(self) -> list[int]:
        """Ids of the live background vehicles."""
        ...


@runtime_checkable
class Simulator(Protocol):
    """A synchronous 20 Hz world. Deterministic for a given seed on the builtin backend."""

    @property
    def map(self) -> Map:
        """The loaded town."""
        ...

    @property
    def background(self) -> BackgroundTraffic:
        """The background-traffic manager."""
        ...

    def snapshot(self) -> Snapshot:
        """The state after the last tick (or after loading)."""
        ...

    def tick(self) -> Snapshot:
        """Advance by :data:`FIXED_DELTA_SECONDS` and return the new state."""
        ...

    def spawn_actor(self, spec: ActorSpec, transform: Transform, attach_to: int | None = None) -> int:
        """Spawn an actor and return its id; raises :class:`SpawnError` when the place is taken."""
        ...

    def try_spawn_actor(self, spec: ActorSpec, transform: Transform) -> int | None:
        """Spawn an actor, or return ``None`` when the place is taken."""
        ...

    def destroy_actor(self, actor_id: int) -> None:
        """Remove an actor (unknown ids raise :class:`SimulatorError`)."""
        ...

    def apply_control(self, actor_id: int, control: VehicleControl | WalkerControl) -> None:
        """Set the control a vehicle or walker applies from the next tick on."""
        ...

    def set_transform(self, actor_id: int, transform: Transform) -> None:
        """Teleport an actor."""
        ...

    def set_target_velocity(self, actor_id: int, velocity: Vector3D) -> None:
        """Force an actor's velocity (world frame) for the next tick."""
        ...

    def set_simulate_physics(self, actor_id: int, enabled: bool) -> None:
        """Freeze (False) or release an actor."""
        ...

    def set_light_state(self, actor_id: int, light_state: str) -> None:
        """Set a vehicle's light state name (``sim.light_state``; Special1 or Special2: sirens)."""
        ...

    def open_door(self, actor_id: int, door: VehicleDoor) -> None:
        """Open a vehicle door (its collision box widens)."""
        ...

    def set_traffic_light_state(self, light_id: int, state: TrafficLightState, freeze: bool = True) -> None:
        """Force a light's state; a frozen light keeps it until released."""
        ...

    def freeze_traffic_lights(self, frozen: bool) -> None:
        """Stop (True) or resume every light's cycle."""
        ...

    def set_weather(self, weather: WeatherParameters) -> None:
        """Change the weather (affects rendering)."""
        ...

    def attach_rig(self, ego_id: int, config: RigConfig = RigConfig()) -> None:
        """Mount the Bench2Drive sensor rig on the ego."""
        ...

    def read_sensors(self) -> SensorData:
        """Capture every mounted sensor at the current tick."""
        ...

    def attach_sensors(self, ego_id: int, mounts: Sequence[SensorMount]) -> None:
        """Mount an agent's own sensors on the ego (replacing any mounted before)."""
        ...

    def read_attached_sensors(self) -> dict[str, Any]:
        """Every sensor of :meth:`attach_sensors` at the current tick, keyed by sensor id, as CARLA delivers them
        to a Leaderboard agent (``input_data`` values without the frame):

        - ``sensor.camera.rgb``: uint8 (H, W, 4), **BGRA**, alpha 255;
        - ``sensor.lidar.ray_cast``: float32 (N, 4) x, y, z in the sensor frame (x forward, y right, z up) and
          intensity; the part of the sweep covered since the previous tick (half a turn at 10 Hz and 20 ticks/s),
          with CARLA's general and intensity drop-off;
        - ``sensor.other.radar``: float32 (N, 4) depth (m), altitude (rad), azimuth (rad), velocity (m/s);
        - ``sensor.other.gnss``: float64 (3,) latitude, longitude (degrees), altitude (m), noise as attributed;
        - ``sensor.other.imu``: float64 (7,) accelerometer xyz (m/s²), gyroscope xyz (rad/s), compass (rad).
        """
        ...

    def close(self) -> None:
        """Release every resource (GL contexts, worker processes)."""
        ...
