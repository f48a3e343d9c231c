"""Static obstacles on the ego's lane that must be overtaken (§2.2 #5–#10): ParkedObstacle(TwoWays),
ConstructionObstacle(TwoWays), Accident(TwoWays).

Shared mechanics (LB2.0 ``route_obstacles.py``): the obstacle stands ``distance`` m after the trigger point, pushed
toward the ``direction`` side of the lane; a warning sign stands at the road's edge near the trigger point; at the
trigger the background leaves the stretch up to the obstacle free; once the ego is within 50 m of the obstacle and
5 s have passed, the scenario's own reaction starts (background speed cap, or the opposite flow on two-way roads);
the scenario ends when the ego has passed a point 50 m beyond the last obstacle, or after the 240 s timeout.

Lane walks are LB2.0's ``_move_waypoint_forward``: 1 m steps that stop at the last point before a junction, so a
``distance`` reaching into a junction puts the obstacle just before it (the construction site and the door car are
the exception: LB2.0 jumps ``next(distance)[0]`` there). The opposite flow is LB2.0's ``OppositeActorFlow``: its
source and sink stop before junctions too, and its reach and speed come from the ego's speed limit when it starts.

Each type combines an obstacle site (what stands on the lane: :class:`ParkedCarSite`, :class:`ConstructionSite`,
:class:`AccidentSite`) with a reaction (multi-lane roads: :class:`SpeedCapObstacle`; two-way roads:
:class:`OppositeFlowObstacle`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import ClassVar

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import LaneType, Waypoint
from b2d_data.scenarios.catalog.actor_choices import (
    CONSTRUCTION_CONE,
    DEBRIS,
    HAZARD_LIGHTS,
    POLICE_ACCIDENT_LIGHTS,
    POLICE_CAR,
    TRAFFIC_WARNING,
    WARNING_ACCIDENT,
    WARNING_CONSTRUCTION,
    random_parked_car,
)
from b2d_data.scenarios.catalog.flows import ActorFlow, flow_path
from b2d_data.scenarios.catalog.road_geometry import (
    move_along,
    move_before_junction,
    neighbour,
    offset_transform,
    same_direction_driving_neighbour,
)
from b2d_data.scenarios.controllers import park
from b2d_data.scenarios.criteria import SWITCH_WRONG_DIRECTION
from b2d_data.scenarios.framework import (
    Scenario,
    ScenarioContext,
    ScenarioSetupError,
    ScenarioStatus,
    register,
)
from b2d_data.scenarios.triggers import DistanceTrigger, Timer, is_in_front
from b2d_data.sim.api import OPPOSITE_LANE_OPEN, ActorState, ScenarioHint, SimulatorError, Snapshot

log = logging.getLogger(__name__)


class RoadObstacle(Scenario):
    """Common part of the obstacle scenarios; subclasses spawn the obstacle and react once the ego approaches."""

    default_distance: ClassVar[float] = 120.0
    #: Extra metres beyond ``distance`` that the background leaves free at the trigger.
    clear_extra: ClassVar[float] = 20.0
    #: Fraction of the lane width the obstacle is pushed toward its side.
    side_offset: ClassVar[float] = 0.35
    trigger_distance: ClassVar[float] = 50.0
    wait_duration: ClassVar[float] = 5.0
    end_distance: ClassVar[float] = 50.0
    #: LB2.0 places the obstacle with ``next(distance)[0]`` (through junctions) rather than ``_move_waypoint_forward``.
    jumps_to_obstacle: ClassVar[bool] = False

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.distance = ctx.value("distance", self.default_distance)
        self.direction = ctx.text("direction", "right")
        if self.direction not in ("left", "right"):
            raise ScenarioSetupError(f"{self.name}: direction must be 'left' or 'right', got {self.direction!r}")
        self.sign = 1.0 if self.direction == "right" else -1.0
        if self.jumps_to_obstacle:
            found = move_along(self.trigger_waypoint, self.distance)
            if found is None:
                raise ScenarioSetupError(f"{self.name}: the lane ends within {self.distance:.0f} m of the trigger point")
            wp = found
        else:
            wp = move_before_junction(self.trigger_waypoint, self.distance)
        self.obstacle_waypoint: Waypoint = wp
        self.end_reference = wp
        self.place_site()
        self.check_layout()
        self.first_id: int | None = None
        self.last_id: int | None = None
        self._approach = DistanceTrigger(self.trigger_distance)
        self._wait = Timer(self.wait_duration)
        self._end_transform: Transform | None = None
        self.reacting = False

    def place_site(self) -> None:
        """Find the lane points of the rest of the obstacle site (before :meth:`check_layout`)."""

    def check_layout(self) -> None:
        """Raise :class:`ScenarioSetupError` when the road lacks what the scenario needs."""

    def spawn_obstacle_vehicle(self, type_id: str, wp: Waypoint) -> int:
        """A parked vehicle on ``wp``'s lane, pushed ``side_offset`` × lane width to the obstacle side."""
        lateral = self.sign * self.side_offset * wp.lane_width
        transform = offset_transform(wp, lateral=lateral, z=0.2)
        retries = [offset_transform(wp, lateral=lateral, forward=f, z=0.2) for f in (1.0, 2.0, -1.0)]
        actor_id = self.spawn(type_id, transform, retries=retries)
        park(self.ctx.sim, actor_id)
        return actor_id

    def warning_sign_transform(self) -> Transform | None:
        """Where LB2.0's ``_spawn_side_prop`` puts the warning sign, or None where it cannot.

        Walking to the ``direction`` side from the trigger point over driving and parking lanes (of either
        direction, as CARLA's ``get_left_lane`` crosses the centre line), the sign stands on the first lane that is
        neither, 0.3 × the last crossed lane's width further out, turned 90 degrees from that lane's heading.
        LB2.0 fails where that lane does not exist (``None.transform``) and never ends the walk where it comes back
        to a lane it crossed (``left`` on a two-way road: the left of lane ∓1 is lane ±1); both give None here.
        """
        prop_wp = self.trigger_waypoint
        seen = {(prop_wp.road_id, prop_wp.lane_id)}
        while True:
            other = neighbour(prop_wp, self.direction)
            if other is None:
                return None
            if not other.lane_type & (LaneType.DRIVING | LaneType.PARKING):
                break
            if (other.road_id, other.lane_id) in seen:
                return None
            seen.add((other.road_id, other.lane_id))
            prop_wp = other
        # the displacement follows prop_wp's right vector (its left for direction=left); the pose is other's
        yaw = math.radians(prop_wp.transform.rotation.yaw)
        out = self.sign * 0.3 * prop_wp.lane_width
        base = other.transform
        loc = Location(base.location.x - math.sin(yaw) * out, base.location.y + math.cos(yaw) * out,
                       base.location.z + 0.2)  # fmt: skip
        return Transform(loc, Rotation(pitch=0.0, yaw=base.rotation.yaw + 90.0, roll=0.0))

    def spawn_warning_sign(self, type_id: str = WARNING_ACCIDENT) -> None:
        """The warning sign at :meth:`warning_sign_transform` (left out, with a warning, where there is none)."""
        transform = self.warning_sign_transform()
        if transform is None:
            log.warning("%s: no lane for the warning sign %s of the trigger point", self.name, self.direction)
            return
        try:
            self.spawn(type_id, transform)
        except ScenarioSetupError as exc:
            log.warning("%s: no warning sign (%s)", self.name, exc)

    def start(self, snapshot: Snapshot) -> None:
        """Leave the stretch up to (and a bit beyond) the obstacle free of background traffic."""
        self.ctx.sim.background.leave_space_in_front(self.distance + self.clear_extra)

    def approach_actor_id(self) -> int | None:
        """The actor whose 50 m proximity starts the reaction."""
        return self.first_id

    def react(self, snapshot: Snapshot) -> None:
        """What happens 5 s after the ego came within 50 m of the obstacle."""

    def hint_extra(self) -> dict[str, float | int | str]:
        """Scenario state the expert may read besides the obstacle actors (none here)."""
        return {}

    def step(self, snapshot: Snapshot) -> None:
        """Per-tick work of the scenario's own actors (flows)."""

    def should_react(self, snapshot: Snapshot, ego: ActorState) -> bool:
        """Whether the reaction starts now: 5 s after the ego came within 50 m of :meth:`approach_actor_id`."""
        watched = self.approach_actor_id()
        actor = snapshot.actors.get(watched) if watched is not None else None
        target = actor.location if actor is not None else self.obstacle_waypoint.transform.location
        return self._approach.check(ego, target) and self._wait.check(snapshot)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Approach → wait → react; SUCCESS once the ego is 50 m past the last obstacle."""
        ego = self.ctx.ego(snapshot)
        self.step(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        if not self.reacting and self.should_react(snapshot, ego):
            self.reacting = True
            self.react(snapshot)
        if self._end_transform is None:
            self._end_transform = move_before_junction(self.end_reference, self.end_distance).transform
        return ScenarioStatus.SUCCESS if is_in_front(ego, self._end_transform) else ScenarioStatus.RUNNING


# ------------------------------------------------------------------------------------------------ reactions


class SpeedCapObstacle(RoadObstacle):
    """One-way multi-lane roads: the obstacle is passed in a same-direction lane; the background slows down."""

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.max_speed = ctx.value("speed", 60.0)

    def check_layout(self) -> None:
        """Needs a same-direction driving lane on the other side to pass the obstacle."""
        other = "left" if self.direction == "right" else "right"
        if same_direction_driving_neighbour(self.obstacle_waypoint, other) is None:
            raise ScenarioSetupError(
                f"{self.name}: layout 'multi_lane' missing: no same-direction driving lane to the {other} of the "
                f"obstacle (road {self.obstacle_waypoint.road_id}, lane {self.obstacle_waypoint.lane_id})"
            )

    def react(self, snapshot: Snapshot) -> None:
        """Cap the background's speed around the obstacle."""
        self.ctx.sim.background.set_max_speed(self.max_speed / 3.6)

    def on_end(self) -> None:
        """Lift the speed cap."""
        super().on_end()
        if self.reacting:
            self.ctx.sim.background.set_max_speed(None)


