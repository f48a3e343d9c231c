"""Actor flows: a stream of vehicles from a source lane point to a sink (scenario_runner's ActorFlow).

With ``constant_velocity`` the vehicles drive at a forced constant speed ignoring lights, signs and other vehicles
(the ego too) until the flow's first collision, as LB2.0's ``ActorFlow`` (Traffic Manager with
``ignore_vehicles_percentage(actor, 100)`` and ``enable_constant_velocity``, a collision sensor on every car). From
the first collision of any of its cars on, the flow's cars (those alive and those spawned later) brake for vehicles
in their path; see :meth:`ActorFlow.update`. Otherwise they are lane-following agents at a target speed that brake
for vehicles ahead (the opposite traffic of the two-way obstacle scenarios). A new vehicle appears at the source
once the previous one has driven a gap drawn uniformly from the interval; vehicles are removed within
``sink_distance`` of the sink.

:class:`FlowScenario` is the shape every flow type shares: ``flow_speed`` and ``source_dist_interval`` read from the
XML, the background prepared and paused at the trigger, the flows driven every tick until the type's end condition,
then removed and the background given back.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from b2d_data.format.transform import Vector3D
from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.road_geometry import lane_walk, offset_transform
from b2d_data.scenarios.controllers import ConstantVelocityAgent, LaneFollowingAgent, PathTrack
from b2d_data.scenarios.framework import SCENARIO_ROLE, Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorSpec, ScenarioHint, Simulator, SimulatorError, Snapshot, VehicleControl

log = logging.getLogger(__name__)


def flow_path(source: Waypoint, sink: Waypoint, max_length: float = 600.0) -> list[Waypoint]:
    """Lane waypoints (1 m apart, straight through junctions) from ``source`` up to the point nearest ``sink``."""
    walk = lane_walk(source, max_length)
    target = sink.transform.location
    d = [wp.transform.location.distance_2d(target) for wp in walk]
    k = int(np.argmin(d))
    if d[k] > 3.0:
        raise ScenarioSetupError(
            f"the flow lane from road {source.road_id} lane {source.lane_id} does not reach its sink at "
            f"({target.x:.1f}, {target.y:.1f}) (closest {d[k]:.1f} m)"
        )
    if k < 1:
        raise ScenarioSetupError("an actor flow needs its sink ahead of its source")
    return walk[: k + 1]


@dataclass
class _FlowVehicle:
    actor_id: int
    agent: ConstantVelocityAgent | LaneFollowingAgent
    crashed: bool = False
    seen: bool = False


#: How far ahead (m) a flow car's path goes into the scenario's hint: beyond a 4 s forecast at 21 m/s.
PATH_HINT_LENGTH = 90.0
#: The ego must get this close to a sink point to end a merge scenario (m; the reference's ``_sink_distance``).
SINK_DISTANCE = 2.0


class ActorFlow:
    """A flow of cars along ``path`` (lane waypoints); ``constant_velocity`` selects the controller.

    ``initial_actors`` pre-populates the path at the start, as LB2.0's ``ActorFlow(..., initial_actors=True)``.
    ``lateral_offset`` (m, right positive) makes the lane-following vehicles drive beside the lane centre;
    ``lateral_margin`` widens their swept path when they look for vehicles to stop for; ``blueprint_ids`` replaces
    the background cars the vehicles are drawn from (e.g. bicycles for a BicycleFlow). ``hero_clearance`` (m; None,
    the default and LB2.0's rule, never waits) holds the next vehicle back while the ego is that close to the source.
    ``yield_after_collision`` (constant-velocity flows only) makes the cars brake for vehicles once any of them has
    collided (LB2.0's ``ActorFlow``); False keeps them ignoring vehicles for good (LB2.0's ``BicycleFlow``, whose
    bicycles are BasicAgents with ``ignore_vehicles`` and no collision sensor).
    """

    def __init__(
        self,
        sim: Simulator,
        rng: np.random.Generator,
        path: list[Waypoint],
        speed: float,
        interval: tuple[float, float],
        sink_distance: float = 2.0,
        constant_velocity: bool = True,
        initial_actors: bool = False,
        lateral_offset: float = 0.0,
        lateral_margin: float = 0.3,
        blueprint_ids: Sequence[str] | None = None,
        hero_clearance: float | None = None,
        yield_after_collision: bool = True,
    ) -> None:
        if len(path) < 2:
            raise ScenarioSetupError("an actor flow needs a path of at least two waypoints")
        self.sim = sim
        self.rng = rng
        self.waypoints = path
        self.track = PathTrack.from_waypoints(path)
        self.speed = float(speed)
        self.interval = (float(min(interval)), float(max(interval)))
        self.sink_distance = sink_distance
        self.constant_velocity = constant_velocity
        self.lateral_offset = float(lateral_offset)
        self.lateral_margin = float(lateral_margin)
        self.hero_clearance = hero_clearance
        self.yield_after_collision = yield_after_collision
        #: Whether the cars brake for vehicles: from the flow's first collision on (constant-velocity flows).
        self.yielding = False
        self.vehicles: list[_FlowVehicle] = []
        self._cars = list(blueprint_ids) if blueprint_ids is not None else blueprints.background_car_ids()
        if not self._cars:
            raise ScenarioSetupError("an actor flow needs at least one blueprint to draw its vehicles from")
        self._gap = self._draw_gap()
        self._last_spawned: int | None = None
        self._initial = initial_actors
        self.active = False

    @property
    def actor_ids(self) -> list[int]:
        """Ids of the live flow vehicles."""
        return [v.actor_id for v in self.vehicles]

    def paths_ahead(self, length: float = PATH_HINT_LENGTH) -> dict[int, np.ndarray]:
        """Each live vehicle's path ahead, (N, 2) x, y over ``length`` metres (the expert's flow forecasts)."""
        return {v.actor_id: v.agent.path_ahead(length) for v in self.vehicles}

    def _draw_gap(self) -> float:
        return float(self.rng.uniform(*self.interval))

    def _spec(self) -> ActorSpec:
        return blueprints.random_background_car(self.rng, role_name=SCENARIO_ROLE, choices=self._cars)

    def _spawn_at(self, index: int) -> int | None:
        wp = self.waypoints[index]
        actor_id = self.sim.try_spawn_actor(self._spec(), offset_transform(wp, lateral=self.lateral_offset, z=0.2))
        if actor_id is None:
            return None
        rest = self.waypoints[index:]
        if self.constant_velocity:
            # Before the first collision the car ignores every vehicle (LB2.0: the TM at ignore_vehicles 100 plus a
            # forced constant velocity), so an ego that pulls in front of it is struck. The detection settings below
            # only act once ``yielding`` (see update). Only a box that reaches into the swept path counts then (no
            # margin): a car waiting to turn across the flow with its nose 0.3 m short of that path would otherwise
            # stop the flow, and both would wait for ever.
            agent: ConstantVelocityAgent | LaneFollowingAgent = ConstantVelocityAgent(
                self.sim,
                actor_id,
                PathTrack.from_waypoints(rest),
                self.speed,
                detect_vehicles=self.yielding,
                base_threshold=5.0,
                speed_ratio=0.5,
                max_brake=1.0,
                predict=1.0,
                crossing_stop_gap=6.0,
                lateral_margin=0.0,
            )
            # a flow car enters at its cruising speed
            yaw = math.radians(wp.transform.rotation.yaw)
            self.sim.set_target_velocity(
                actor_id, Vector3D(math.cos(yaw) * self.speed, math.sin(yaw) * self.speed, 0.0)
            )
        else:
            agent = LaneFollowingAgent(self.sim, actor_id, rest, self.speed, lateral_offset=self.lateral_offset,
                                       lateral_margin=self.lateral_margin)
        self.vehicles.append(_FlowVehicle(actor_id, agent))
        return actor_id

    def start(self) -> None:
        """Begin spawning (and pre-populate the path if asked)."""
        self.active = True
        if not self._initial:
            return
        s = float(self.track.length) - self.sink_distance - 5.0
        # from the sink backwards so that the first car spawned is the one furthest along
        while s > self._gap:
            index = int(np.clip(np.searchsorted(self.track.s, s), 0, len(self.waypoints) - 1))
            self._spawn_at(index)
            s -= self._draw_gap()

    def update(self, snapshot: Snapshot) -> None:
        """Spawn at the source when the gap is free, drive every vehicle, remove those at the sink."""
        crashed = {c.actor_id for c in snapshot.collisions}
        if not self.yielding and self.constant_velocity and self.yield_after_collision:
            ours = {v.actor_id for v in self.vehicles}
            hit = next((c for c in snapshot.collisions if c.actor_id in ours), None)
            if hit is not None:
                self._start_yielding(hit.actor_id, hit.other_id)
        for veh in list(self.vehicles):
            actor = snapshot.actors.get(veh.actor_id)
            if actor is None:
                if veh.seen:  # removed by somebody else; unseen ones were spawned this tick
                    self.vehicles.remove(veh)
                continue
            veh.seen = True
            if not self.constant_velocity and veh.actor_id in crashed and not veh.crashed:
                veh.crashed = True  # a lane-following flow car stops where it collided, for good
                log.debug("flow vehicle %d collided, it stops", veh.actor_id)
            if veh.crashed:
                self.sim.apply_control(veh.actor_id, VehicleControl(brake=1.0))
                continue
            veh.agent.run_step(snapshot)
            if veh.agent.done:
                self._destroy(veh)
        if not self.active:
            return
        if self._last_spawned is not None:
            last = snapshot.actors.get(self._last_spawned)
            source = self.waypoints[0].transform.location
            if last is None and any(v.actor_id == self._last_spawned and not v.seen for v in self.vehicles):
                return  # spawned this tick
            if last is not None and last.location.distance_2d(source) < self._gap:
                return
        if self._hero_at_source(snapshot):
            return
        if self._spawn_at(0) is not None:
            self._last_spawned = self.vehicles[-1].actor_id
            self._gap = self._draw_gap()

    def _start_yielding(self, actor_id: int, other_id: int) -> None:
        """The flow's first collision: from now on every car of the flow brakes for vehicles in its path.

        LB2.0 then calls ``disable_constant_velocity`` and ``ignore_vehicles_percentage(actor, 0)`` on every live
        car, and spawns later cars without either, so the Traffic Manager drives them at ``flow_speed`` and brakes
        for vehicles. Our kinematic stand-in for the TM is the same path-following agent with its vehicle detection
        on: it still cruises at ``flow_speed`` but slows down for a vehicle in its path (bounded braking, and speeds
        up again at ``resume_accel`` once the path is clear). The car that collided is no exception: it stays
        against what it hit (the simulator does not let it drive through) until its path is clear.
        """
        self.yielding = True
        for veh in self.vehicles:
            if isinstance(veh.agent, ConstantVelocityAgent):
                veh.agent.detect_vehicles = True
        log.debug("flow vehicle %d collided with actor %d: the flow now brakes for vehicles", actor_id, other_id)

    def _hero_at_source(self, snapshot: Snapshot) -> bool:
        """Whether ``hero_clearance`` holds the next vehicle back: the ego is within it of the source (2D)."""
        if self.hero_clearance is None:
            return False
        hero = snapshot.hero()
        source = self.waypoints[0].transform.location
        return hero is not None and hero.location.distance_2d(source) < self.hero_clearance

    def _destroy(self, veh: _FlowVehicle) -> None:
        if veh in self.vehicles:
            self.vehicles.remove(veh)
        try:
            self.sim.destroy_actor(veh.actor_id)
        except SimulatorError:
            log.debug("flow vehicle %d already gone", veh.actor_id)

    def stop(self) -> None:
        """Remove every flow vehicle and stop spawning."""
        self.active = False
        for veh in list(self.vehicles):
            self._destroy(veh)


class FlowScenario(Scenario):
    """Base of the flow types: one or more :class:`ActorFlow` from a source to a sink around the ego's way.

    The shape (LB2.0's ``_create_behavior`` of every ActorFlow type): at the trigger the background is prepared
    (:meth:`prepare_background`: HandleJunctionScenario, RemoveRoadLane), the route sources and/or the opposite
    traffic are switched off (``route_sources_off``, ``opposite_off``), the flows start (:meth:`start_flows`); every
    tick the flows drive, then :meth:`step` and the end condition :meth:`finished`; at the end the flows are removed,
    :meth:`restore_background` runs and what was switched off is switched back on. Subclasses may put the flow base
    before another scenario base (``class T(FlowScenario, JunctionScenario)``).
    """

    #: The XML's ``flow_speed`` (m/s) when it gives none (LB2.0's ``get_value_parameter`` default of the type).
    default_flow_speed: ClassVar[float] = 10.0
    #: The XML's ``source_dist_interval`` (m) when it gives none.
    default_interval: ClassVar[tuple[float, float]] = (20.0, 50.0)
    #: LB2.0's ``SwitchRouteSources(False)`` before the flows and ``(True)`` after them.
    route_sources_off: ClassVar[bool] = False
    #: LB2.0's ``ChangeOppositeBehavior(active=False)`` before the flows and ``(active=True)`` after them.
    opposite_off: ClassVar[bool] = False

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.flow_speed = ctx.value("flow_speed", self.default_flow_speed)
        self.interval = ctx.interval("source_dist_interval", self.default_interval)
        self.flows: list[ActorFlow] = []
        self._flows_started = False

    @property
    def flow(self) -> ActorFlow | None:
        """The first flow (the only one of most types), None before the trigger."""
        return self.flows[0] if self.flows else None

    def ego_near_sink(self, snapshot: Snapshot, sinks: list[Waypoint]) -> bool:
        """LB2.0's ``InTriggerDistanceToLocation(ego, sink, _sink_distance)`` over several sink points: any fires."""
        ego = self.ctx.ego(snapshot)
        return ego is not None and any(
            ego.location.distance_2d(s.transform.location) < SINK_DISTANCE for s in sinks
        )

    # -- hooks ----------------------------------------------------------------------------------------------------
    def prepare_background(self, snapshot: Snapshot) -> None:
        """Background hooks before the flows start (HandleJunctionScenario, RemoveRoadLane)."""

    def start_flows(self, snapshot: Snapshot) -> None:
        """Create and start the flows (:meth:`add_flow`) and whatever goes with them (lights, cones)."""

    def step(self, snapshot: Snapshot) -> None:
        """Per-tick work after the flows drove (lights, lane clearing)."""

    def finished(self, snapshot: Snapshot) -> bool:
        """The type's end condition (SUCCESS once true)."""
        return False

    def restore_background(self) -> None:
        """Undo :meth:`prepare_background` and release what :meth:`start_flows` held (lights); only after a start."""

    # -- the shared shape -----------------------------------------------------------------------------------------
    def add_flow(
        self,
        path: list[Waypoint],
        speed: float | None = None,
        interval: tuple[float, float] | None = None,
        **options: object,
    ) -> ActorFlow:
        """Start an :class:`ActorFlow` along ``path`` at ``speed`` (default ``flow_speed``) spawning every
        ``interval`` (default the XML's); ``options`` are ActorFlow's keyword arguments."""
        flow = ActorFlow(
            self.ctx.sim,
            self.ctx.rng,
            path,
            self.flow_speed if speed is None else speed,
            self.interval if interval is None else interval,
            **options,  # type: ignore[arg-type]
        )
        flow.start()
        self.flows.append(flow)
        return flow

    def start(self, snapshot: Snapshot) -> None:
        """Prepare the background, switch off the route sources / opposite traffic, start the flows."""
        self.prepare_background(snapshot)
        bg = self.ctx.sim.background
        if self.route_sources_off:
            bg.switch_route_sources(False)
        if self.opposite_off:
            bg.change_opposite_behavior(active=False)
        self._flows_started = True
        self.start_flows(snapshot)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Drive the flows, then :meth:`step`; SUCCESS once :meth:`finished`."""
        for flow in self.flows:
            flow.update(snapshot)
        self.step(snapshot)
        return ScenarioStatus.SUCCESS if self.finished(snapshot) else ScenarioStatus.RUNNING

    def hint(self) -> ScenarioHint | None:
        """A hint of the scenario's type (its flow's cars never brake for the ego: the expert's flow checks) with
        every flow car's path ahead, so that a car about to turn is forecast turning."""
        paths: dict[int, np.ndarray] = {}
        for flow in self.flows:
            paths.update(flow.paths_ahead())
        return ScenarioHint(self.xml_type, None, None, paths=paths)

    def on_end(self) -> None:
        """Remove the flows, undo the background hooks, switch back on what the start switched off."""
        for flow in self.flows:
            flow.stop()
        if not (self._flows_started or self.flows):  # never started (a subclass's own start() fills flows)
            return
        self.restore_background()
        bg = self.ctx.sim.background
        if self.route_sources_off:
            bg.switch_route_sources(True)
        if self.opposite_off:
            try:
                bg.change_opposite_behavior(active=True)
            except SimulatorError as exc:
                log.warning("%s: could not restore opposite traffic: %s", self.name, exc)
