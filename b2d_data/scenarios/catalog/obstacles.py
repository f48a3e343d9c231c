"""Static obstacles on the ego's lane that must be overtaken (§2.2 #5–#10): ParkedObstacle(TwoWays),
ConstructionObstacle(TwoWays), Accident(TwoWays).

Shared mechanics (LB2.0 ``route_obstacles.py``): the obstacle stands ``distance`` m after the trigger point, pushed
toward the ``direction`` side of the lane; a warning sign stands at the road's edge near the trigger point; at the
trigger the background leaves the stretch up to the obstacle free; once the ego is within 50 m of the obstacle and
5 s have passed, the scenario's own reaction starts (background speed cap, or the opposite flow on two-way roads);
the scenario ends when the ego has passed a point 50 m beyond the last obstacle, or after the 240 s timeout.

Each type combines an obstacle site (what stands on the lane: :class:`ParkedCarSite`, :class:`ConstructionSite`,
:class:`AccidentSite`) with a reaction (multi-lane roads: :class:`SpeedCapObstacle`; two-way roads:
:class:`OppositeFlowObstacle`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import ClassVar

from b2d_data.format.transform import Transform
from b2d_data.maps import LaneType, Waypoint
from b2d_data.scenarios.catalog.actor_choices import (
    CONSTRUCTION_CONE,
    DEBRIS,
    HAZARD_LIGHTS,
    POLICE_CAR,
    SIREN_LIGHTS,
    TRAFFIC_WARNING,
    WARNING_ACCIDENT,
    WARNING_CONSTRUCTION,
    random_parked_car,
)
from b2d_data.scenarios.catalog.flows import ActorFlow, flow_path
from b2d_data.scenarios.catalog.road_geometry import (
    move_along,
    neighbour,
    offset_transform,
    opposite_driving_neighbour,
    same_direction,
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
from b2d_data.sim.api import ActorState, ScenarioHint, SimulatorError, Snapshot

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

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.distance = ctx.value("distance", self.default_distance)
        self.direction = ctx.text("direction", "right")
        if self.direction not in ("left", "right"):
            raise ScenarioSetupError(f"{self.name}: direction must be 'left' or 'right', got {self.direction!r}")
        self.sign = 1.0 if self.direction == "right" else -1.0
        wp = move_along(self.trigger_waypoint, self.distance)
        if wp is None or wp.is_junction:
            raise ScenarioSetupError(
                f"{self.name}: no junction-free lane {self.distance:.0f} m after the trigger point for the obstacle"
            )
        self.obstacle_waypoint: Waypoint = wp
        self.check_layout()
        self.first_id: int | None = None
        self.last_id: int | None = None
        self.end_reference = wp
        self._approach = DistanceTrigger(self.trigger_distance)
        self._wait = Timer(self.wait_duration)
        self._end_transform: Transform | None = None
        self.reacting = False

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

    def spawn_warning_sign(self, type_id: str = WARNING_ACCIDENT) -> None:
        """A warning sign just beyond the outer edge of the outermost driving/parking lane near the trigger point."""
        wp = self.trigger_waypoint
        lateral = 0.0
        current = wp
        while True:
            other = neighbour(current, self.direction)
            if other is None or not same_direction(current, other):
                break
            if not other.lane_type & (LaneType.DRIVING | LaneType.PARKING):
                break
            lateral += 0.5 * (current.lane_width + other.lane_width)
            current = other
        lateral += 0.5 * current.lane_width + 0.6
        transforms = [offset_transform(wp, lateral=self.sign * lateral, forward=f, yaw=180.0) for f in (0.0, 2.0, 4.0)]
        try:
            self.spawn(type_id, transforms[0], retries=transforms[1:])
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
            end = move_along(self.end_reference, self.end_distance)
            self._end_transform = (end or self.end_reference).transform
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

    def check_layout(self) -> None:
        """Needs an opposite-direction driving lane to the left of the ego's lane."""
        if opposite_driving_neighbour(self.obstacle_waypoint) is None:
            raise ScenarioSetupError(
                f"{self.name}: layout 'two_way_street' missing: no opposite driving lane left of road "
                f"{self.obstacle_waypoint.road_id} lane {self.obstacle_waypoint.lane_id} at the obstacle"
            )

    def _make_flow(self) -> ActorFlow | None:
        opposite = opposite_driving_neighbour(self.obstacle_waypoint)
        if opposite is None:
            return None
        # the opposite lane drives against the ego: its source lies ahead of the obstacle (its "previous")
        return self._flow_along(opposite, lambda wp, d, forward: move_along(wp, d, forward=forward) or wp)

    def _flow_along(self, lane: Waypoint, walk: Callable[[Waypoint, float, bool], Waypoint]) -> ActorFlow | None:
        """LB2.0's OppositeActorFlow on ``lane``: source and sink ``1.5 × limit [km/h] + 30`` m back and on (by
        ``walk``), cars at the limit at the obstacle; None (logged) when no path joins them."""
        limit = self.ctx.map.speed_limit(self.obstacle_waypoint)
        reach = 1.5 * limit + 30.0
        source, sink = walk(lane, reach, False), walk(lane, reach, True)
        try:
            path = flow_path(source, sink, 2.0 * reach + 50.0)
        except ScenarioSetupError as exc:
            log.warning("%s: no flow (%s)", self.name, exc)
            return None
        return ActorFlow(self.ctx.sim, self.ctx.rng, path, limit / 3.6, self.frequency, constant_velocity=False)

    def react(self, snapshot: Snapshot) -> None:
        """Allow the wrong direction, pause the normal opposite traffic, start the opposite flow."""
        self.request_switch(SWITCH_WRONG_DIRECTION, False)
        self.ctx.sim.background.change_opposite_behavior(active=False)
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
        return ScenarioHint(self.xml_type, self.first_id, None, direction=self.direction)