class OppositeFlowObstacle(RoadObstacle):
    """Two-way roads: the obstacle is passed through the opposite lane, where an opposite flow must be gapped."""

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.frequency = ctx.interval("frequency", (20.0, 100.0))
        self._flow: ActorFlow | None = None
        self._reference_limit: float | None = None

    def flow_anchor(self) -> Waypoint:
        """The lane point whose left lane carries the opposite flow (LB2.0: the obstacle's lane point)."""
        return self.obstacle_waypoint

    def flow_lane(self) -> Waypoint | None:
        """The lane the flow runs on: LB2.0's ``reference_wp = <anchor>.get_left_lane()``, of any type and
        direction (route_obstacles.py ``AccidentTwoWays._create_behavior`` and its twins)."""
        return self.flow_anchor().get_left_lane()

    def check_layout(self) -> None:
        """Needs a lane left of the anchor, LB2.0's only check (``if not reference_wp: raise``).

        Route files put these types on multi-lane roads too (Bench2Drive v0.0.4 validation routes 25783, 25727,
        25986 on Town04): there LB2.0's "opposite" flow drives the ego's way in the lane to its left. Generated
        routes still get real two-way streets from their placement (``obstacles_placement.py``).
        """
        if self.flow_lane() is None:
            anchor = self.flow_anchor()
            raise ScenarioSetupError(
                f"{self.name}: no lane left of road {anchor.road_id} lane {anchor.lane_id} at the obstacle for the "
                "opposite flow"
            )

    def _make_flow(self) -> ActorFlow | None:
        lane = self.flow_lane()
        if lane is None:
            return None
        # walked the lane's own way: an opposite lane's source lies ahead of the obstacle (its "previous")
        return self._flow_along(lane, move_before_junction)

    def ego_speed_limit(self, snapshot: Snapshot) -> float:
        """The speed limit (km/h) at the ego's route point: LB2.0's ``ego.get_speed_limit()``."""
        return float(self.ctx.route.speed_limits[self.ego_route_point(snapshot)])

    def _flow_along(self, lane: Waypoint, walk: Callable[[Waypoint, float, bool], Waypoint]) -> ActorFlow | None:
        """LB2.0's OppositeActorFlow on ``lane``: source and sink ``1.5 × limit [km/h] + 30`` m back and on (by
        ``walk``), cars at the limit; the limit is the ego's when the flow starts (the map's at the obstacle before
        that). None (logged) when no path joins source and sink."""
        limit = self._reference_limit
        if limit is None:
            limit = self.ctx.map.speed_limit(self.obstacle_waypoint)
        reach = 1.5 * limit + 30.0
        source, sink = walk(lane, reach, False), walk(lane, reach, True)
        try:
            path = flow_path(source, sink, 2.0 * reach + 50.0)
        except ScenarioSetupError as exc:
            log.warning("%s: no flow (%s)", self.name, exc)
            return None
        return ActorFlow(self.ctx.sim, self.ctx.rng, path, limit / 3.6, self.frequency, constant_velocity=False)

    def hint_extra(self) -> dict[str, float | int | str]:
        """``opposite_lane_open``: 1 once the wrong-direction test is off (the reaction), else 0."""
        return {OPPOSITE_LANE_OPEN: int(self.reacting)}

    def react(self, snapshot: Snapshot) -> None:
        """Allow the wrong direction, pause the normal opposite traffic, start the opposite flow."""
        self.request_switch(SWITCH_WRONG_DIRECTION, False)
        self.ctx.sim.background.change_opposite_behavior(active=False)
        # OppositeActorFlow.initialise reads the ego's speed limit when the flow starts
        self._reference_limit = self.ego_speed_limit(snapshot)
        self._flow = self._make_flow()
        if self._flow is not None:
            self._flow.start()

    def step(self, snapshot: Snapshot) -> None:
        """Drive the opposite flow."""
        if self._flow is not None:
            self._flow.update(snapshot)

    def on_end(self) -> None:
        """Stop the flow and restore the opposite traffic and the wrong-direction test."""
        super().on_end()
        if self._flow is not None:
            self._flow.stop()
        if self.reacting:
            try:
                self.ctx.sim.background.change_opposite_behavior(active=True)
            except SimulatorError as exc:
                log.warning("%s: could not restore opposite traffic: %s", self.name, exc)
            self.request_switch(SWITCH_WRONG_DIRECTION, True)


