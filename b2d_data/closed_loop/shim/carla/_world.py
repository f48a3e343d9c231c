"""Read-only views of the running route's world with CARLA 0.9.15's client API: World, actors, Map, Waypoint, Client.

Every view reads the route through :func:`b2d_data.closed_loop.bridge.current`: an actor view holds only its id and
reads its state from the bridge's snapshot (the world after the last tick) at each call, as a CARLA actor handle
returns what the last tick reported. Whatever would change the world (spawning, teleporting, applying controls,
ticking, changing settings) raises a RuntimeError that says why: the evaluator owns the clock and the world, and an
agent steers the ego only by returning a ``carla.VehicleControl`` from ``run_step``. Attributes the stand-in does not
offer raise an AttributeError naming the class and attribute.
"""

from __future__ import annotations

import fnmatch
import logging
import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from b2d_data.closed_loop import bridge as _bridge
from b2d_data.format import transform as fmt
from b2d_data.sim.api import FIXED_DELTA_SECONDS, ActorKind, ActorState, TrafficLightInfo
from b2d_data.sim.api import VehicleControl as _SimVehicleControl
from b2d_data.sim.api import WalkerControl as _SimWalkerControl
from b2d_data.sim.light_state import light_bits

from ._convert import (
    from_carla_location,
    to_carla_bbox,
    to_carla_control,
    to_carla_geolocation,
    to_carla_location,
    to_carla_transform,
    to_carla_vector,
    to_carla_walker_control,
    to_carla_weather,
)
from ._geom import BoundingBox, GeoLocation, Location, Transform, Vector3D
from ._types import (
    LaneChange,
    LaneMarkingColor,
    LaneMarkingType,
    LaneType,
    Timestamp,
    TrafficLightState,
    VehicleControl,
    VehicleLightState,
    VehicleWheelLocation,
    WalkerControl,
    WeatherParameters,
    WorldSettings,
)

if TYPE_CHECKING:
    from b2d_data.maps import Map as B2DMap
    from b2d_data.maps import Waypoint as B2DWaypoint

__all__ = [
    "Actor", "ActorList", "ActorSnapshot", "Client", "DebugHelper", "Junction", "LaneMarking", "Map", "TrafficLight",
    "TrafficSign", "Vehicle", "Walker", "Waypoint", "World", "WorldSnapshot",
]  # fmt: skip

log = logging.getLogger(__name__)

#: Why actor mutations are refused.
AGENT_STEERS_BY_CONTROL = (
    "the world is read-only to agents; an agent steers the ego by returning a carla.VehicleControl from run_step "
    "(the evaluator applies it)"
)
#: Why world, client and settings changes are refused.
EVALUATOR_OWNS_WORLD = "the evaluator owns the clock and the world (it ticks the simulator and applies the settings)"

_TOWN_PREFIX = "Carla/Maps/"


def _refusal(cls_name: str, name: str, why: str) -> Callable[..., Any]:
    def refuse(self: Any, *args: Any, **kwargs: Any) -> Any:
        raise RuntimeError(f"carla.{cls_name}.{name}() is not available in b2d-data's closed-loop evaluation: {why}")

    refuse.__name__ = name
    refuse.__doc__ = f"Not available: {why}."
    return refuse


def _refuse(cls: type, names: Iterable[str], why: str) -> None:
    for name in names:
        setattr(cls, name, _refusal(cls.__name__, name, why))


class _View:
    """Base of the views: an unknown attribute says it is not part of the stand-in."""

    __slots__ = ()

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        raise AttributeError(
            f"carla.{type(self).__name__} of b2d-data's CARLA stand-in has no attribute '{name}' "
            "(only the part of CARLA 0.9.15's API that agents read is provided)"
        )


def _route() -> _bridge.RouteBridge:
    return _bridge.current()


# ---------------------------------------------------------------------------------------------------- map views


def _b2d_lane_type(lane_type: Any) -> Any:
    """A carla.LaneType (or an int mask of them) as the maps package's LaneType (CARLA's Any is −2 as int32)."""
    from b2d_data.maps import LaneType as B2DLaneType

    return B2DLaneType(int(lane_type) & 0xFFFFFFFF)


def _carla_lane_type(lane_type: Any) -> LaneType | int:
    value = int(lane_type)
    value = value - (1 << 32) if value >= 1 << 31 else value  # back to CARLA's int32 (Any = −2)
    try:
        return LaneType(value)
    except ValueError:
        return value


