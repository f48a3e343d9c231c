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
from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.flows import FlowScenario, flow_path
from b2d_data.scenarios.catalog.junctions import JunctionScenario
from b2d_data.scenarios.catalog.road_geometry import is_driving, same_direction_lanes
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

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Remove the junction's entries from background traffic (the opposite traffic pauses)."""
        entries = {(c.entry.road_id, c.entry.lane_id): c.entry for c in self.lanes}
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=False, clear_ego_entry=True,
            remove_entries=[*entries.values(), *same_direction_lanes(self.path[0])], remove_exits=[],
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

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Empty the junction of background traffic (the route sources and the opposite traffic stop)."""
        entries = {(c.entry.road_id, c.entry.lane_id): c.entry for c in self.lanes}
        exits = {(c.exit.road_id, c.exit.lane_id): c.exit for c in self.lanes}
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=list(entries.values()),
            remove_exits=list(exits.values()), stop_entries=False, extend_road_exit=0.0,
        )  # fmt: skip

    def start_flows(self, snapshot: Snapshot) -> None:
        """The two flows, not pre-populated."""
        for path in (self.path_1, self.path_2):
            self.add_flow(path)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego has passed flow 2's sink."""
        return self.ego_route_point(snapshot) >= self.end_index
