"""Interurban junctions with fast actor flows (§2.2 #33, #34): InterurbanActorFlow, InterurbanAdvancedActorFlow.

InterurbanActorFlow: the ego leaves an interurban road by turning left at an unsignalised junction, across a
constant-speed flow on the opposite lane that runs from the XML's ``start_actor_flow`` to ``end_actor_flow`` (not
pre-populated). As LB2.0, three entries are removed from background traffic: the ego's, the one from the road the ego
turns into and the flow's source lane; the opposite background is paused. The scenario ends when the ego has left the
junction, or after 240 s.

InterurbanAdvancedActorFlow: the ego enters an interurban road by turning left from a side road. Flow 1 runs from
``start_actor_flow`` to ``end_actor_flow`` across the ego's path; flow 2 runs the other way on the lane left of flow
1's sink to the lane left of its source, the lane the ego merges into. Both at ``flow_speed``. Every junction entry
and exit but the ego's own is removed from background traffic, the road after the junction kept free for flow 2's
length past it + 20 m, the route sources are off and the opposite traffic paused; the scenario ends when the ego
passes flow 2's sink, or after 240 s.
"""

from __future__ import annotations

import logging

from b2d_data.format.transform import Location
from b2d_data.maps import Map, Waypoint
from b2d_data.scenarios.catalog.flows import FlowScenario, flow_path
from b2d_data.scenarios.catalog.junctions import JunctionScenario, walk_back_to_source
from b2d_data.scenarios.catalog.layout import CHECK_STEP, Layout, register_layouts, signal_lanes, xml_location
from b2d_data.scenarios.catalog.road_geometry import JunctionLane, connection, entries_from, is_driving, move_along
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, register
from b2d_data.scenarios.triggers import WaitEndIntersection
from b2d_data.sim.api import Snapshot

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
class InterurbanActorFlow(FlowScenario, JunctionScenario):
    """Left turn off an interurban road across a fast oncoming flow (§2.2 #33)."""

    xml_type = "InterurbanActorFlow"
    required_turn = ("left",)
    opposite_off = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.path: list[Waypoint] = flow_lane_path(ctx)
        if not any(wp.is_junction and wp.junction_id == self.junction.id for wp in self.path):
            raise ScenarioSetupError(
                f"{self.name}: layout missing: the actor flow does not cross junction {self.junction.id}"
            )
        self._left = WaitEndIntersection(ctx.map, self.junction.id)
        self.removed_entries = self._entries_to_remove()

    def _entries_to_remove(self) -> list[Waypoint]:
        """LB2.0's three entries taken from background traffic: the ego's (2 m before its junction entry), the one
        from the road the ego turns into (the lane left of the ego's exit lane 10 m after the junction) and the
        flow's source lane."""
        route_entry = move_along(self.ego_entry, 2.0, forward=False) or self.ego_entry
        route_exit = move_along(self.ego_exit, 10.0) if self.ego_exit is not None else None
        other_entry = route_exit.get_left_lane() if route_exit is not None else None
        if other_entry is None or not is_driving(other_entry):
            # LB2.0 raises "Couldn't find an end position" here
            raise ScenarioSetupError(f"{self.name}: layout missing: no driving lane left of the ego's exit lane")
        return [route_entry, other_entry, self.path[0]]

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Remove the ego's entry, the exit road's entry and the flow's source from background traffic (the opposite
        traffic pauses)."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=False, clear_ego_entry=True, remove_entries=self.removed_entries, remove_exits=[],
            stop_entries=False, extend_road_exit=0.0,
        )  # fmt: skip

    def start_flows(self, snapshot: Snapshot) -> None:
        """The flow, not pre-populated."""
        self.add_flow(self.path)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego has left the junction."""
        ego = self.ctx.ego(snapshot)
        return ego is not None and self._left.check(ego)


def _opposite(wp: Waypoint, name: str) -> Waypoint:
    """The driving lane left of ``wp`` across the centre line (raises naming the scenario when there is none)."""
    other = wp.get_left_lane()
    if other is None or not is_driving(other) or other.lane_id * wp.lane_id > 0:
        raise ScenarioSetupError(f"{name}: layout missing: no opposite lane beside road {wp.road_id} lane {wp.lane_id}")
    return other


@register
class InterurbanAdvancedActorFlow(FlowScenario, JunctionScenario):
    """Left turn onto an interurban road across one fast flow and into another (§2.2 #34)."""

    xml_type = "InterurbanAdvancedActorFlow"
    required_turn = ("left",)
    route_sources_off = True
    opposite_off = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
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

        # LB2.0 keeps the road after the junction free for flow 2's length past the junction + 20 m, and leaves
        # flow 2's lane after the junction (the one the ego turns into) to the background
        inside = [k for k, wp in enumerate(self.path_2) if wp.is_junction]
        last = inside[-1] if inside else len(self.path_2) - 1
        self.extra_space = 20.0 + float(len(self.path_2) - 1 - last)
        self.route_exit: Waypoint | None = self.path_2[last + 1] if inside and last + 1 < len(self.path_2) else None

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Empty the junction of background traffic but for the ego's own entry and exit lanes (the route sources
        and the opposite traffic stop); keep the road after it free for flow 2's length + 20 m."""
        ego_entry = (self.ego_entry.road_id, self.ego_entry.lane_id)
        ego_exit = (self.route_exit.road_id, self.route_exit.lane_id) if self.route_exit is not None else None
        entries = {(c.entry.road_id, c.entry.lane_id): c.entry for c in self.lanes}
        exits = {(c.exit.road_id, c.exit.lane_id): c.exit for c in self.lanes}
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True,
            remove_entries=[wp for key, wp in entries.items() if key != ego_entry],
            remove_exits=[wp for key, wp in exits.items() if key != ego_exit], stop_entries=False,
            extend_road_exit=self.extra_space,
        )  # fmt: skip

    def start_flows(self, snapshot: Snapshot) -> None:
        """The two flows, not pre-populated."""
        for path in (self.path_1, self.path_2):
            self.add_flow(path)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego has passed flow 2's sink."""
        return self.ego_route_point(snapshot) >= self.end_index


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


def _straight_flow(conn: JunctionLane, lanes: list[JunctionLane], side: str,
                   back: float) -> dict[str, dict[str, str]] | None:
    """The flow's ends on the first ``side`` entry's straight lane across the junction: source ``back`` m before it
    (at least 50 m of it), sink 40 m after it; None when no such entry has them."""
    for entry in entries_from(lanes, conn.entry, side):
        straight = connection(lanes, entry, "straight")
        if straight is None:
            continue
        source = walk_back_to_source(straight.entry, back)
        sink = move_along(straight.exit, 40.0, step=CHECK_STEP)
        if sink is None or source.transform.location.distance_2d(straight.entry.transform.location) < 50.0:
            continue
        return {"start_actor_flow": xml_location(source), "end_actor_flow": xml_location(sink)}
    return None


def _interurban_flow(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The opposite entry's straight lane as the flow: source 70 m before the junction, sink 40 m after it."""
    ends = _straight_flow(conn, lanes, "opposite", 70.0)
    return [ends] if ends is not None else []


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
    ends = _straight_flow(conn, lanes, "left", 60.0)
    return [{"direction": {"value": "right"}, **ends}] if ends is not None else []


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
