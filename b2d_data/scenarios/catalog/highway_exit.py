"""HighwayExit (§2.2 #30): the ego leaves a multi-lane highway by an exit on the right, across a flow.

One constant-speed :class:`~b2d_data.scenarios.catalog.flows.ActorFlow` runs from ``start_actor_flow`` (a lane right
of the ego's, behind it) on through the exit junction (the planner's route) to ``end_actor_flow``, pre-populated, also inside the
junction (LB2.0's ``initial_actors=True, initial_junction=True``). The flow's lane is removed from background traffic
(``RemoveRoadLane``). The route changes lanes across the flow toward the exit; the scenario ends when the ego leaves
the exit junction (the first junction on the flow's path), or after 240 s.
"""

from __future__ import annotations

import logging

from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.enter_flow import flow_lanes_path
from b2d_data.scenarios.catalog.flows import ActorFlow
from b2d_data.scenarios.catalog.interurban import location_parameter
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import WaitEndIntersection
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


@register
class HighwayExit(Scenario):
    """Cut across a flow on the right to take a highway exit (§2.2 #30)."""

    xml_type = "HighwayExit"

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.flow_speed = ctx.value("flow_speed", 10.0)
        self.interval = ctx.interval("source_dist_interval", (20.0, 50.0))
        source = ctx.map.get_waypoint(location_parameter(ctx, "start_actor_flow"))
        sink = ctx.map.get_waypoint(location_parameter(ctx, "end_actor_flow"))
        if source is None or sink is None:
            raise ScenarioSetupError(f"{self.name}: the actor flow's source or sink is off the road")
        # as LB2.0, the flow follows the planner's route from source to sink (at an exit the lane forks)
        self.path: list[Waypoint] = flow_lanes_path(ctx, source, sink)
        junction = next((wp.junction_id for wp in self.path if wp.is_junction), None)
        if junction is None:
            raise ScenarioSetupError(f"{self.name}: layout missing: the actor flow crosses no junction")
        route_junctions = {wp.junction_id for wp in ctx.route.waypoints[self.trigger_index :] if wp.is_junction}
        if junction not in route_junctions:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: the route does not pass junction {junction}, where the flow leaves "
                "the exit behind"
            )
        self.junction_id = int(junction)
        exit_lanes = {
            (wp.road_id, wp.lane_id)
            for wp in ctx.route.waypoints[self.trigger_index :]
            if wp.is_junction and wp.junction_id == junction
        }
        through = {(wp.road_id, wp.lane_id) for wp in self.path if wp.is_junction and wp.junction_id == junction}
        if exit_lanes & through:
            raise ScenarioSetupError(
                f"{self.name}: the route follows the flow straight through junction {junction} instead of exiting"
            )
        self.flow: ActorFlow | None = None
        self._left = WaitEndIntersection(ctx.map, self.junction_id)

    def start(self, snapshot: Snapshot) -> None:
        """Remove the flow's lane from background traffic and start the pre-populated flow."""
        self.ctx.sim.background.remove_road_lane(self.path[0])
        self.flow = ActorFlow(self.ctx.sim, self.ctx.rng, self.path, self.flow_speed, self.interval,
                              initial_actors=True)  # fmt: skip
        self.flow.start()

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Drive the flow; SUCCESS once the ego has left the exit junction."""
        if self.flow is not None:
            self.flow.update(snapshot)
        ego = self.ctx.ego(snapshot)
        if ego is not None and self._left.check(ego):
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Remove the flow."""
        if self.flow is not None:
            self.flow.stop()