class LaneMarking(_View):
    """carla.LaneMarking: type, color, lane_change and width of one side's marking."""

    __slots__ = ("color", "lane_change", "type", "width")

    def __init__(self, marking: Any) -> None:
        self.type = LaneMarkingType(int(marking.type))
        self.color = LaneMarkingColor(int(marking.color))
        self.lane_change = LaneChange(int(marking.lane_change))
        self.width = float(marking.width)

    def __repr__(self) -> str:
        return f"LaneMarking(type={self.type}, color={self.color}, lane_change={self.lane_change}, width={self.width})"


class Waypoint(_View):
    """carla.Waypoint: a view of one of our waypoints (lane-centre pose and lane attributes)."""

    __slots__ = ("_wp",)

    def __init__(self, waypoint: B2DWaypoint) -> None:
        self._wp = waypoint

    @property
    def b2d_waypoint(self) -> B2DWaypoint:
        """The wrapped ``b2d_data.maps.Waypoint`` (for b2d-data's own privileged agents)."""
        return self._wp

    def __repr__(self) -> str:
        return f"Waypoint({self.transform!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Waypoint):
            return NotImplemented
        return self._wp == other._wp

    def __hash__(self) -> int:
        return hash(self._wp)

    @property
    def id(self) -> int:
        """Identifier of (road, section, lane, s)."""
        return self._wp.id

    @property
    def transform(self) -> Transform:
        """Lane-centre pose, yaw along the lane's driving direction (a new object per read, as CARLA)."""
        return to_carla_transform(self._wp.transform)

    @property
    def road_id(self) -> int:
        """OpenDRIVE road id."""
        return self._wp.road_id

    @property
    def section_id(self) -> int:
        """Lane-section index within the road."""
        return self._wp.section_id

    @property
    def lane_id(self) -> int:
        """OpenDRIVE lane id."""
        return self._wp.lane_id

    @property
    def s(self) -> float:
        """OpenDRIVE s along the road."""
        return self._wp.s

    @property
    def lane_width(self) -> float:
        """Lane width at s (m)."""
        return self._wp.lane_width

    @property
    def lane_type(self) -> LaneType | int:
        """The lane's carla.LaneType."""
        return _carla_lane_type(self._wp.lane_type)

    @property
    def is_junction(self) -> bool:
        """Whether the waypoint lies in a junction."""
        return self._wp.is_junction

    @property
    def is_intersection(self) -> bool:
        """Deprecated alias of :attr:`is_junction`."""
        return self._wp.is_junction

    @property
    def junction_id(self) -> int:
        """Junction id, −1 outside junctions."""
        return self._wp.junction_id

    @property
    def lane_change(self) -> LaneChange:
        """Lane changes the markings allow here."""
        return LaneChange(int(self._wp.lane_change))

    @property
    def left_lane_marking(self) -> LaneMarking | None:
        """Marking on the left of the lane (None where the map has none)."""
        mark = self._wp.left_lane_marking
        return None if mark is None else LaneMarking(mark)

    @property
    def right_lane_marking(self) -> LaneMarking | None:
        """Marking on the right of the lane (None where the map has none)."""
        mark = self._wp.right_lane_marking
        return None if mark is None else LaneMarking(mark)

    def next(self, distance: float) -> list[Waypoint]:
        """Waypoints ``distance`` metres ahead (several after a branching lane end)."""
        return [Waypoint(w) for w in self._wp.next(distance)]

    def previous(self, distance: float) -> list[Waypoint]:
        """Waypoints ``distance`` metres behind."""
        return [Waypoint(w) for w in self._wp.previous(distance)]

    def next_until_lane_end(self, distance: float) -> list[Waypoint]:
        """Waypoints every ``distance`` metres to the end of the lane."""
        return [Waypoint(w) for w in self._wp.next_until_lane_end(distance)]

    def previous_until_lane_start(self, distance: float) -> list[Waypoint]:
        """Waypoints every ``distance`` metres back to the start of the lane."""
        return [Waypoint(w) for w in self._wp.previous_until_lane_start(distance)]

    def get_left_lane(self) -> Waypoint | None:
        """The lane on the left of the driving direction, or None."""
        w = self._wp.get_left_lane()
        return None if w is None else Waypoint(w)

    def get_right_lane(self) -> Waypoint | None:
        """The lane on the right of the driving direction, or None."""
        w = self._wp.get_right_lane()
        return None if w is None else Waypoint(w)

    def get_junction(self) -> Junction | None:
        """The junction the waypoint lies in, or None."""
        j = self._wp.get_junction()
        return None if j is None else Junction(j)