class AccidentSite(RoadObstacle):
    """A police car with its lights on and two crashed cars 10 m and 16 m beyond it (§2.2 #9, #10)."""

    clear_extra = 36.0
    side_offset = 0.3  # offset 0.6 × half lane width
    first_gap = 10.0
    second_gap = 6.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        first = move_along(self.obstacle_waypoint, self.first_gap)
        second = move_along(first, self.second_gap) if first is not None else None
        if first is None or second is None or first.is_junction or second.is_junction:
            raise ScenarioSetupError(f"{self.name}: the accident needs 16 m of junction-free lane after the police car")
        self._car_waypoints = (first, second)
        self.end_reference = second
        self._crashed: list[int] = []

    def build(self) -> None:
        """Warning sign, police car with its lights on, two crashed cars."""
        self.spawn_warning_sign()
        police = self.spawn_obstacle_vehicle(POLICE_CAR, self.obstacle_waypoint)
        self.ctx.sim.set_light_state(police, SIREN_LIGHTS)
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
        return ScenarioHint(self.xml_type, self.first_id, self.last_id, direction=self.direction)


class ConstructionSite(RoadObstacle):
    """A lane closed by a construction site (§2.2 #7, #8), LB2.0's ``_create_construction_setup``.

    A traffic-warning board stands on the lane 5 m before the site, dirt debris 2 m after it; 4 cones run 2 m apart
    along the lane edge on the passing side (0.85 × half the lane width out), then 3 cones 1 m apart back across the
    lane toward the obstacle side: the closed lane's outline as the ego passes it.
    The ego's lane is taken out of the background traffic while the scenario runs.
    """

    #: LB2.0's default ``distance`` of both construction types (construction_crash_vehicle.py), not 120 m.
    default_distance = 100.0
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
        board = move_along(self.obstacle_waypoint, self.board_before, forward=False)
        along = self.edge_cones * self.edge_gap
        end = move_along(self.obstacle_waypoint, along)
        if board is None or end is None or board.is_junction or end.is_junction:
            raise ScenarioSetupError(
                f"{self.name}: the construction site needs {self.board_before + along:.0f} m of junction-free lane"
            )
        self._board_waypoint = board
        self.end_reference = end
        self._removed_lane = False

    def cone_transforms(self) -> list[Transform]:
        """Where the cones stand: along the lane edge away from the obstacle side, then across toward that side."""
        wp = self.obstacle_waypoint
        edge = -self.sign * 0.85 * wp.lane_width / 2.0
        out = []
        current: Waypoint | None = wp
        for _ in range(self.edge_cones):
            current = move_along(current, self.edge_gap) if current is not None else None
            if current is None:
                break
            out.append(offset_transform(current, lateral=edge))
        last = current or wp
        out += [offset_transform(last, lateral=edge + self.sign * self.across_gap * (k + 1))
                for k in range(self.across_cones)]  # fmt: skip
        return out

    def build(self) -> None:
        """Construction warning sign at the road's edge (the site itself appears at the trigger)."""
        self.spawn_warning_sign(WARNING_CONSTRUCTION)

    def start(self, snapshot: Snapshot) -> None:
        """Clear the stretch, take the ego's lane out of the background traffic, put the site up.

        LB2.0 spawns the board, the debris and the cones at build 200 m underground and lifts them into place at
        the trigger (construction_crash_vehicle.py); here they are spawned at the trigger, once the stretch is clear.
        """
        super().start(snapshot)
        self.ctx.sim.background.remove_road_lane(self.trigger_waypoint)
        self._removed_lane = True
        board = offset_transform(self._board_waypoint, yaw=180.0)
        self.first_id = self.spawn(TRAFFIC_WARNING, board, retries=[offset_transform(board, forward=-1.0)])
        debris = move_along(self.obstacle_waypoint, self.debris_after) or self.obstacle_waypoint
        self._spawn_prop(DEBRIS, offset_transform(debris))
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
        return ScenarioHint(self.xml_type, self.first_id, self.last_id, direction=self.direction)


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
