"""Turns through crossing traffic (§2.2 #23, #25, #27, #28): the signalised and unsignalised left and right turns.

A constant-speed :class:`~b2d_data.scenarios.catalog.flows.ActorFlow` crosses the junction straight; the ego
must find a gap. Left turn: the flow comes from the opposite entry (a random lane of it), its source
``4 × flow_speed`` m before the junction and its sink ``2.5 × flow_speed`` m after. Right turn: the flow comes from
the left entry's rightmost lane, ``5 × flow_speed`` m before to ``3 × flow_speed`` m after, pre-populated. On
signalised junctions the ego's light is red for 5 s while the flow's is green, then both are green; on unsignalised
ones the background stops the junction's other entries. All end 10 m after the ego left the junction, or after 240 s.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import ClassVar

from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.flows import FlowScenario
from b2d_data.scenarios.catalog.junctions import (
    JunctionScenario,
    LightSchedule,
    junction_flow_path,
    light_states,
    lights_of_lane,
    rightmost_driving,
)
from b2d_data.scenarios.catalog.layout import CHECK_STEP, Layout, register_layouts
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    connection,
    entries_from,
    flow_into_exit,
    move_along,
    same_direction_lanes,
    straightest_connection,
)
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, register
from b2d_data.scenarios.triggers import DriveDistance, WaitEndIntersection
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


class JunctionFlowTurn(FlowScenario, JunctionScenario):
    """Common part: the flow, the end condition and the background preparation."""

    flow_direction: ClassVar[str] = "opposite"
    source_factor: ClassVar[float] = 4.0
    sink_factor: ClassVar[float] = 2.5
    initial_actors: ClassVar[bool] = False
    signalized: ClassVar[bool] = True
    end_distance: ClassVar[float] = 10.0
    green_light_delay: ClassVar[float] = 5.0
    default_flow_speed: ClassVar[float] = 20.0
    default_interval: ClassVar[tuple[float, float]] = (25.0, 50.0)

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        entries = entries_from(self.lanes, self.ego_entry, self.flow_direction)
        if not entries:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: junction {self.junction.id} has no entry from the {self.flow_direction}"
            )
        self.sink_distance = self.sink_factor * self.flow_speed
        options, preferred = [], []
        for entry in self.entry_choices(entries):
            conn = self.flow_connection(entry)
            if conn is None:
                continue
            try:
                path = junction_flow_path(conn, self.source_factor * self.flow_speed, self.sink_distance)
            except ScenarioSetupError:
                continue
            options.append((entry, path))
            if self.preferred(conn):
                preferred.append((entry, path))
        # entries whose flow really goes straight first (generated routes' builds pick as before); the others only
        # where no entry does, as LB2.0 would then still build (``generate_target_waypoint`` has no angle limit)
        options = preferred or options
        if not options:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: no {self.flow_direction} entry of junction {self.junction.id} "
                f"{self.flow_move} for {self.sink_distance:.0f} m"
            )
        self.source_entry, self.path = self.pick(options)
        self.source, self.sink = self.path[0], self.path[-1]
        self.lights: LightSchedule | None = None
        self._left = WaitEndIntersection(ctx.map, self.junction.id)
        self._after = DriveDistance(self.end_distance)

    def entry_choices(self, entries: list[Waypoint]) -> list[Waypoint]:
        """The entry lanes the flow may use."""
        return entries

    @property
    def flow_move(self) -> str:
        """What the flow does through the junction, for error messages."""
        return "goes straight on"

    def flow_connection(self, entry: Waypoint) -> JunctionLane | None:
        """The flow's way through the junction from ``entry``: LB2.0's ``generate_target_waypoint(source, 0)``, the
        straightest branch at any angle (signalized_junction_left_turn.py / _right_turn.py ``_initialize_actors``),
        None only where the lane has no connection."""
        return straightest_connection(self.lanes, entry)

    def preferred(self, conn: JunctionLane) -> bool:
        """Whether the flow's connection is the kind the scenario is about (straight on), chosen before others."""
        return conn.turn == "straight"

    def pick(self, options: list[tuple[Waypoint, list[Waypoint]]]) -> tuple[Waypoint, list[Waypoint]]:
        """Which of the usable entries (with their flow paths) the flow takes."""
        return options[0]

    def build(self) -> None:
        """Check that a signalised version's junction has lights."""
        if self.signalized:
            self.require_lights(self.ctx.sim.snapshot())

    def light_phases(self, snapshot: Snapshot) -> LightSchedule | None:
        """Signalised versions: ego red and flow green for 5 s, then both green; others red."""
        if not self.signalized:
            return None
        lights = self.require_lights(snapshot)
        ego_lights = lights_of_lane(lights, self.ego_entry)
        flow_lights = lights_of_lane(lights, self.source_entry)
        first = light_states(lights, flow_lights)
        second = light_states(lights, [*ego_lights, *flow_lights])
        return LightSchedule(self.ctx.sim, [(first, self.green_light_delay), (second, None)])

    def start_flows(self, snapshot: Snapshot) -> None:
        """Start the flow and the light schedule."""
        self.add_flow(self.path, initial_actors=self.initial_actors)
        self.lights = self.light_phases(snapshot)
        if self.lights is not None:
            self.lights.update(snapshot)

    def step(self, snapshot: Snapshot) -> None:
        """Run the light schedule."""
        if self.lights is not None:
            self.lights.update(snapshot)

    def finished(self, snapshot: Snapshot) -> bool:
        """10 m after the ego left the junction."""
        ego = self.ctx.ego(snapshot)
        return ego is not None and self._left.check(ego) and self._after.check(ego)

    def restore_background(self) -> None:
        """Release the lights."""
        if self.lights is not None:
            self.lights.release()


