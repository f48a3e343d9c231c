"""Interurban junctions with fast actor flows (§2.2 #33, #34): InterurbanActorFlow, InterurbanAdvancedActorFlow.

InterurbanActorFlow: the ego leaves an interurban road by turning left at an unsignalised junction, across a constant-speed flow on the
opposite lane that runs from the XML's ``start_actor_flow`` to ``end_actor_flow`` (not pre-populated). The ego's
entry, the flow's entry and the other entries are removed from background traffic and the opposite background is
paused. The scenario ends when the ego has left the junction, or after 240 s.

InterurbanAdvancedActorFlow: the ego enters an interurban road by turning left from a side road. Flow 1 runs from
``start_actor_flow`` to ``end_actor_flow`` across the ego's path; flow 2 runs the other way on the lane left of flow
1's sink to the lane left of its source, the lane the ego merges into. Both at ``flow_speed``. Every other junction
entry and exit is removed from background traffic, the route sources are off and the opposite traffic paused; the
scenario ends when the ego passes flow 2's sink, or after 240 s.
"""

from __future__ import annotations

import logging

from b2d_data.format.transform import Location
from b2d_data.maps import Map, Waypoint
from b2d_data.scenarios.catalog.flows import ActorFlow, flow_path
from b2d_data.scenarios.catalog.junctions import JunctionScenario, walk_back_to_source
from b2d_data.scenarios.catalog.layout import CHECK_STEP, Layout, register_layouts, signal_lanes, xml_location
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    connection,
    entries_from,
    is_driving,
    move_along,
    same_direction_lanes,
)
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import WaitEndIntersection
from b2d_data.sim.api import ScenarioHint, Snapshot

log = logging.getLogger(__name__)


def location_parameter(ctx: ScenarioContext, tag: str) -> Location:
    """A ``<tag x=".." y=".." z=".."/>`` parameter; a missing or non-numeric one raises naming the tag."""
    raw = [ctx.config.parameter(tag, axis) for axis in ("x", "y", "z")]
    if raw[0] is None or raw[1] is None:
        raise ScenarioSetupError(f"{ctx.config.name}: parameter <{tag} x=.. y=.. z=..> is missing")
    try:
        return Location(float(raw[0]), float(raw[1]), float(raw[2] or 0.0))
    except ValueError:
        raise ScenarioSetupError(f"{ctx.config.name}: parameter <{tag}> has a non-numeric coordinate") from None


def flow_lane_path(ctx: ScenarioContext, start_tag: str = "start_actor_flow", end_tag: str = "end_actor_flow"):
    """The flow's lane path from the XML's source to its sink (1 m steps, straight through junctions)."""
    source = ctx.map.get_waypoint(location_parameter(ctx, start_tag))
    sink = ctx.map.get_waypoint(location_parameter(ctx, end_tag))
    if source is None or sink is None:
        raise ScenarioSetupError(f"{ctx.config.name}: the actor flow's source or sink is off the road")
    try:
        return flow_path(source, sink)
    except ScenarioSetupError as exc:
        straight_error = exc
    # the sink is not straight on (e.g. Town06's entries, where the flow keeps to a lane that forks off): plan the
    # way as scenario_runner's ActorFlow does, with the route planner
    planned = [wp for wp, _ in ctx.map.interpolate_trajectory(
        [source.transform.location, sink.transform.location], hop_resolution=1.0)]  # fmt: skip
    if len(planned) < 2 or planned[-1].transform.location.distance_2d(sink.transform.location) > 3.0:
        raise ScenarioSetupError(f"{ctx.config.name}: {straight_error}") from None
    return planned