# ------------------------------------------------------------------------------------------------ obstacle sites


class ParkedCarSite(RoadObstacle):
    """A parked car with its hazard lights on, pushed 35 % of the lane width to the obstacle side (§2.2 #5, #6)."""

    clear_extra = 20.0
    side_offset = 0.35

    def build(self) -> None:
        """Warning sign and the parked car with its hazard lights on."""
        self.spawn_warning_sign()
        car = self.spawn_obstacle_vehicle(random_parked_car(self.ctx.rng), self.obstacle_waypoint)
        self.ctx.sim.set_light_state(car, HAZARD_LIGHTS)
        self.first_id = car

    def hint(self) -> ScenarioHint | None:
        """The parked car (no last actor), obstacle side."""
        if self.first_id is None:
            return None
        return ScenarioHint(self.xml_type, self.first_id, None, direction=self.direction, extra=self.hint_extra())


class AccidentSite(RoadObstacle):
    """A police car with its lights on and two crashed cars 10 m and 16 m beyond it (§2.2 #9, #10)."""

    clear_extra = 36.0
    side_offset = 0.3  # offset 0.6 × half lane width
    first_gap = 10.0
    second_gap = 6.0

    def __init__(self, ctx: ScenarioContext) -> None:
        self._crashed: list[int] = []
        super().__init__(ctx)

    def place_site(self) -> None:
        """The crashed cars 10 m and 6 m on, each walk stopping before a junction (LB2.0 ``_move_waypoint_forward``)."""
        first = move_before_junction(self.obstacle_waypoint, self.first_gap)
        second = move_before_junction(first, self.second_gap)
        self._car_waypoints = (first, second)
        self.end_reference = second

    def flow_anchor(self) -> Waypoint:
        """LB2.0 AccidentTwoWays anchors the flow beside the second crashed car (``self._accident_wp``)."""
        return self._car_waypoints[1]

    def build(self) -> None:
        """Warning sign, police car with its lights on, two crashed cars."""
        self.spawn_warning_sign()
        police = self.spawn_obstacle_vehicle(POLICE_CAR, self.obstacle_waypoint)
        self.ctx.sim.set_light_state(police, POLICE_ACCIDENT_LIGHTS)
        for wp in self._car_waypoints:
            self._crashed.append(self.spawn_obstacle_vehicle(random_parked_car(self.ctx.rng), wp))
        self.first_id, self.last_id = police, self._crashed[-1]

    def approach_actor_id(self) -> int | None:
        """The reaction starts 5 s after the ego came within 50 m of the first crashed car."""
        return self._crashed[0] if self._crashed else self.first_id

    def hint(self) -> ScenarioHint | None:
        """Police car → last crashed car, obstacle side."""
        if self.first_id is None:
            return None
        return ScenarioHint(self.xml_type, self.first_id, self.last_id, direction=self.direction,
                            extra=self.hint_extra())