class LeftTurnAcrossFlow(JunctionFlowTurn):
    """Left turn across an oncoming flow (§2.2 #23, #25); the signalised version forces the lights."""

    required_turn = ("left",)
    flow_direction = "opposite"
    source_factor = 4.0
    sink_factor = 2.5
    opposite_off = True

    def pick(self, options: list[tuple[Waypoint, list[Waypoint]]]) -> tuple[Waypoint, list[Waypoint]]:
        """A random lane among those facing the ego."""
        return options[int(self.ctx.rng.integers(len(options)))]

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Clear the junction, remove the flow's lanes (unsignalised: stop entries); the opposite traffic pauses."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=same_direction_lanes(self.source),
            remove_exits=same_direction_lanes(self.sink), stop_entries=not self.signalized,
            extend_road_exit=self.sink_distance + 20.0,
        )  # fmt: skip


@register
class SignalizedJunctionLeftTurn(LeftTurnAcrossFlow):
    """Left turn across an oncoming flow at a signalised junction (§2.2 #23)."""

    xml_type = "SignalizedJunctionLeftTurn"
    signalized = True


@register
class NonSignalizedJunctionLeftTurn(LeftTurnAcrossFlow):
    """Left turn across an oncoming flow at an unsignalised junction, other entries stopped (§2.2 #25)."""

    xml_type = "NonSignalizedJunctionLeftTurn"
    signalized = False


class LeftTurnEnterFlow(LeftTurnAcrossFlow):
    """Bench2Drive's left turn into a flow: the opposite flow turns right into the ego's exit road (§2.2 #24, #26)."""

    @property
    def flow_move(self) -> str:
        """What the flow does through the junction, for error messages."""
        return "turns right into the ego's exit road"

    def flow_connection(self, entry: Waypoint) -> JunctionLane | None:
        """The right turn from ``entry`` that ends on the ego's exit road."""
        return flow_into_exit(self.lanes, entry, self.ego_exit)

    def preferred(self, conn: JunctionLane) -> bool:
        """Every right turn into the ego's exit road is the scenario's flow."""
        return True