@register
class InterurbanActorFlow(JunctionScenario):
    """Left turn off an interurban road across a fast oncoming flow (§2.2 #33)."""

    xml_type = "InterurbanActorFlow"
    required_turn = ("left",)

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.flow_speed = ctx.value("flow_speed", 10.0)
        self.interval = ctx.interval("source_dist_interval", (20.0, 50.0))
        self.path: list[Waypoint] = flow_lane_path(ctx)
        if not any(wp.is_junction and wp.junction_id == self.junction.id for wp in self.path):
            raise ScenarioSetupError(
                f"{self.name}: layout missing: the actor flow does not cross junction {self.junction.id}"
            )
        self.flow: ActorFlow | None = None
        self._left = WaitEndIntersection(ctx.map, self.junction.id)

    def start(self, snapshot: Snapshot) -> None:
        """Remove the junction's entries from background traffic, pause the opposite traffic, start the flow."""
        bg = self.ctx.sim.background
        entries = {(c.entry.road_id, c.entry.lane_id): c.entry for c in self.lanes}
        bg.handle_junction_scenario(
            clear_junction=False, clear_ego_entry=True,
            remove_entries=[*entries.values(), *same_direction_lanes(self.path[0])], remove_exits=[],
            stop_entries=False, extend_road_exit=0.0,
        )  # fmt: skip
        bg.change_opposite_behavior(active=False)
        self.flow = ActorFlow(self.ctx.sim, self.ctx.rng, self.path, self.flow_speed, self.interval)
        self.flow.start()

    def hint(self) -> ScenarioHint | None:
        """A hint of the scenario's type: its flow's cars never brake for the ego (the expert's flow checks)."""
        return ScenarioHint(self.xml_type, None, None)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Drive the flow; SUCCESS once the ego has left the junction."""
        if self.flow is not None:
            self.flow.update(snapshot)
        ego = self.ctx.ego(snapshot)
        if ego is not None and self._left.check(ego):
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Stop the flow and restore the opposite traffic."""
        if self.flow is not None:
            self.flow.stop()
            self.ctx.sim.background.change_opposite_behavior(active=True)


def _opposite(wp: Waypoint, name: str) -> Waypoint:
    """The driving lane left of ``wp`` across the centre line (raises naming the scenario when there is none)."""
    other = wp.get_left_lane()
    if other is None or not is_driving(other) or other.lane_id * wp.lane_id > 0:
        raise ScenarioSetupError(f"{name}: layout missing: no opposite lane beside road {wp.road_id} lane {wp.lane_id}")
    return other


@register
class InterurbanAdvancedActorFlow(JunctionScenario):
    """Left turn onto an interurban road across one fast flow and into another (§2.2 #34)."""

    xml_type = "InterurbanAdvancedActorFlow"
    required_turn = ("left",)

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.flow_speed = ctx.value("flow_speed", 10.0)
        self.interval = ctx.interval("source_dist_interval", (20.0, 50.0))
        self.path_1: list[Waypoint] = flow_lane_path(ctx)
        if not any(wp.is_junction and wp.junction_id == self.junction.id for wp in self.path_1):
            raise ScenarioSetupError(f"{self.name}: layout missing: flow 1 does not cross junction {self.junction.id}")
        source_2, sink_2 = _opposite(self.path_1[-1], self.name), _opposite(self.path_1[0], self.name)
        try:
            self.path_2: list[Waypoint] = flow_path(source_2, sink_2)
        except ScenarioSetupError as exc:
            raise ScenarioSetupError(f"{self.name}: flow 2: {exc}") from None
        route = ctx.route
        end = sink_2.transform.location
        self.end_index = route.closest_index(end)
        if route.waypoints[self.end_index].transform.location.distance_2d(end) > 3.0:
            raise ScenarioSetupError(f"{self.name}: the route does not pass flow 2's sink")
        self.flows: list[ActorFlow] = []

    def start(self, snapshot: Snapshot) -> None:
        """Empty the junction of background traffic, stop the route sources and the opposite traffic; start the
        two flows."""
        bg = self.ctx.sim.background
        entries = {(c.entry.road_id, c.entry.lane_id): c.entry for c in self.lanes}
        exits = {(c.exit.road_id, c.exit.lane_id): c.exit for c in self.lanes}
        bg.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=list(entries.values()),
            remove_exits=list(exits.values()), stop_entries=False, extend_road_exit=0.0,
        )  # fmt: skip
        bg.switch_route_sources(False)
        bg.change_opposite_behavior(active=False)
        for path in (self.path_1, self.path_2):
            flow = ActorFlow(self.ctx.sim, self.ctx.rng, path, self.flow_speed, self.interval)
            flow.start()
            self.flows.append(flow)

    def hint(self) -> ScenarioHint | None:
        """A hint of the scenario's type: its flow's cars never brake for the ego (the expert's flow checks)."""
        return ScenarioHint(self.xml_type, None, None)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Drive the flows; SUCCESS once the ego has passed flow 2's sink."""
        for flow in self.flows:
            flow.update(snapshot)
        if self.ego_route_point(snapshot) >= self.end_index:
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Stop the flows, restore the route sources and the opposite traffic."""
        for flow in self.flows:
            flow.stop()
        if self.flows:
            self.ctx.sim.background.switch_route_sources(True)
            self.ctx.sim.background.change_opposite_behavior(active=True)


# ------------------------------------------------------------------------------------------------ placement


#: Interurban roads are faster than this (km/h); town streets and boulevards are 30–60.
INTERURBAN_MIN_LIMIT = 65.0


def _interurban_turn(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The ego leaves a fast road with priority (no stop sign) that goes on straight across the junction."""
    if town.speed_limit(conn.entry) <= INTERURBAN_MIN_LIMIT:
        return False
    keys = {(conn.entry.road_id, conn.entry.lane_id), (conn.start.road_id, conn.start.lane_id)}
    if keys & signal_lanes(town.stop_signs()):
        return False
    opposite = entries_from(lanes, conn.entry, "opposite")
    return any(town.speed_limit(e) > INTERURBAN_MIN_LIMIT for e in opposite)


