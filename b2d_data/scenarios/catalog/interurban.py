"""Interurban junctions with a fast actor flow (§2.2 #33): InterurbanActorFlow.

The ego leaves an interurban road by turning left at an unsignalised junction, across a constant-speed flow on the
opposite lane that runs from the XML's ``start_actor_flow`` to ``end_actor_flow`` (not pre-populated). The ego's
entry, the flow's entry and the other entries are removed from background traffic and the opposite background is
paused. The scenario ends when the ego has left the junction, or after 240 s.
"""

from __future__ import annotations

import logging

from b2d_data.format.transform import Location
from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.flows import ActorFlow, flow_path
from b2d_data.scenarios.catalog.junctions import JunctionScenario
from b2d_data.scenarios.catalog.road_geometry import same_direction_lanes
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, ScenarioStatus, register
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
        raise ScenarioSetupError(f"{ctx.config.name}: {exc}") from None


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