@register
class SignalizedJunctionLeftTurnEnterFlow(LeftTurnEnterFlow):
    """Left turn at a signalised junction, merging into the opposite flow turning right (§2.2 #24)."""

    xml_type = "SignalizedJunctionLeftTurnEnterFlow"
    signalized = True


@register
class NonSignalizedJunctionLeftTurnEnterFlow(LeftTurnEnterFlow):
    """Left turn at an unsignalised junction, merging into the opposite flow turning right (§2.2 #26)."""

    xml_type = "NonSignalizedJunctionLeftTurnEnterFlow"
    signalized = False


class RightTurnIntoFlow(JunctionFlowTurn):
    """Right turn into a pre-populated flow from the left entry's rightmost lane (§2.2 #27, #28)."""

    required_turn = ("right",)
    flow_direction = "left"
    source_factor = 5.0
    sink_factor = 3.0
    initial_actors = True

    def entry_choices(self, entries: list[Waypoint]) -> list[Waypoint]:
        """The rightmost driving lane of the left entry."""
        return [rightmost_driving(entries[0])]

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Clear the junction, remove the flow's entry lanes; unsignalised: stop the other entries."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=same_direction_lanes(self.source),
            remove_exits=[], stop_entries=not self.signalized, extend_road_exit=self.sink_distance + 20.0,
        )  # fmt: skip


@register
class SignalizedJunctionRightTurn(RightTurnIntoFlow):
    """Right turn into a flow coming from the left at a signalised junction (§2.2 #27)."""

    xml_type = "SignalizedJunctionRightTurn"
    signalized = True


@register
class NonSignalizedJunctionRightTurn(RightTurnIntoFlow):
    """Right turn into a flow coming from the left at an unsignalised junction (§2.2 #28)."""

    xml_type = "NonSignalizedJunctionRightTurn"
    signalized = False


# ------------------------------------------------------------------------------------------------ placement


def _flow_from(direction: str) -> Callable[[JunctionLane, list[JunctionLane]], list[dict[str, dict[str, str]]]]:
    def check(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
        for entry in entries_from(lanes, conn.entry, direction):
            straight = connection(lanes, entry, "straight")
            if straight is not None and move_along(straight.exit, 45.0, step=CHECK_STEP) is not None:
                return [{}]
        return []

    return check


def _flow_into_ego_exit(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """An opposite entry turning right onto the road the ego turns left into."""
    for entry in entries_from(lanes, conn.entry, "opposite"):
        if flow_into_exit(lanes, entry, conn.exit) is not None:
            return [{}]
    return []


register_layouts({
    "SignalizedJunctionLeftTurn": Layout(
        "signalized_junction", "a signalised junction where the route turns left, with an opposite entry going "
        "straight", turns=("left",), signalized=True, junction_extra=_flow_from("opposite")),
    "NonSignalizedJunctionLeftTurn": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns left, with an opposite entry going "
        "straight", turns=("left",), signalized=False, junction_extra=_flow_from("opposite")),
    "SignalizedJunctionLeftTurnEnterFlow": Layout(
        "signalized_junction", "a signalised junction where the route turns left, with an opposite entry turning "
        "right into the same road", turns=("left",), signalized=True, junction_extra=_flow_into_ego_exit),
    "NonSignalizedJunctionLeftTurnEnterFlow": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns left, with an opposite entry "
        "turning right into the same road", turns=("left",), signalized=False, junction_extra=_flow_into_ego_exit),
    "SignalizedJunctionRightTurn": Layout(
        "signalized_junction", "a signalised junction where the route turns right, with a left entry going "
        "straight", turns=("right",), signalized=True, junction_extra=_flow_from("left")),
    "NonSignalizedJunctionRightTurn": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns right, with a left entry going "
        "straight", turns=("right",), signalized=False, junction_extra=_flow_from("left")),
})  # fmt: skip
