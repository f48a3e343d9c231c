"""Leaderboard-2.0-style background traffic around the ego (expert-and-scenarios.md §3.1).

Sources, as in the LB2.0 BackgroundBehavior:

- **road**: on every same-direction driving lane of the ego's road, keep ``front`` vehicles ahead and
  ``back`` vehicles behind, spawned ``spawn_dist`` (15 m) apart and never within 20 m of the ego. Vehicles
  ahead drive normally closer than the min radius ``2·spawn_dist + 1.7·v_ego + extra_space``, ramp their speed
  down linearly to 0 at the max radius ``3·spawn_dist + 1.7·v_ego + extra_space``, and stop beyond it;
- **opposite**: a source on each opposite lane 80 m ahead of the ego along the route spawns every 40 m; these
  vehicles ignore lights and stop signs;
- **junctions**: a junction on the route is activated when the ego is within 30 m + 1.5 s × its speed of it;
  each entry lane (except the ego's) gets, with 80 % probability, a source 40 m before the junction (at least
  15 m), spawning every 15 m up to 6 live vehicles; it is deactivated once the ego has left it.

Every vehicle is a TM-like car (``role_name="background"``, blueprints with lights and no special type) driven
by :class:`~b2d_data.sim.builtin.lane_following.TrafficDriver`: IDM with a 10 m gap, the lane speed limit
(capped at 90 km/h and by :meth:`set_max_speed`, slower in bends), no lane changes, a 0.1 m lane offset,
stopping at red and yellow lights and at stop signs, first-come junction reservations in which other vehicles
(the ego) on a junction's lanes, or about to drive onto them, hold every lane, so background traffic gives way
to them, and no entering a junction whose exit is full (don't block the box). A road vehicle that drives
into a junction is "detached" from the ego's road and no longer held back by the radius ramp (LB2.0 hands such
vehicles over to the junction too). Vehicles far behind, far away or stuck for 30 s (out of the ego's way)
are removed (recycled). New vehicles enter rolling, no faster than lets them stop behind whatever is ahead.
Every random choice comes from the generator the world hands in.

Differences from LB2.0 worth knowing: speed follows each vehicle's own lane limit (LB2.0 uses the ego lane's);
LeaveSpaceInFront removes the vehicles in the way (LB2.0 may move them); parked cars fill parking lanes of the
map (LB2.0 reads per-town slot files).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from b2d_data.format.transform import Location, Rotation, Transform, Vector3D
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorKind, ActorSpec, SimulatorError, Snapshot, SpawnError
from b2d_data.sim.builtin.lane_following import (
    ANY_LANE,
    PATH_STEP,
    DriverOutput,
    DrivingAgent,
    LanePath,
    TrafficDriver,
)

if TYPE_CHECKING:
    from b2d_data.maps import Waypoint
    from b2d_data.sim.builtin.world import BuiltinSimulator

log = logging.getLogger(__name__)

ROLE_NAME = "background"
#: A car is born only where every car behind it in its lane can close their speed difference at this rate (m/s²)
#: before it is this close (m): the same comfortable rate the newborn's own speed is bounded by.
BIRTH_DECEL, BIRTH_GAP = 3.0, 10.0
#: Within this distance (m) of its route point the ego counts as on the route's lane for lane offsets (one lane over).
ROUTE_LANE_TOLERANCE = 5.0
#: A background car that has stood this many ticks (2 s) in a lane narrower than 2.25 m is removed.
NARROW_LANE_TICKS = 40


@dataclass
class BackgroundSettings:
    """The knobs of §3.1 (distances in m, speeds in km/h)."""

    spawn_dist: float = 15.0
    extra_space: float = 0.0
    front_vehicles: int = 2
    back_vehicles: int = 2
    min_spawn_distance: float = 20.0
    radius_speed_factor: float = 1.7  # s: the radii grow by this × ego speed
    opposite_active: bool = True
    opposite_source_dist: float = 80.0
    opposite_spawn_dist: float = 40.0
    junction_activation: float = 30.0
    junction_activation_time: float = 1.5  # s × ego speed added to the activation distance
    junction_source_dist: float = 40.0
    junction_min_source_dist: float = 15.0
    junction_source_probability: float = 0.8
    junction_max_vehicles: int = 6
    junction_spawn_dist: float = 15.0
    max_speed_kmh: float = 90.0
    speed_percentage: float = 100.0
    lane_offset: float = 0.1
    min_lane_width: float = 2.25
    min_spawn_clearance: float = 8.0  # centre distance to any vehicle at a spawn point
    manage_every: int = 5  # ticks between population updates
    stuck_timeout: float = 30.0  # s standing still (not for a light or a stop order) before recycling


@dataclass
class _Newborn:
    """A car spawned since the last snapshot: where, heading (deg) and the speed it was given (m/s)."""

    location: Location
    yaw: float
    speed: float


@dataclass
class _Vehicle:
    id: int
    source: str  # "road" | "opposite" | "junction" | "detached" (a road vehicle that went into a junction)
    agent: DrivingAgent
    source_key: tuple[Any, ...] = ()
    junction_id: int | None = None
    still_ticks: int = 0
    narrow_ticks: int = 0  # ticks standing in a lane narrower than a car (a taper): it will not move again
    location: Location = field(default_factory=Location)  # last known (spawn point until the next tick)
    lane_offset: int = 0  # road vehicles: the ego-relative lane they were spawned on (LB2.0 keys them so)


@dataclass
class _JunctionSource:
    key: tuple[Any, ...]
    waypoint: Any
    lane_key: tuple[int, int]
    live: list[int] = field(default_factory=list)
    last_id: int | None = None


@dataclass
class _RouteJunction:
    junction_id: int
    entry_index: int  # first route index inside the junction
    exit_index: int  # first route index after it
    active: bool = False
    done: bool = False
    sources: list[_JunctionSource] = field(default_factory=list)
    removed_entries: set[tuple[int, int]] = field(default_factory=set)
    removed_exits: set[tuple[int, int]] = field(default_factory=set)
    stop_entries: bool = False
    extend_exit: float = 0.0
    clear_junction: bool = False
    clear_ego_entry: bool = False
    lane_keys: tuple[tuple[int, int, int], ...] = ()  # the route's lanes through it (road, section, lane)


class BackgroundTrafficManager:
    """Implements :class:`~b2d_data.sim.api.BackgroundTraffic` on the builtin world."""

    def __init__(self, world: BuiltinSimulator, rng: np.random.Generator,
                 settings: BackgroundSettings | None = None) -> None:
        self._world = world
        self._map = world.map
        self._rng = rng
        self._defaults = settings or BackgroundSettings()
        self.settings = dataclasses.replace(self._defaults)
        self.driver = TrafficDriver(self._map)
        self._vehicles: dict[int, _Vehicle] = {}
        self._ego_id: int | None = None
        self._route: list[Waypoint] = []
        self._route_xy = np.zeros((0, 2))
        self._route_s = np.zeros(0)
        self._ego_index = 0
        self._junctions: list[_RouteJunction] = []
        self._removed_offsets: set[int] = set()
        # the removed lanes themselves: road vehicles of the ego's lane follow the route, which may change into one
        self._removed_lanes: set[tuple[int, int]] = set()
        self._max_speed: float | None = None
        # StopFront/BackVehicles: a request is taken at the next tick, where the vehicles it stops are picked;
        # those stay stopped until released (LB2.0 stops the road vehicles of that moment, not later arrivals)
        self._stop_front = False
        self._stop_back = False
        self._stopped: dict[str, set[int]] = {"front": set(), "back": set()}
        self._road_sources = True
        self._front_clear_until = -math.inf  # route s before which no road vehicle is spawned ahead
        self._opposite_last: dict[int, int] = {}
        self._tick = 0
        self._speed_limits: dict[tuple[int, int, int], float] = {}
        self._parked: list[int] = []
        self._pending: list[_Newborn] = []  # spawned since the last tick (not yet in the snapshot)
        self._handed_in: set[int] = set()  # other vehicles handed to the arbiter as junction holders last tick
        self._started = False
        #: The driver's decision per vehicle at the last tick (control, acceleration, reason, leader).
        self.last_outputs: dict[int, DriverOutput] = {}

    # -- BackgroundTraffic protocol ----------------------------------------------------------------------
    def start(self, ego_id: int, route: Sequence[Waypoint]) -> None:
        """Begin managing traffic along ``route`` (1 m leaderboard waypoints) for the ego.

        The first vehicles appear at once if the ego is already in the last snapshot, else at the next tick.
        """
        if ego_id not in self._world.actor_ids():
            raise SimulatorError(f"background traffic: no ego actor with id {ego_id}")
        if len(route) < 2:
            raise SimulatorError("background traffic needs a route of at least two waypoints")
        self._ego_id = ego_id
        self._route = list(route)
        # a new route starts from the default behaviour
        self.settings = dataclasses.replace(self._defaults)
        self._removed_offsets.clear()
        self._removed_lanes.clear()
        self._max_speed = None
        self._stop_front = self._stop_back = False
        self._stopped = {"front": set(), "back": set()}
        self._road_sources = True
        self._front_clear_until = -math.inf
        self._opposite_last.clear()
        xy = np.array([[wp.transform.location.x, wp.transform.location.y] for wp in self._route])
        self._route_xy = xy
        self._route_s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        self._junctions = _route_junctions(self._route)
        self._started = False
        snapshot = self._world.snapshot()
        if ego_id in snapshot.actors:
            self._begin(snapshot)
        log.info("background traffic for ego %d: %d junctions on a %.0f m route", ego_id, len(self._junctions),
                 self._route_s[-1])

    def _begin(self, snapshot: Snapshot) -> None:
        self._ego_index = self._nearest_route_index(snapshot, full=True)
        self._started = True
        self._manage(snapshot)

    def stop(self) -> None:
        """Remove every background vehicle and stop spawning."""
        for vid in list(self._vehicles):
            self._destroy(vid)
        self._ego_id = None

    def leave_space_in_front(self, space: float) -> None:
        """Remove background vehicles on the route within ``space`` m ahead of the ego; spawn beyond it only."""
        snapshot = self._world.snapshot()
        if self._ego_id is None or not self._started:
            return
        ego_s = float(self._route_s[self._ego_index])
        self._front_clear_until = max(self._front_clear_until, ego_s + float(space))
        for vid in self._on_route(snapshot, ego_s - 1.0, ego_s + float(space)):
            self._destroy(vid)

    def remove_road_lane(self, lane: Waypoint) -> None:
        """Stop spawning on ``lane`` (stored as an offset from the ego lane) and remove its vehicles."""
        snapshot = self._world.snapshot()
        if self._ego_id is None or self._ego_id not in snapshot.actors:
            raise SimulatorError("remove_road_lane: start() the background traffic with a ticked ego first")
        offset = self._lane_offset_of(snapshot, lane)
        if offset is not None:
            self._removed_offsets.add(offset)
        key = (lane.road_id, lane.lane_id)
        self._removed_lanes.add(key)
        for vid, veh in list(self._vehicles.items()):
            wp = veh.agent.path.waypoints[0]
            on_lane = (wp.road_id, wp.lane_id) == key
            if on_lane or (offset is not None and veh.source == "road" and veh.lane_offset == offset):
                self._destroy(vid)

    def leave_crossing_space(self, collision_wp: Waypoint) -> None:
        """Remove the opposite vehicles within 20 m of the lane left of ``collision_wp`` and stop those within 30 m.

        BackgroundActivity's ``_leave_crossing_space`` (LeaveCrossingSpace): distances are to the point of the lane
        left of ``collision_wp``; a stopped vehicle gets a zero velocity once and then drives on.
        """
        opposite = collision_wp.get_left_lane()
        if opposite is None:
            return
        target = opposite.transform.location
        snapshot = self._world.snapshot()
        for vid, veh in list(self._vehicles.items()):
            actor = snapshot.actors.get(vid)
            if veh.source != "opposite" or actor is None:
                continue
            distance = actor.location.distance(target)
            if distance < 20.0:
                self._destroy(vid)
            elif distance < 30.0:
                self._world.set_target_velocity(vid, Vector3D())

    def readd_road_lane(self, offset: int) -> None:
        """Spawn again on the ego-relative lane ``offset`` (0 ego lane, 1 right, −1 left); every removed lane is
        open to road vehicles again."""
        self._removed_offsets.discard(int(offset))
        self._removed_lanes.clear()

    def set_max_speed(self, speed: float | None) -> None:
        """Cap background speed (m/s); ``None`` lifts the cap."""
        self._max_speed = None if speed is None else max(0.0, float(speed))

    def stop_front_vehicles(self) -> None:
        """Brake every background vehicle now in front of the ego that drives its way (within 45°)."""
        self._stop_front = True

    def start_front_vehicles(self) -> None:
        """Release the vehicles stopped by :meth:`stop_front_vehicles`."""
        self._stop_front = False
        self._stopped["front"].clear()

    def stop_back_vehicles(self) -> None:
        """Brake every background vehicle now behind the ego that drives its way (within 45°)."""
        self._stop_back = True

    def start_back_vehicles(self) -> None:
        """Release the vehicles stopped by :meth:`stop_back_vehicles`."""
        self._stop_back = False
        self._stopped["back"].clear()

    def change_road_behavior(self, spawn_dist: float | None = None, extra_space: float | None = None) -> None:
        """Change the 15 m spawn spacing and the radius offset of the ego's road."""
        if spawn_dist is not None:
            self.settings.spawn_dist = max(1.0, float(spawn_dist))
        if extra_space is not None:
            self.settings.extra_space = float(extra_space)

    def change_opposite_behavior(self, active: bool | None = None, spawn_dist: float | None = None) -> None:
        """Switch the opposite sources on/off (off also removes the opposite vehicles) or change their spacing."""
        if spawn_dist is not None:
            self.settings.opposite_spawn_dist = max(1.0, float(spawn_dist))
        if active is not None:
            self.settings.opposite_active = bool(active)
            if not active:
                for vid, veh in list(self._vehicles.items()):
                    if veh.source == "opposite":
                        self._destroy(vid)

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
        junction = self._next_junction()
        if junction is None:
            log.warning("handle_junction_scenario: no junction ahead of the ego on the route")
            return
        junction.clear_junction |= bool(clear_junction)
        junction.clear_ego_entry |= bool(clear_ego_entry)
        junction.removed_entries |= {(wp.road_id, wp.lane_id) for wp in remove_entries}
        junction.removed_exits |= {(wp.road_id, wp.lane_id) for wp in remove_exits}
        junction.stop_entries |= bool(stop_entries)
        junction.extend_exit = max(junction.extend_exit, float(extend_road_exit))
        if extend_road_exit > 0.0:
            exit_s = float(self._route_s[min(junction.exit_index, len(self._route_s) - 1)])
            self._front_clear_until = max(self._front_clear_until, exit_s + float(extend_road_exit))
        if clear_ego_entry:
            # the cleared entry stays clear: a car born there afterwards would take the scenario's turn in front of
            # the ego (route InterurbanActorFlow on Town103: one turned across the flow, was hit by a flow car that
            # does not yield, and both then stood in the ego's way until TickRuntime)
            entry_s = float(self._route_s[min(junction.entry_index, len(self._route_s) - 1)])
            self._front_clear_until = max(self._front_clear_until, entry_s)
        self._apply_junction_clearing(self._world.snapshot(), junction)

    def switch_route_sources(self, enabled: bool) -> None:
        """Switch the same-direction road sources on or off."""
        self._road_sources = bool(enabled)

    def vehicle_ids(self) -> list[int]:
        """Ids of the live background vehicles."""
        return sorted(self._vehicles)

    def vehicle_sources(self) -> dict[int, str]:
        """Which source made each live vehicle: road, opposite, junction, or detached (a road vehicle that
        left the ego's road through a junction)."""
        return {vid: self._vehicles[vid].source for vid in sorted(self._vehicles)}

    # -- extras --------------------------------------------------------------------------------------------
    def spawn_parked_cars(self, max_route_distance: float = 100.0, max_ego_distance: float = 450.0,
                          spacing: float = 7.0, probability: float = 0.6) -> list[int]:
        """Spawn static parked-car meshes (scale 0.9) along parking lanes near the route; returns their ids.

        The CARLA route runner reads each town's parking slots from a file; here the slots are points every
        ``spacing`` m along the map's parking lanes, each filled with ``probability``.
        """
        if self._ego_id is None:
            raise SimulatorError("start() the background traffic before spawning parked cars")
        from b2d_data.maps import LaneType

        snapshot = self._world.snapshot()
        ego_actor = snapshot.actors.get(self._ego_id)
        ego = ego_actor.transform.location if ego_actor is not None else self._route[0].transform.location
        meshes = list(blueprints.PARKED_VEHICLE_MESHES)
        spawned = []
        for lane in self._map.lane_geometry(resolution=spacing, lane_type=LaneType.PARKING):
            centre = lane.centre
            if len(centre) < 2:
                continue
            for k in range(len(centre)):
                p = centre[k]
                if math.hypot(p[0] - ego.x, p[1] - ego.y) > max_ego_distance:
                    continue
                if np.min(np.hypot(self._route_xy[:, 0] - p[0], self._route_xy[:, 1] - p[1])) > max_route_distance:
                    continue
                if self._rng.random() >= probability:
                    continue
                a, b = centre[max(k - 1, 0)], centre[min(k + 1, len(centre) - 1)]
                yaw = math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))
                mesh = meshes[int(self._rng.integers(len(meshes)))]
                spec = ActorSpec(blueprints.MESH_TYPE_ID, role_name="parked",
                                 attributes={"mesh_path": mesh, "scale": str(blueprints.PARKED_MESH_SCALE)})
                actor_id = self._world.try_spawn_actor(spec, Transform(Location(*map(float, p)), Rotation(yaw=yaw)))
                if actor_id is not None:
                    spawned.append(actor_id)
        self._parked.extend(spawned)
        return spawned

    def forget(self) -> None:
        """Drop all bookkeeping (the world is closing)."""
        self._vehicles.clear()
        self._ego_id = None

    # -- per tick ------------------------------------------------------------------------------------------
    def update(self, snapshot: Snapshot) -> None:
        """Called by the world before each tick: manage the population, then drive every vehicle."""
        live = self._world.actor_ids()
        for vid in [v for v in self._vehicles if v not in live]:
            del self._vehicles[vid]  # destroyed by somebody else
        for vid, veh in self._vehicles.items():
            actor = snapshot.actors.get(vid)
            if actor is not None:
                veh.location = actor.transform.location
        if self._ego_id is None or self._ego_id not in snapshot.actors:
            return
        if not self._started:
            self._begin(snapshot)
        self._tick += 1
        self._ego_index = self._nearest_route_index(snapshot)
        if self._tick % self.settings.manage_every == 0:
            self._manage(snapshot)
        if not self._vehicles:
            return
        self._set_targets(snapshot)
        agents = [veh.agent for veh in self._vehicles.values()]
        outputs = self.driver.plan(snapshot, agents, extra_inside=self._others_in_junctions(snapshot))
        self.last_outputs = outputs
        for vid, out in outputs.items():
            self._world.apply_control(vid, out.control)
            veh = self._vehicles[vid]
            moving = snapshot.actors[vid].speed() > 0.1
            veh.still_ticks = 0 if moving or out.reason in ("light", "stopped", "stop_sign") else veh.still_ticks + 1
            veh.narrow_ticks = veh.narrow_ticks + 1 if out.reason == "narrow_lane" and not moving else 0

    # -- internals: population -----------------------------------------------------------------------------
    def _manage(self, snapshot: Snapshot) -> None:
        ego = snapshot.actors[self._ego_id]
        self._pending = []
        self._recycle(snapshot, ego)
        self._update_junctions(snapshot, ego)
        if self._road_sources:
            self._spawn_road(snapshot, ego)
        if self.settings.opposite_active:
            self._spawn_opposite(snapshot, ego)
        self._spawn_junctions(snapshot, ego)

    def _radii(self, ego_speed: float) -> tuple[float, float]:
        s = self.settings
        grow = s.radius_speed_factor * ego_speed + s.extra_space
        return 2.0 * s.spawn_dist + grow, 3.0 * s.spawn_dist + grow

    def _recycle(self, snapshot: Snapshot, ego: Any) -> None:
        r_min, r_max = self._radii(ego.speed())
        stuck = int(self.settings.stuck_timeout / 0.05)
        for vid, veh in list(self._vehicles.items()):
            rel_x, rel_y = _ego_frame(ego, self._location(snapshot, vid))
            dist = math.hypot(rel_x, rel_y)
            far = False
            if veh.source == "road":
                far = rel_x < -(r_max + 15.0) or dist > 2.0 * r_max + 40.0
            elif veh.source == "opposite":
                far = rel_x < -max(30.0, r_min) or dist > 2.0 * r_max + 60.0
            else:
                far = dist > max(100.0, r_max + 40.0)
            if veh.still_ticks > stuck and dist > 15.0:
                far = True
            if veh.narrow_ticks > NARROW_LANE_TICKS:
                # standing in a lane's taper (our lane followers do not change lanes before their lane ends, TM's
                # do): it never moves again and half blocks the next lane (route 61430013 on Town100, seed 61: the
                # ego stood behind two such cars until TickRuntime)
                far = True
            wp = veh.agent.path.waypoints[0]
            if veh.junction_id is not None or wp.is_junction:
                for junction in self._junctions:
                    if (wp.road_id, wp.lane_id) in junction.removed_exits:
                        far = True
            if far:
                self._destroy(vid)

    def _spawn_road(self, snapshot: Snapshot, ego: Any) -> None:
        s = self.settings
        ego_wp = self._ego_waypoint(snapshot, ego)
        if ego_wp is None or ego_wp.is_junction:
            return
        _, r_max = self._radii(ego.speed())
        lanes = _same_direction_lanes(ego_wp)
        ego_s = float(self._route_s[self._ego_index])
        by_lane: dict[int, list[float]] = {}
        for vid, veh in self._vehicles.items():
            if veh.source == "road":
                rel_x, _ = _ego_frame(ego, self._location(snapshot, vid))
                by_lane.setdefault(veh.lane_offset, []).append(rel_x)
        for offset, lane_wp in lanes:
            if offset in self._removed_offsets or lane_wp.lane_width < s.min_lane_width:
                continue
            xs = by_lane.get(offset, [])
            front = sorted(x for x in xs if x > 0.0)
            back = sorted((-x for x in xs if x <= 0.0))
            d = max(s.min_spawn_distance, front[-1] + s.spawn_dist if front else s.min_spawn_distance)
            d = max(d, self._front_clear_until - ego_s)  # keep the space a scenario asked for
            for _ in range(s.front_vehicles - len(front)):
                if d > r_max + s.spawn_dist:
                    break
                wp = self._lane_ahead(lane_wp, offset, d)
                if wp is not None:
                    self._spawn(snapshot, wp, "road", lane_offset=offset)
                d += s.spawn_dist
            d = max(s.min_spawn_distance, back[-1] + s.spawn_dist if back else s.min_spawn_distance)
            for _ in range(s.back_vehicles - len(back)):
                if d > r_max + s.spawn_dist:
                    break
                options = lane_wp.previous(d)
                if options:
                    self._spawn(snapshot, options[0], "road", lane_offset=offset)
                d += s.spawn_dist

    def _spawn_opposite(self, snapshot: Snapshot, ego: Any) -> None:
        s = self.settings
        target_s = float(self._route_s[self._ego_index]) + s.opposite_source_dist
        index = int(np.searchsorted(self._route_s, target_s))
        if index >= len(self._route):
            index = len(self._route) - 1
            extra = target_s - float(self._route_s[index])
            ahead = self._route[index].next(extra) if extra > 1.0 else [self._route[index]]
            if not ahead:
                return
            source_wp = ahead[0]
        else:
            source_wp = self._route[index]
        if source_wp.is_junction:
            return
        for n, lane in enumerate(_opposite_lanes(source_wp)):
            if lane.lane_width < s.min_lane_width or lane.is_junction:
                continue
            last = self._opposite_last.get(n)
            if last is not None and last in snapshot.actors:
                loc = snapshot.actors[last].transform.location
                if loc.distance_2d(lane.transform.location) < s.opposite_spawn_dist:
                    continue
            vid = self._spawn(snapshot, lane, "opposite", ignore_signals=True)
            if vid is not None:
                self._opposite_last[n] = vid

    def _update_junctions(self, snapshot: Snapshot, ego: Any) -> None:
        s = self.settings
        ego_s = float(self._route_s[self._ego_index])
        for junction in self._junctions:
            if junction.done:
                continue
            entry_s = float(self._route_s[min(junction.entry_index, len(self._route_s) - 1)])
            if self._ego_index >= junction.exit_index + 3:
                junction.done, junction.active = True, False
                continue
            if not junction.active and entry_s - ego_s < s.junction_activation + s.junction_activation_time * ego.speed():
                junction.active = True
                self.driver.arbiter.learn_lanes(self._route[junction.entry_index:junction.exit_index])
                self._create_junction_sources(junction)
                self._apply_junction_clearing(snapshot, junction)

    def _create_junction_sources(self, junction: _RouteJunction) -> None:
        s = self.settings
        record = self._map.junctions.get(junction.junction_id)
        if record is None:
            return
        ego_entry = self._route[junction.entry_index - 1] if junction.entry_index > 0 else None
        ego_key = (ego_entry.road_id, ego_entry.lane_id) if ego_entry is not None else None
        seen: list[tuple[int, int]] = []
        for entry, _ in record.get_waypoints():
            for before in entry.previous(0.5):
                key = (before.road_id, before.lane_id)
                if before.is_junction or key == ego_key or key in seen:
                    continue
                seen.append(key)
                if self._rng.random() >= s.junction_source_probability:
                    continue
                wp, travelled = before, 0.0
                while travelled < s.junction_source_dist:
                    back = wp.previous(1.0)
                    if not back or back[0].is_junction:
                        break
                    wp, travelled = back[0], travelled + 1.0
                if travelled < s.junction_min_source_dist:
                    continue
                junction.sources.append(_JunctionSource(("junction", junction.junction_id, key), wp, key))

    def _spawn_junctions(self, snapshot: Snapshot, ego: Any) -> None:
        s = self.settings
        for junction in self._junctions:
            if not junction.active:
                continue
            for source in junction.sources:
                if source.lane_key in junction.removed_entries:
                    continue
                source.live = [v for v in source.live if v in self._vehicles]
                if len(source.live) >= s.junction_max_vehicles:
                    continue
                if source.last_id is not None and source.last_id in snapshot.actors:
                    loc = snapshot.actors[source.last_id].transform.location
                    if loc.distance_2d(source.waypoint.transform.location) < s.junction_spawn_dist:
                        continue
                vid = self._spawn(snapshot, source.waypoint, "junction", junction_id=junction.junction_id,
                                  source_key=source.key)
                if vid is not None:
                    source.live.append(vid)
                    source.last_id = vid

    def _apply_junction_clearing(self, snapshot: Snapshot, junction: _RouteJunction) -> None:
        if not junction.active and not (junction.clear_junction or junction.clear_ego_entry
                                         or junction.removed_entries or junction.removed_exits):
            return
        entry_s = float(self._route_s[min(junction.entry_index, len(self._route_s) - 1)])
        doomed: set[int] = set()
        if junction.clear_ego_entry:
            doomed.update(self._on_route(snapshot, float(self._route_s[self._ego_index]), entry_s))
        for vid, veh in self._vehicles.items():
            wp = veh.agent.path.waypoints[0]
            key = (wp.road_id, wp.lane_id)
            if junction.clear_junction and wp.is_junction and wp.junction_id == junction.junction_id:
                doomed.add(vid)
            if key in junction.removed_exits:
                doomed.add(vid)
            if veh.junction_id == junction.junction_id and veh.source_key and veh.source_key[2] in junction.removed_entries:
                doomed.add(vid)
        for vid in sorted(doomed):
            self._destroy(vid)

    def _spawn(self, snapshot: Snapshot, wp: Waypoint, source: str, ignore_signals: bool = False,
               junction_id: int | None = None, source_key: tuple[Any, ...] = (), lane_offset: int = 0) -> int | None:
        s = self.settings
        if wp.is_junction or wp.lane_width < s.min_lane_width:
            return None
        if source == "road" and (wp.road_id, wp.lane_id) in self._removed_lanes:
            return None
        from b2d_data.maps import LaneType

        if not wp.lane_type & LaneType.DRIVING:
            return None
        loc = wp.transform.location
        ego = snapshot.actors[self._ego_id].transform.location
        if loc.distance_2d(ego) < s.min_spawn_distance:
            return None
        for actor in snapshot.actors.values():
            if actor.kind in (ActorKind.VEHICLE, ActorKind.WALKER) and \
                    actor.transform.location.distance_2d(loc) < s.min_spawn_clearance:
                return None
        if any(p.location.distance_2d(loc) < s.min_spawn_clearance for p in self._pending):
            return None
        spec = blueprints.random_background_car(self._rng, role_name=ROLE_NAME)
        yaw = wp.transform.rotation.yaw
        right = (-math.sin(math.radians(yaw)), math.cos(math.radians(yaw)))
        place = Location(loc.x + right[0] * s.lane_offset, loc.y + right[1] * s.lane_offset, loc.z)
        path = LanePath(wp, rng=self._rng, lateral_offset=s.lane_offset)
        # enter the scene rolling, like the traffic around it, rather than parked on the lane
        limit = min(self._speed_limit(wp) / 3.6, s.max_speed_kmh / 3.6)
        ego_actor = snapshot.actors[self._ego_id]
        ego_speed = ego_actor.speed()
        initial = {"road": min(limit, ego_speed), "opposite": limit, "junction": 0.5 * limit}[source]
        if self._max_speed is not None:
            initial = min(initial, self._max_speed)
        # never faster than what stops comfortably (3 m/s²) short of the 10 m gap behind whatever is ahead,
        # nor before the next junction (whose reservation it may not get)
        path.extend()
        free = self._free_distance(snapshot, path) - BIRTH_GAP
        junction = path.first_junction()
        if junction is not None:
            free = min(free, junction[1] * PATH_STEP - 5.0)
        initial = min(initial, math.sqrt(2.0 * BIRTH_DECEL * max(0.0, free)))
        # any same-direction lane, not only the ego's: an overtaking ego returns to its lane (route 29000004 on
        # Town100, seed 29: a car born at 2.7 m/s 25 m ahead in the lane the ego came back to was hit at 20 m/s)
        if source == "road" and _yaw_difference(yaw, ego_actor.transform.rotation.yaw) <= 45.0 and \
                self._too_close_ahead(ego_actor, place, initial):
            return None
        if self._stops_a_follower(snapshot, place, yaw, initial):
            return None
        try:
            vid = self._world.try_spawn_actor(spec, Transform(place, Rotation(yaw=yaw)))
        except SpawnError as exc:
            log.debug("background spawn failed: %s", exc)
            return None
        if vid is None:
            return None
        self._pending.append(_Newborn(place, yaw, initial))
        agent = DrivingAgent(id=vid, path=path, target_speed=0.0, ignore_signals=ignore_signals)
        self._vehicles[vid] = _Vehicle(vid, source, agent, source_key=source_key, junction_id=junction_id,
                                       location=place, lane_offset=lane_offset)
        if initial > 0.0:
            rad = math.radians(yaw)
            self._world.set_target_velocity(vid, Location(initial * math.cos(rad), initial * math.sin(rad), 0.0))
        return vid

    @staticmethod
    def _too_close_ahead(ego: Any, place: Location, initial: float) -> bool:
        """Whether a car born at ``place`` in the ego's lane at ``initial`` m/s is one the ego could not stop for.

        A lane given back to the traffic (a scenario's end) fills from the minimum spawn distance on; a car born
        there slow (a junction or a queue ahead of it) in front of a fast ego leaves it no room: route 29430003 on
        Town100 (seed 29) was hit at 17 m/s by a car born standing 19.5 m ahead. The ego must be able to close the
        speed difference at 3 m/s² (the same comfortable rate the newcomer's own speed is bounded by) before it
        is within 10 m of the car.
        """
        rel_x, _ = _ego_frame(ego, place)
        return rel_x > 0.0 and _cannot_close(ego.speed(), initial, rel_x)

    def _stops_a_follower(self, snapshot: Snapshot, place: Location, yaw: float, initial: float) -> bool:
        """Whether a car born at ``place`` at ``initial`` m/s would stand in front of a background car of its lane
        that could not close the speed difference at 3 m/s² before a 10 m gap (as :meth:`_too_close_ahead`).

        Cars are born nearest first, so a slow newcomer (a junction or a queue ahead of it) can appear just in front
        of one born fast a moment before: route 29000009 on Town100 (seed 29) had a car born at 11 m/s brake at
        8 m/s² to a stop 11 m behind one born after it, 25 m ahead of an ego returning to that lane at 20 m/s.
        """
        rad = math.radians(yaw)
        c, s = math.cos(rad), math.sin(rad)
        followers = [(a.transform.location, a.transform.rotation.yaw, a.speed()) for a in snapshot.actors.values()
                     if a.kind is ActorKind.VEHICLE and a.id != self._ego_id and a.id in self._vehicles]
        followers += [(p.location, p.yaw, p.speed) for p in self._pending]
        for loc, f_yaw, speed in followers:
            dx, dy = loc.x - place.x, loc.y - place.y
            behind, across = -(dx * c + dy * s), abs(-dx * s + dy * c)
            if behind <= 0.0 or across > 1.5 or _yaw_difference(f_yaw, yaw) > 30.0:
                continue
            if _cannot_close(speed, initial, behind):
                return True
        return False

    def _free_distance(self, snapshot: Snapshot, path: LanePath) -> float:
        """Distance along a new vehicle's lane to the nearest vehicle or walker on it (at most the path length).

        Measured along the lane, not straight ahead: in a bend a straight probe misses the car standing in the
        lane, and the newcomer would enter too fast to stop behind it.
        """
        xy, _, arc, width = path.arrays()
        points = [a.transform.location for a in snapshot.actors.values()
                  if a.kind in (ActorKind.VEHICLE, ActorKind.WALKER)] + [p.location for p in self._pending]
        best = float(arc[-1])
        for loc in points:
            d = np.hypot(xy[:, 0] - loc.x, xy[:, 1] - loc.y)
            k = int(np.argmin(d))
            if 0 < k and float(arc[k]) < best and d[k] < 0.5 * width[k] + 0.5:
                best = float(arc[k])
        return best

    def _location(self, snapshot: Snapshot, vid: int) -> Location:
        actor = snapshot.actors.get(vid)
        return actor.transform.location if actor is not None else self._vehicles[vid].location

    def _destroy(self, vid: int) -> None:
        self._vehicles.pop(vid, None)
        try:
            self._world.destroy_actor(vid)
        except SimulatorError:
            pass  # already gone

    # -- internals: per-tick targets ---------------------------------------------------------------------
    def _set_targets(self, snapshot: Snapshot) -> None:
        s = self.settings
        ego = snapshot.actors[self._ego_id]
        r_min, r_max = self._radii(ego.speed())
        cap = s.max_speed_kmh / 3.6
        if self._max_speed is not None:
            cap = min(cap, self._max_speed)
        for vid, veh in self._vehicles.items():
            actor = snapshot.actors.get(vid)
            if actor is None:
                continue
            path = veh.agent.path
            if path.advance(actor.transform.location.x, actor.transform.location.y) > 3.0:
                self._replan(veh, actor)
            limit = self._speed_limit(path.waypoints[0]) / 3.6 * s.speed_percentage / 100.0
            target = min(limit, cap)
            if veh.source == "road" and path.waypoints[0].is_junction:
                # a road vehicle that drives into a junction leaves the ego's road: like LB2.0 it is no longer
                # held back by the radius ramp (that could stop it across the exit of a junction and jam it)
                veh.source = "detached"
            rel_x, _ = _ego_frame(ego, actor.transform.location)
            if veh.source == "road" and rel_x > 0.0:
                if rel_x >= r_max:
                    target = 0.0
                elif rel_x > r_min:
                    target *= (r_max - rel_x) / (r_max - r_min)
            if (self._stop_front or self._stop_back) and veh.source != "opposite" and _same_heading(ego, actor):
                if self._stop_front and rel_x > 0.0:
                    self._stopped["front"].add(vid)
                if self._stop_back and rel_x <= 0.0:
                    self._stopped["back"].add(vid)
            if vid in self._stopped["front"] or vid in self._stopped["back"]:
                target = 0.0
            veh.agent.target_speed = target
            junction = self._junction_by_id(veh.junction_id) if veh.junction_id is not None else None
            veh.agent.stop_before_junction = bool(junction is not None and junction.stop_entries)
        self._stop_front = self._stop_back = False  # the requests are taken: later arrivals drive on

    def _replan(self, veh: _Vehicle, actor: Any) -> None:
        wp = self._map.get_waypoint(actor.transform.location)
        if wp is not None:
            veh.agent.path = LanePath(wp, rng=self._rng, lateral_offset=self.settings.lane_offset)

    def _speed_limit(self, wp: Waypoint) -> float:
        key = (wp.road_id, wp.lane_id, int(wp.s // 10.0))
        limit = self._speed_limits.get(key)
        if limit is None:
            limit = float(self._map.speed_limit(wp))
            self._speed_limits[key] = limit
        return limit

    def _others_in_junctions(self, snapshot: Snapshot) -> dict[int, tuple[int, tuple[tuple[int, int, int], ...]]]:
        """Other vehicles in (or about to enter) an active route junction hold lanes of it for the arbiter.

        Background vehicles give way to them (TM-like yielding to the hero). The ego holds the route's lanes
        through the junction (the expert follows the route), any other vehicle, or the ego off its route, every
        lane: their way is unknown. Holding every lane for the ego would let traffic it waits for wait for it
        in turn (e.g. an oncoming car held at the junction the ego stands in the exit of, whose queue keeps the
        junction ahead of the ego full). Vehicles that another :class:`TrafficDriver` drives with the same arbiter
        are left to it.
        """
        out = {}
        shared = self.driver.arbiter.holders
        for actor in snapshot.actors.values():
            if actor.kind is not ActorKind.VEHICLE or actor.id in self._vehicles or actor.parent_id is not None:
                continue
            if actor.id in shared and actor.id not in self._handed_in:
                continue
            junction = self._junction_near(actor)
            if junction is None:
                continue
            keys: tuple[tuple[int, int, int], ...] = (ANY_LANE,)
            if actor.id == self._ego_id and junction.lane_keys and self._near_route(actor.transform.location):
                keys = junction.lane_keys
            out[actor.id] = (junction.junction_id, keys)
        self._handed_in = set(out)
        return out

    def _near_route(self, loc: Location, tolerance: float = 2.0) -> bool:
        """Is a location within ``tolerance`` m of the route near the ego's route index?"""
        lo, hi = max(0, self._ego_index - 10), min(len(self._route_xy), self._ego_index + 30)
        if hi <= lo:
            return False
        d = np.hypot(self._route_xy[lo:hi, 0] - loc.x, self._route_xy[lo:hi, 1] - loc.y)
        return float(d.min()) < tolerance

    def _junction_near(self, actor: Any) -> _RouteJunction | None:
        """The active route junction an actor is inside (its centre or front bumper on one of the junction's
        lanes), or drives into within ~1 s (at least 5 m away)."""
        loc = actor.transform.location
        speed = actor.speed()
        yaw = math.radians(actor.transform.rotation.yaw)
        front = actor.bounding_box.extent.x
        probes = [0.0, front]
        if speed > 0.5:
            probes.append(max(5.0, speed * 1.0))
        for junction in self._junctions:
            if not junction.active:
                continue
            record = self._map.junctions.get(junction.junction_id)
            if record is None:
                continue
            box = record.bounding_box
            margin = 1.0
            for probe in probes:
                x, y = loc.x + math.cos(yaw) * probe, loc.y + math.sin(yaw) * probe
                if abs(x - box.location.x) > box.extent.x + margin or abs(y - box.location.y) > box.extent.y + margin:
                    continue
                # the axis-aligned box of a skewed junction reaches far over its entry roads: a car waiting
                # there (e.g. at a red light) must not hold the junction, so ask the lane under the probe
                wp = self._map.get_waypoint(Location(x, y, loc.z))
                if wp is not None and wp.is_junction and wp.junction_id == junction.junction_id:
                    return junction
        return None

    # -- internals: geometry helpers ---------------------------------------------------------------------
    def _nearest_route_index(self, snapshot: Snapshot, full: bool = False) -> int:
        loc = snapshot.actors[self._ego_id].transform.location
        if full:
            lo, hi = 0, len(self._route_xy)
        else:
            lo, hi = max(0, self._ego_index - 5), min(len(self._route_xy), self._ego_index + 60)
        d = np.hypot(self._route_xy[lo:hi, 0] - loc.x, self._route_xy[lo:hi, 1] - loc.y)
        return lo + int(np.argmin(d))

    def _ego_waypoint(self, snapshot: Snapshot, ego: Any) -> Waypoint | None:
        """The route's lane beside the ego while the ego is within a lane of it, else the ego's own lane.

        Lane offsets (road spawns, removed lanes) count from the route's lane, as BackgroundActivity keys its lanes:
        an ego that moved over (yielding to an emergency vehicle, passing an obstacle) must not make the lane a
        scenario removed count as a free neighbour (route 67430004 on Town100, seed 67: a car born in the lane
        removed for the ambulance held it behind the ego until the scenario ended as not yielded).
        """
        wp = self._route[self._ego_index]
        gap = wp.transform.location.distance_2d(ego.transform.location)
        if gap < 2.0 or (gap < ROUTE_LANE_TOLERANCE and not wp.is_junction):
            return wp
        return self._map.get_waypoint(ego.transform.location)

    def _lane_ahead(self, lane_wp: Waypoint, offset: int, d: float) -> Waypoint | None:
        if offset == 0:
            target = float(self._route_s[self._ego_index]) + d
            index = int(np.searchsorted(self._route_s, target))
            if index < len(self._route):
                return self._route[index]
        options = lane_wp.next(d)
        return options[0] if options else None

    def _lane_offset_of(self, snapshot: Snapshot, lane: Waypoint) -> int | None:
        ego_wp = self._ego_waypoint(snapshot, snapshot.actors[self._ego_id]) if self._ego_id is not None else None
        if ego_wp is None:
            return None
        for offset, wp in _same_direction_lanes(ego_wp):
            if (wp.road_id, wp.lane_id) == (lane.road_id, lane.lane_id):
                return offset
        ego = snapshot.actors[self._ego_id]
        _, rel_y = _ego_frame(ego, lane.transform.location)
        return int(round(rel_y / max(ego_wp.lane_width, 1.0)))

    def _on_route(self, snapshot: Snapshot, s_from: float, s_to: float) -> list[int]:
        """Background vehicles within 1.5 m of the route between two route distances."""
        lo = int(np.searchsorted(self._route_s, s_from))
        hi = int(np.searchsorted(self._route_s, s_to, side="right"))
        if hi <= lo:
            return []
        pts = self._route_xy[lo:hi]
        out = []
        for vid in sorted(self._vehicles):
            loc = self._location(snapshot, vid)
            if float(np.min(np.hypot(pts[:, 0] - loc.x, pts[:, 1] - loc.y))) < 1.5 + 1.0:
                out.append(vid)
        return out

    def _next_junction(self) -> _RouteJunction | None:
        for junction in self._junctions:
            if junction.exit_index >= self._ego_index and not junction.done:
                return junction
        return None

    def _junction_by_id(self, junction_id: int) -> _RouteJunction | None:
        for junction in self._junctions:
            if junction.junction_id == junction_id and not junction.done:
                return junction
        return None


def _ego_frame(ego: Any, loc: Location) -> tuple[float, float]:
    """(forward, right) coordinates of a location in the ego's frame."""
    t = ego.transform
    yaw = math.radians(t.rotation.yaw)
    dx, dy = loc.x - t.location.x, loc.y - t.location.y
    return dx * math.cos(yaw) + dy * math.sin(yaw), -dx * math.sin(yaw) + dy * math.cos(yaw)


def _same_heading(ego: Any, actor: Any, tolerance: float = 45.0) -> bool:
    """Does ``actor`` head the ego's way (yaw within ``tolerance`` degrees)?"""
    return _yaw_difference(actor.transform.rotation.yaw, ego.transform.rotation.yaw) <= tolerance


def _yaw_difference(a: float, b: float) -> float:
    """The absolute difference of two headings in degrees, in [0, 180]."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def _cannot_close(speed_behind: float, speed_ahead: float, gap: float) -> bool:
    """Whether a car ``gap`` m behind another cannot close their speed difference at ``BIRTH_DECEL`` before it is
    within ``BIRTH_GAP`` m of it (the rule every newborn car is checked against, for the ego and its followers)."""
    return speed_behind**2 - speed_ahead**2 > 2.0 * BIRTH_DECEL * max(0.0, gap - BIRTH_GAP)


def _same_direction_lanes(wp: Waypoint) -> list[tuple[int, Waypoint]]:
    """(offset, waypoint) of every driving lane in the ego's direction: 0 itself, −1 left, +1 right..."""
    from b2d_data.maps import LaneType

    out = [(0, wp)]
    for step, offset_sign in ((lambda w: w.get_left_lane(), -1), (lambda w: w.get_right_lane(), 1)):
        current, n = wp, 0
        for _ in range(8):
            current = step(current)
            if current is None or (current.lane_id > 0) != (wp.lane_id > 0):
                break
            n += 1
            if not current.lane_type & LaneType.DRIVING:
                break
            out.append((offset_sign * n, current))
    return out


def _opposite_lanes(wp: Waypoint) -> list[Waypoint]:
    """Driving lanes of the opposite direction, from the centre outwards."""
    from b2d_data.maps import LaneType

    current: Waypoint | None = wp
    for _ in range(8):
        if current is None or (current.lane_id > 0) != (wp.lane_id > 0):
            break
        current = current.get_left_lane()
    out: list[Waypoint] = []
    for _ in range(8):
        if current is None or (current.lane_id > 0) == (wp.lane_id > 0):
            break
        if current.lane_type & LaneType.DRIVING:
            out.append(current)
        current = current.get_right_lane()
    return out


def _route_junctions(route: Sequence[Waypoint]) -> list[_RouteJunction]:
    out: list[_RouteJunction] = []
    current: _RouteJunction | None = None
    for i, wp in enumerate(route):
        if wp.is_junction:
            if current is None or current.junction_id != wp.junction_id:
                current = _RouteJunction(wp.junction_id, i, i + 1)
                out.append(current)
            current.exit_index = i + 1
            key = (wp.road_id, wp.section_id, wp.lane_id)
            if key not in current.lane_keys:
                current.lane_keys += (key,)
        else:
            current = None
    return out