class Junction(_View):
    """carla.Junction: id, bounding box (world centre, half extents) and the waypoint pairs of its lanes."""

    __slots__ = ("_junction",)

    def __init__(self, junction: Any) -> None:
        self._junction = junction

    def __repr__(self) -> str:
        return f"Junction(id={self.id})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Junction) and other._junction == self._junction

    def __hash__(self) -> int:
        return hash(self._junction)

    @property
    def id(self) -> int:
        """OpenDRIVE junction id."""
        return self._junction.id

    @property
    def bounding_box(self) -> BoundingBox:
        """Axis-aligned box around the junction, in world coordinates."""
        return to_carla_bbox(self._junction.bounding_box)

    def get_waypoints(self, lane_type: Any = LaneType.Driving) -> list[tuple[Waypoint, Waypoint]]:
        """(entry, exit) waypoints of each lane of ``lane_type`` inside the junction."""
        return [(Waypoint(a), Waypoint(b)) for a, b in self._junction.get_waypoints(_b2d_lane_type(lane_type))]


class Map(_View):
    """carla.Map: a view of the running town (``name`` is ``Carla/Maps/<Town>``)."""

    __slots__ = ("_map", "_xodr")

    def __init__(self, name: str = "", xodr_content: str | None = None) -> None:
        # carla.Map(name, xodr_content) builds a map from OpenDRIVE text; the stand-in does the same with our parser.
        if xodr_content is None:
            raise RuntimeError(
                "carla.Map(name, xodr_content) needs the OpenDRIVE text; use world.get_map() for the running town"
            )
        from b2d_data.maps import load_opendrive

        self._map = load_opendrive(xodr_content, name=name.split("/")[-1] or None)
        self._xodr: str | None = xodr_content

    @classmethod
    def _wrap(cls, b2d_map: B2DMap) -> Map:
        view = object.__new__(cls)
        view._map = b2d_map
        view._xodr = None
        return view

    @property
    def b2d_map(self) -> B2DMap:
        """The wrapped ``b2d_data.maps.Map`` (for b2d-data's own privileged agents)."""
        return self._map

    def __repr__(self) -> str:
        return f"Map(name={self.name})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Map) and other._map is self._map

    def __hash__(self) -> int:
        return id(self._map)

    @property
    def name(self) -> str:
        """``Carla/Maps/<Town>``, so that ``name.split('/')[-1]`` is the town."""
        return _TOWN_PREFIX + str(self._map.name)

    def get_waypoint(
        self, location: Vector3D, project_to_road: bool = True, lane_type: Any = LaneType.Driving
    ) -> Waypoint | None:
        """Waypoint on the nearest lane of ``lane_type`` (None off-road when ``project_to_road`` is False)."""
        w = self._map.get_waypoint(from_carla_location(location), project_to_road, _b2d_lane_type(lane_type))
        return None if w is None else Waypoint(w)

    def get_waypoint_xodr(self, road_id: int, lane_id: int, s: float) -> Waypoint | None:
        """Waypoint at OpenDRIVE (road, lane, s), or None."""
        w = self._map.get_waypoint_xodr(int(road_id), int(lane_id), float(s))
        return None if w is None else Waypoint(w)

    def generate_waypoints(self, distance: float) -> list[Waypoint]:
        """Waypoints every ``distance`` metres on every driving lane."""
        return [Waypoint(w) for w in self._map.generate_waypoints(distance)]

    def get_topology(self) -> list[tuple[Waypoint, Waypoint]]:
        """(segment start, successor start) pairs of the driving lanes."""
        return [(Waypoint(a), Waypoint(b)) for a, b in self._map.get_topology()]

    def get_spawn_points(self) -> list[Transform]:
        """Spawn poses on driving lanes."""
        return [to_carla_transform(t) for t in self._map.get_spawn_points()]

    def transform_to_geolocation(self, location: Vector3D) -> GeoLocation:
        """CARLA's GNSS projection of a world location."""
        return to_carla_geolocation(self._map.transform_to_geolocation(from_carla_location(location)))

    def to_opendrive(self) -> str:
        """The town's OpenDRIVE text."""
        if self._xodr is None:
            path = getattr(self._map, "path", None)
            if path is None:
                raise RuntimeError(f"map {self._map.name} was not loaded from a file; its OpenDRIVE text is unknown")
            with open(path, encoding="utf-8") as f:
                self._xodr = f.read()
        return self._xodr

    def save_to_disk(self, path: str) -> None:
        """Write the OpenDRIVE text to ``path``."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.to_opendrive())

    def get_crosswalks(self) -> list[Location]:
        """Crosswalk outline points; each polygon is closed by repeating its first point (CARLA's layout)."""
        out: list[Location] = []
        for crosswalk in self._map.crosswalks():
            points = [Location(float(p[0]), float(p[1]), float(p[2])) for p in np.asarray(crosswalk.polygon)]
            if points:
                out.extend(points + [Location(points[0])])
        return out


_map_cache: tuple[Any, Map] | None = None


def map_view(b2d_map: B2DMap) -> Map:
    """The (cached) carla.Map view of one of our maps."""
    global _map_cache
    if _map_cache is None or _map_cache[0] is not b2d_map:
        _map_cache = (b2d_map, Map._wrap(b2d_map))
    return _map_cache[1]


# -------------------------------------------------------------------------------------------------- actor views

_DEFAULT_TYPE_IDS = {ActorKind.TRAFFIC_LIGHT: "traffic.traffic_light", ActorKind.TRAFFIC_SIGN: "traffic.unknown"}


def _inside_volume(volume: fmt.BoundingBox, owner: fmt.Transform, point: fmt.Location, z_margin: float) -> bool:
    """Whether a world point lies in a trigger volume (placed by the owner's pose and its own rotation, as the
    simulator's overlap test sees it; x, y within the half extents, z with a margin)."""
    local = owner.inverse_transform_points(np.array([[point.x, point.y, point.z]]))[0]
    box_frame = fmt.Transform(volume.location, volume.rotation)
    d = box_frame.inverse_transform_points(local[None, :])[0]
    e = volume.extent
    return abs(d[0]) <= e.x and abs(d[1]) <= e.y and abs(d[2]) <= e.z + z_margin


class Actor(_View):
    """carla.Actor: a handle holding an id; every read is live from the last tick's snapshot."""

    __slots__ = ("_id", "_last")

    def __init__(self, actor_id: int) -> None:
        self._id = int(actor_id)
        self._last: ActorState | None = None

    # -- state
    def _state(self) -> ActorState:
        state = _route().snapshot.actors.get(self._id)
        if state is not None:
            self._last = state
            return state
        if self._last is not None:
            return self._last  # a destroyed actor keeps reporting what the last tick it lived in said
        raise RuntimeError(f"actor {self._id} does not exist in the running world")

    def __repr__(self) -> str:
        try:
            type_id = self.type_id
        except RuntimeError:
            type_id = "?"
        return f"{type(self).__name__}(id={self._id}, type={type_id})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Actor):
            return NotImplemented
        return self._id == other._id

    def __hash__(self) -> int:
        return hash(self._id)

    @property
    def id(self) -> int:
        """Actor id (unique in the episode)."""
        return self._id

    @property
    def type_id(self) -> str:
        """Blueprint id, e.g. ``vehicle.lincoln.mkz_2020``."""
        return self._state().type_id

    @property
    def attributes(self) -> dict[str, str]:
        """Blueprint attributes as strings (``role_name`` always present: ``hero`` for the ego)."""
        state = self._state()
        attributes = {str(k): str(v) for k, v in state.attributes.items()}
        attributes.setdefault("role_name", state.role_name)
        return attributes

    @property
    def is_alive(self) -> bool:
        """Whether the actor is still in the world."""
        snap = _route().snapshot
        return self._id in snap.actors or self._id in snap.traffic_lights or self._id in snap.traffic_signs

    @property
    def is_active(self) -> bool:
        """Always True (no dormant actors in the builtin world)."""
        return self.is_alive

    @property
    def is_dormant(self) -> bool:
        """Always False."""
        return False

    @property
    def semantic_tags(self) -> list[int]:
        """CityObjectLabel ids of the actor's mesh."""
        return [int(t) for t in self._state().semantic_tags]

    @property
    def parent(self) -> Actor | None:
        """The actor this one is attached to, or None."""
        parent_id = self._state().parent_id
        return None if parent_id is None else actor_view(parent_id)

    @property
    def bounding_box(self) -> BoundingBox:
        """Box in the actor frame with half extents."""
        return to_carla_bbox(self._state().bounding_box)

    def get_world(self) -> World:
        """The world view."""
        return World()

    def get_transform(self) -> Transform:
        """World pose after the last tick."""
        return to_carla_transform(self._state().transform)

    def get_location(self) -> Location:
        """World location after the last tick."""
        return to_carla_location(self._state().transform.location)

    def get_velocity(self) -> Vector3D:
        """World velocity (m/s)."""
        return to_carla_vector(self._state().velocity)

    def get_angular_velocity(self) -> Vector3D:
        """Angular velocity (deg/s), as CARLA reports it."""
        return to_carla_vector(self._state().angular_velocity)

    def get_acceleration(self) -> Vector3D:
        """World acceleration (m/s²)."""
        return to_carla_vector(self._state().acceleration)


_refuse(Actor, ("destroy", "set_transform", "set_location", "set_target_velocity", "set_target_angular_velocity",
                "set_simulate_physics", "set_enable_gravity", "set_collisions", "add_impulse", "add_force",
                "add_torque", "add_angular_impulse", "enable_constant_velocity", "disable_constant_velocity",
                "set_actor_dead"), AGENT_STEERS_BY_CONTROL)  # fmt: skip


class Vehicle(Actor):
    """carla.Vehicle."""

    __slots__ = ()

    def get_control(self) -> VehicleControl:
        """The control applied at the last tick."""
        control = self._state().control
        return to_carla_control(control if isinstance(control, _SimVehicleControl) else None)

    def get_light_state(self) -> VehicleLightState:
        """The lights that are on."""
        return VehicleLightState(light_bits(self._state().light_state))

    def get_traffic_light(self) -> TrafficLight | None:
        """The traffic light whose trigger volume the vehicle is in, or None."""
        state = self._state()
        margin = 2.0 * state.bounding_box.extent.z + 1.0
        for info in _route().snapshot.traffic_lights.values():
            if _inside_volume(info.trigger_volume, info.transform, state.transform.location, margin):
                return TrafficLight(info.id)
        return None

    def get_traffic_light_state(self) -> TrafficLightState:
        """State of the light affecting the vehicle; Green when none does (CARLA's rule)."""
        light = self.get_traffic_light()
        return TrafficLightState.Green if light is None else light.state

    def is_at_traffic_light(self) -> bool:
        """Whether a traffic light affects the vehicle (it is in the light's trigger volume)."""
        return self.get_traffic_light() is not None

    def get_speed_limit(self) -> float:
        """Speed limit (km/h) of the lane the vehicle is on (50 off the road network)."""
        route = _route()
        waypoint = route.map.get_waypoint(self._state().transform.location)
        return 50.0 if waypoint is None else float(route.map.speed_limit(waypoint))

    def get_wheel_steer_angle(self, wheel_location: Any) -> float:
        """Steering angle of a wheel in degrees (front wheels from the last control; rear wheels 0)."""
        if int(wheel_location) not in (VehicleWheelLocation.FL_Wheel, VehicleWheelLocation.FR_Wheel):
            return 0.0
        from b2d_data.sim import blueprints

        try:
            geometry = blueprints.find(self.type_id).geometry
        except blueprints.UnknownBlueprintError:
            geometry = None
        steer_to_wheel = (geometry or blueprints.BicycleGeometry()).steer_to_wheel
        return math.degrees(float(self.get_control().steer) * steer_to_wheel)

    def get_failure_state(self) -> Any:
        """Always NONE (the builtin world does not model failures)."""
        from ._types import VehicleFailureState

        return VehicleFailureState.NONE


_refuse(Vehicle, ("apply_control", "apply_ackermann_control", "apply_physics_control", "set_autopilot",
                  "set_light_state", "open_door", "close_door", "enable_carsim", "use_carsim_road",
                  "enable_chrono_physics", "show_debug_telemetry", "set_wheel_steer_direction",
                  "apply_ackermann_controller_settings"), AGENT_STEERS_BY_CONTROL)  # fmt: skip


class Walker(Actor):
    """carla.Walker."""

    __slots__ = ()

    def get_control(self) -> WalkerControl:
        """The control applied at the last tick."""
        control = self._state().control
        return to_carla_walker_control(control if isinstance(control, _SimWalkerControl) else None)


_refuse(Walker, ("apply_control", "set_bones", "blend_pose", "show_pose", "hide_pose"), AGENT_STEERS_BY_CONTROL)


class TrafficSign(Actor):
    """carla.TrafficSign (stop, yield and speed-limit signs)."""

    __slots__ = ()

    def _state(self) -> ActorState:
        snap = _route().snapshot
        state = snap.actors.get(self._id)
        if state is None and self._id in snap.traffic_signs:
            info = snap.traffic_signs[self._id]
            state = _furniture_state(self._id, info.type_id, ActorKind.TRAFFIC_SIGN, info.transform, info.level_bbox)
        if state is not None:
            self._last = state
            return state
        return super()._state()

    @property
    def trigger_volume(self) -> BoundingBox:
        """Trigger box in the sign's frame (half extents)."""
        info = _route().snapshot.traffic_signs.get(self._id)
        if info is None:
            raise RuntimeError(f"traffic sign {self._id} does not exist in the running world")
        return to_carla_bbox(info.trigger_volume)

    def get_opendrive_id(self) -> str:
        """The OpenDRIVE signal id."""
        info = _route().snapshot.traffic_signs.get(self._id)
        return "" if info is None else info.opendrive_id


class TrafficLight(TrafficSign):
    """carla.TrafficLight: state, trigger volume, stop and lane waypoints, its group."""

    __slots__ = ()

    def _info(self) -> TrafficLightInfo:
        info = _route().snapshot.traffic_lights.get(self._id)
        if info is None:
            raise RuntimeError(f"traffic light {self._id} does not exist in the running world")
        return info

    def _state(self) -> ActorState:
        snap = _route().snapshot
        state = snap.actors.get(self._id)
        if state is None and self._id in snap.traffic_lights:
            info = snap.traffic_lights[self._id]
            state = _furniture_state(self._id, _DEFAULT_TYPE_IDS[ActorKind.TRAFFIC_LIGHT], ActorKind.TRAFFIC_LIGHT,
                                     info.transform, info.level_bbox)  # fmt: skip
        if state is not None:
            self._last = state
            return state
        return Actor._state(self)

    @property
    def state(self) -> TrafficLightState:
        """Current state."""
        return TrafficLightState(int(self._info().state))

    def get_state(self) -> TrafficLightState:
        """Current state."""
        return self.state

    @property
    def trigger_volume(self) -> BoundingBox:
        """Trigger box in the light's frame (half extents)."""
        return to_carla_bbox(self._info().trigger_volume)

    def get_opendrive_id(self) -> str:
        """The OpenDRIVE signal id."""
        return self._info().opendrive_id

    def get_elapsed_time(self) -> float:
        """Seconds since the light entered its current state."""
        return float(self._info().elapsed_time)

    def is_frozen(self) -> bool:
        """Whether the light's cycle is frozen."""
        return bool(self._info().frozen)

    def get_stop_waypoints(self) -> list[Waypoint]:
        """Lane waypoints at the stop line, one per governed lane."""
        return [Waypoint(w) for w in self._info().stop_waypoints]

    def get_affected_lane_waypoints(self) -> list[Waypoint]:
        """Waypoints of the lanes the light governs."""
        return [Waypoint(w) for w in self._info().affected_lane_waypoints]

    def get_group_traffic_lights(self) -> list[TrafficLight]:
        """Every light of the same group (junction), this one included."""
        group = self._info().group_id
        lights = _route().snapshot.traffic_lights.values()
        return [TrafficLight(i.id) for i in sorted(lights, key=lambda i: i.id) if i.group_id == group]

    def get_light_boxes(self) -> list[BoundingBox]:
        """The light's head box in world coordinates."""
        return [to_carla_bbox(self._info().level_bbox)]


_refuse(TrafficLight, ("set_state", "set_green_time", "set_yellow_time", "set_red_time", "freeze", "reset_group"),
        EVALUATOR_OWNS_WORLD)  # fmt: skip


def _furniture_state(
    actor_id: int, type_id: str, kind: ActorKind, transform: fmt.Transform, box: fmt.BoundingBox
) -> ActorState:
    """An ActorState for a light or sign a simulator reports only among its lights and signs."""
    zero = fmt.Vector3D()
    local_box = fmt.BoundingBox(fmt.Location(0.0, 0.0, box.extent.z), box.extent)
    tag = 7 if kind is ActorKind.TRAFFIC_LIGHT else 8
    return ActorState(id=actor_id, type_id=type_id, kind=kind, transform=transform, velocity=zero,
                      angular_velocity=zero, acceleration=zero, bounding_box=local_box, semantic_tags=(tag,),
                      is_static=True)  # fmt: skip


_VIEW_BY_KIND: dict[ActorKind, type[Actor]] = {
    ActorKind.VEHICLE: Vehicle,
    ActorKind.WALKER: Walker,
    ActorKind.TRAFFIC_LIGHT: TrafficLight,
    ActorKind.TRAFFIC_SIGN: TrafficSign,
    ActorKind.PROP: Actor,
}


def actor_view(actor_id: int) -> Actor | None:
    """The view of an actor of the running world (the class by its kind), or None when it does not exist."""
    snap = _route().snapshot
    state = snap.actors.get(actor_id)
    if state is not None:
        view = _VIEW_BY_KIND.get(state.kind, Actor)(actor_id)
        view._last = state
        return view
    if actor_id in snap.traffic_lights:
        return TrafficLight(actor_id)
    if actor_id in snap.traffic_signs:
        return TrafficSign(actor_id)
    return None


class ActorList(_View):
    """carla.ActorList: iterable, sized, indexable, with ``filter(wildcard)`` on type_id and ``find(id)``."""

    __slots__ = ("_actors",)

    def __init__(self, actors: Iterable[Actor] = ()) -> None:
        self._actors = list(actors)

    def __iter__(self) -> Iterator[Actor]:
        return iter(self._actors)

    def __len__(self) -> int:
        return len(self._actors)

    def __getitem__(self, index: int | slice) -> Any:
        if isinstance(index, slice):
            return ActorList(self._actors[index])
        return self._actors[index]

    def __contains__(self, actor: object) -> bool:
        return actor in self._actors

    def __repr__(self) -> str:
        return "ActorList([" + ", ".join(repr(a) for a in self._actors) + "])"

    def filter(self, wildcard_pattern: str) -> ActorList:
        """The actors whose type_id matches the shell-style pattern (``vehicle.*``, ``*traffic_light*``)."""
        return ActorList(a for a in self._actors if fnmatch.fnmatchcase(a.type_id, wildcard_pattern))

    def find(self, actor_id: int) -> Actor | None:
        """The actor with this id, or None."""
        for actor in self._actors:
            if actor.id == actor_id:
                return actor
        return None


# ------------------------------------------------------------------------------------------- snapshots and world


class ActorSnapshot(_View):
    """carla.ActorSnapshot: one actor's state frozen at a world snapshot."""

    __slots__ = ("_state",)

    def __init__(self, state: ActorState) -> None:
        self._state = state

    @property
    def id(self) -> int:
        """Actor id."""
        return self._state.id

    def get_transform(self) -> Transform:
        """World pose."""
        return to_carla_transform(self._state.transform)

    def get_velocity(self) -> Vector3D:
        """World velocity (m/s)."""
        return to_carla_vector(self._state.velocity)

    def get_angular_velocity(self) -> Vector3D:
        """Angular velocity (deg/s)."""
        return to_carla_vector(self._state.angular_velocity)

    def get_acceleration(self) -> Vector3D:
        """World acceleration (m/s²)."""
        return to_carla_vector(self._state.acceleration)


class WorldSnapshot(_View):
    """carla.WorldSnapshot: the world after one tick, frozen."""

    __slots__ = ("_episode", "_snapshot", "timestamp")

    def __init__(self, snapshot: Any, episode: int = 0) -> None:
        self._snapshot = snapshot
        self._episode = episode
        self.timestamp = Timestamp(snapshot.frame, snapshot.timestamp, FIXED_DELTA_SECONDS, time.time())

    @property
    def id(self) -> int:
        """Episode id."""
        return self._episode

    @property
    def frame(self) -> int:
        """Frame number."""
        return int(self._snapshot.frame)

    def find(self, actor_id: int) -> ActorSnapshot | None:
        """The actor's snapshot, or None."""
        state = self._snapshot.actors.get(actor_id)
        return None if state is None else ActorSnapshot(state)

    def has_actor(self, actor_id: int) -> bool:
        """Whether the actor is in the snapshot."""
        return actor_id in self._snapshot.actors

    def __iter__(self) -> Iterator[ActorSnapshot]:
        return (ActorSnapshot(s) for s in self._snapshot.actors.values())

    def __len__(self) -> int:
        return len(self._snapshot.actors)


class DebugHelper(_View):
    """carla.DebugHelper: drawing does nothing (there is no viewer)."""

    __slots__ = ()

    def _ignore(self, *args: Any, **kwargs: Any) -> None:
        return None

    draw_point = draw_line = draw_arrow = draw_box = draw_string = _ignore
    draw_hud_point = draw_hud_line = draw_hud_arrow = draw_hud_box = _ignore


class Spectator(_View):
    """The spectator: a harmless camera pose nobody renders (moving it is allowed and does nothing)."""

    __slots__ = ("_transform",)

    def __init__(self) -> None:
        self._transform = Transform()

    id = 0
    type_id = "spectator"
    is_alive = True

    @property
    def attributes(self) -> dict[str, str]:
        """No blueprint attributes."""
        return {}

    def get_transform(self) -> Transform:
        """The last pose set."""
        return Transform(self._transform.location, self._transform.rotation)

    def get_location(self) -> Location:
        """The last location set."""
        return Location(self._transform.location)

    def set_transform(self, transform: Transform) -> None:
        """Remember the pose (nothing is rendered from it)."""
        self._transform = Transform(transform.location, transform.rotation)

    def set_location(self, location: Vector3D) -> None:
        """Remember the location."""
        self._transform = Transform(location, self._transform.rotation)


_spectator = Spectator()


def _episode_id(route: _bridge.RouteBridge) -> int:
    return id(route.sim) & 0x7FFFFFFF


class World(_View):
    """carla.World: the running route's world (read-only)."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f"World(id={self.id})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, World)

    def __hash__(self) -> int:
        return hash("b2d-world")

    @property
    def id(self) -> int:
        """Episode id."""
        return _episode_id(_route())

    @property
    def debug(self) -> DebugHelper:
        """A debug helper whose drawing does nothing."""
        return DebugHelper()

    def get_actors(self, actor_ids: Sequence[int] | None = None) -> ActorList:
        """Every actor (vehicles, walkers, props, traffic lights and signs), or those with the given ids."""
        snap = _route().snapshot
        ids = list(snap.actors)
        ids += [i for i in snap.traffic_lights if i not in snap.actors]
        ids += [i for i in snap.traffic_signs if i not in snap.actors]
        if actor_ids is not None:
            wanted = {int(i) for i in actor_ids}
            ids = [i for i in ids if i in wanted]
        return ActorList(view for view in (actor_view(i) for i in ids) if view is not None)

    def get_actor(self, actor_id: int) -> Actor | None:
        """The actor with this id, or None."""
        return actor_view(int(actor_id))

    def get_map(self) -> Map:
        """The town."""
        return map_view(_route().map)

    def get_settings(self) -> WorldSettings:
        """Synchronous mode at 20 Hz, as the Leaderboard runs."""
        return WorldSettings(synchronous_mode=True, no_rendering_mode=False, fixed_delta_seconds=FIXED_DELTA_SECONDS)

    def get_snapshot(self) -> WorldSnapshot:
        """The world after the last tick."""
        route = _route()
        return WorldSnapshot(route.snapshot, _episode_id(route))

    def get_weather(self) -> WeatherParameters:
        """The current weather."""
        return to_carla_weather(_route().snapshot.weather)

    def get_spectator(self) -> Spectator:
        """A spectator pose that renders nothing."""
        return _spectator


_refuse(World, ("tick", "wait_for_tick", "on_tick", "remove_on_tick", "apply_settings", "spawn_actor",
                "try_spawn_actor", "set_weather", "get_blueprint_library", "load_map_layer", "unload_map_layer",
                "freeze_all_traffic_lights", "reset_all_traffic_lights", "set_pedestrians_cross_factor",
                "set_pedestrians_seed", "enable_environment_objects", "set_annotations_traverse_translucency"),
        EVALUATOR_OWNS_WORLD)  # fmt: skip


class Client(_View):
    """carla.Client: constructing works and ``get_world()`` gives the running world; server calls are refused."""

    __slots__ = ("_timeout", "host", "port", "worker_threads")

    def __init__(self, host: str = "127.0.0.1", port: int = 2000, worker_threads: int = 0) -> None:
        self.host = host
        self.port = int(port)
        self.worker_threads = int(worker_threads)
        self._timeout = 5.0

    def __repr__(self) -> str:
        return f"Client(host={self.host!r}, port={self.port})"

    def set_timeout(self, seconds: float) -> None:
        """Accepted and ignored (nothing goes over a network)."""
        self._timeout = float(seconds)

    def get_client_version(self) -> str:
        """``0.9.15``."""
        return "0.9.15"

    def get_server_version(self) -> str:
        """``0.9.15``."""
        return "0.9.15"

    def get_world(self) -> World:
        """The running route's world."""
        _route()  # fail here, with the bridge's message, when no route runs
        return World()

    def get_available_maps(self) -> list[str]:
        """The running town only."""
        return ["/Game/" + World().get_map().name]


_refuse(Client, ("load_world", "reload_world", "generate_opendrive_world", "load_world_if_different",
                 "get_trafficmanager", "get_instance_tm", "apply_batch", "apply_batch_sync", "start_recorder",
                 "stop_recorder", "replay_file", "show_recorder_file_info", "show_recorder_collisions",
                 "show_recorder_actors_blocked", "stop_replayer", "set_replayer_time_factor",
                 "set_replayer_ignore_hero", "set_replayer_ignore_spectator", "set_files_base_folder",
                 "get_required_files", "request_file"), EVALUATOR_OWNS_WORLD)  # fmt: skip