def _interurban_flow(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The opposite entry's straight lane as the flow: source 70 m before the junction, sink 40 m after it."""
    for entry in entries_from(lanes, conn.entry, "opposite"):
        straight = connection(lanes, entry, "straight")
        if straight is None:
            continue
        source = walk_back_to_source(straight.entry, 70.0)
        sink = move_along(straight.exit, 40.0, step=CHECK_STEP)
        if sink is None or source.transform.location.distance_2d(straight.entry.transform.location) < 50.0:
            continue
        return [{"start_actor_flow": xml_location(source), "end_actor_flow": xml_location(sink)}]
    return []


def _onto_interurban(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The ego turns from a side road onto a fast road that runs straight across the junction."""
    # the limit just after a junction is still the previous road's (speed signs stand a little way in)
    onto = move_along(conn.exit, 30.0, step=CHECK_STEP)
    fast = town.speed_limit(onto) if onto is not None else 0.0
    if not (fast > INTERURBAN_MIN_LIMIT and town.speed_limit(conn.entry) < fast):
        return False
    # flow 1 drives along the fast road on both sides of the junction (not into or out of a town street)
    for entry in entries_from(lanes, conn.entry, "left"):
        straight = connection(lanes, entry, "straight")
        beyond = move_along(straight.exit, 30.0, step=CHECK_STEP) if straight is not None else None
        if beyond is not None and min(town.speed_limit(entry), town.speed_limit(beyond)) > INTERURBAN_MIN_LIMIT:
            return True
    return False


def _interurban_two_flows(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Flow 1 on the left entry's straight lane, 60 m before the junction to 40 m after it (flow 2 runs back on the
    lanes beside it, into the ego's exit lane)."""
    for entry in entries_from(lanes, conn.entry, "left"):
        straight = connection(lanes, entry, "straight")
        if straight is None:
            continue
        source = walk_back_to_source(straight.entry, 60.0)
        sink = move_along(straight.exit, 40.0, step=CHECK_STEP)
        if sink is None or source.transform.location.distance_2d(straight.entry.transform.location) < 50.0:
            continue
        return [{"direction": {"value": "right"}, "start_actor_flow": xml_location(source),
                 "end_actor_flow": xml_location(sink)}]  # fmt: skip
    return []


register_layouts({
    "InterurbanActorFlow": Layout(
        "interurban", "an unsignalised junction where the route turns left off a road faster than 65 km/h, with an "
        "opposite entry going straight on for 40 m", turns=("left",), signalized=False,
        junction_extra=_interurban_flow, junction_ok=_interurban_turn),
    "InterurbanAdvancedActorFlow": Layout(
        "interurban", "an unsignalised junction where the route turns left from a side road onto a road faster than "
        "65 km/h, with a left entry going straight on", turns=("left",), signalized=False,
        junction_extra=_interurban_two_flows, junction_ok=_onto_interurban, departure=(70.0, 85.0)),
})  # fmt: skip