class ConstructionSite(RoadObstacle):
    """A lane closed by a construction site (§2.2 #7, #8), LB2.0's ``_create_construction_setup``.

    The site point is ``next(distance)[0]`` from the trigger point. From its pose, in straight lines: a
    traffic-warning board 5 m back (yaw + 270), dirt debris 2 m on (yaw + 90, 1 m up), and cones starting
    0.85 × half the trigger lane's width to the passing side: 4 cones 2 m apart straight on, then 3 cones 1 m apart
    across toward the obstacle side, the closed lane's outline as the ego passes it. The reaction waits for the
    ego within 30 m of the site point; the scenario ends 50 m past it. The ego's lane is taken out of the
    background traffic while the scenario runs, and the stretch up to 20 m past the site is cleared at the trigger
    (LB2.0 only removes the lane; see :meth:`start`).
    """

    #: LB2.0's default ``distance`` of both construction types (construction_crash_vehicle.py), not 120 m.
    default_distance = 100.0
    jumps_to_obstacle = True
    clear_extra = 20.0
    trigger_distance = 30.0
    board_before = 5.0
    debris_after = 2.0
    edge_cones = 4
    edge_gap = 2.0
    across_cones = 3
    across_gap = 1.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self._removed_lane = False

    def approach_actor_id(self) -> int | None:
        """None: LB2.0 watches the site point itself (``InTriggerDistanceToLocation(construction_wp)``)."""
        return None

    def board_transform(self) -> Transform:
        """The traffic-warning board: 5 m back from the site point along its heading, turned by 180 + 90 degrees."""
        return offset_transform(self.obstacle_waypoint, forward=-self.board_before, yaw=270.0)

    def debris_transform(self) -> Transform:
        """The debris: 2 m on from the site point, 1 m up, turned by 90 degrees."""
        return offset_transform(self.obstacle_waypoint, forward=self.debris_after, z=1.0, yaw=90.0)

    def cone_transforms(self) -> list[Transform]:
        """Where the cones stand: straight on along the passing-side edge, then across toward the obstacle side."""
        edge = -self.sign * 0.85 * self.trigger_waypoint.lane_width / 2.0
        along = [offset_transform(self.obstacle_waypoint, lateral=edge, forward=self.edge_gap * (k + 1), z=0.1)
                 for k in range(self.edge_cones)]  # fmt: skip
        ahead = self.edge_gap * self.edge_cones
        across = [
            offset_transform(self.obstacle_waypoint, lateral=edge + self.sign * self.across_gap * (k + 1),
                             forward=ahead, z=0.1, yaw=self.sign * 90.0)
            for k in range(self.across_cones)
        ]  # fmt: skip
        return along + across

    def build(self) -> None:
        """Construction warning sign at the road's edge (the site itself appears at the trigger)."""
        self.spawn_warning_sign(WARNING_CONSTRUCTION)

    def start(self, snapshot: Snapshot) -> None:
        """Clear the stretch, take the ego's lane out of the background traffic, put the site up.

        LB2.0 spawns the board, the debris and the cones at build 200 m underground and lifts them into place at
        the trigger (construction_crash_vehicle.py); here they are spawned at the trigger, once the lane is clear.
        """
        # Not LB2.0 (RemoveRoadLane only): our remove_road_lane misses a car ahead on the route under another lane
        # key, which then stood before the cones with the ego waiting behind it until TickRuntime (route 41030001,
        # Town100, seed 41)
        super().start(snapshot)
        self.ctx.sim.background.remove_road_lane(self.trigger_waypoint)
        self._removed_lane = True
        board = self.board_transform()
        self.first_id = self.spawn(TRAFFIC_WARNING, board, retries=[offset_transform(board, lateral=-1.0)])
        self._spawn_prop(DEBRIS, self.debris_transform())
        for transform in self.cone_transforms():
            self.last_id = self._spawn_prop(CONSTRUCTION_CONE, transform) or self.last_id

    def _spawn_prop(self, type_id: str, transform: Transform) -> int | None:
        """One prop of the site; a place taken at the trigger (a car on the lane edge) leaves that prop out."""
        try:
            return self.spawn(type_id, transform)
        except ScenarioSetupError as exc:
            log.warning("%s: %s", self.name, exc)
            return None

    def on_end(self) -> None:
        """Give the lane back to the background traffic."""
        super().on_end()
        if self._removed_lane:
            self.ctx.sim.background.readd_road_lane(0)

    def hint(self) -> ScenarioHint | None:
        """Warning board → last cone, obstacle side."""
        if self.first_id is None:
            return None
        return ScenarioHint(self.xml_type, self.first_id, self.last_id, direction=self.direction,
                            extra=self.hint_extra())


# ------------------------------------------------------------------------------------------------ the types


@register
class ParkedObstacle(ParkedCarSite, SpeedCapObstacle):
    """A parked car with hazard lights blocks the ego's lane of a multi-lane road (§2.2 #5)."""

    xml_type = "ParkedObstacle"


@register
class ParkedObstacleTwoWays(ParkedCarSite, OppositeFlowObstacle):
    """A parked car with hazard lights blocks the ego's lane of a two-way road; an opposite flow must be gapped
    (§2.2 #6)."""

    xml_type = "ParkedObstacleTwoWays"


@register
class ConstructionObstacle(ConstructionSite, SpeedCapObstacle):
    """A construction site closes the ego's lane of a multi-lane road (§2.2 #7)."""

    xml_type = "ConstructionObstacle"


@register
class ConstructionObstacleTwoWays(ConstructionSite, OppositeFlowObstacle):
    """A construction site closes the ego's lane of a two-way road; an opposite flow must be gapped (§2.2 #8)."""

    xml_type = "ConstructionObstacleTwoWays"


@register
class Accident(AccidentSite, SpeedCapObstacle):
    """A police car and two crashed cars block the ego's lane of a multi-lane road (§2.2 #9)."""

    xml_type = "Accident"


@register
class AccidentTwoWays(AccidentSite, OppositeFlowObstacle):
    """An accident blocks the ego's lane of a two-way road; an opposite flow must be gapped (§2.2 #10)."""

    xml_type = "AccidentTwoWays"
