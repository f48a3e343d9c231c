"""HighwayExit (§2.2 #30): the ego leaves a multi-lane highway by an exit on the right, across a flow.

One constant-speed :class:`~b2d_data.scenarios.catalog.flows.ActorFlow` runs from ``start_actor_flow`` (a lane right
of the ego's, behind it) on along its lane through the exit junction to ``end_actor_flow``, pre-populated, also inside the
junction (LB2.0's ``initial_actors=True, initial_junction=True``). The flow's lane is removed from background traffic
(``RemoveRoadLane``), and so is a deceleration lane that leads to the exit (generated towns; Bench2Drive's exits leave
from the flow's lane itself). The route changes lanes across the flow toward the exit; the scenario ends when the ego leaves
the exit junction (the first junction on the flow's path), or after 240 s.
"""

from __future__ import annotations

import logging

from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.flows import FlowScenario
from b2d_data.scenarios.catalog.interurban import location_parameter
from b2d_data.scenarios.catalog.road_geometry import lane_walk
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, register
from b2d_data.scenarios.triggers import WaitEndIntersection
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)

#: Ticks between two clearings of the flow's lane.
CLEAR_EVERY = 10
#: At a fork the flow takes the branch whose next metres come nearest its sink.
FORK_LOOKAHEAD = 60.0


def lane_path_to(source: Waypoint, sink: Waypoint, max_length: float = 600.0) -> list[Waypoint] | None:
    """Lane waypoints 1 m apart from ``source`` along its lane, never changing lanes, up to the point nearest
    ``sink``; at a fork (an exit) the branch that leads nearer the sink. None when the sink is not reached."""
    target = sink.transform.location
    path = [source]
    while len(path) < max_length:
        options = path[-1].next(1.0)
        if not options:
            break
        if len(options) == 1:
            path.append(options[0])
        else:
            path.append(
                min(
                    options,
                    key=lambda o: min(wp.transform.location.distance_2d(target) for wp in lane_walk(o, FORK_LOOKAHEAD)),
                )
            )
        if path[-1].transform.location.distance_2d(target) < 0.5:
            break
    d = [wp.transform.location.distance_2d(target) for wp in path]
    k = min(range(len(d)), key=d.__getitem__)
    return path[: k + 1] if d[k] < 3.0 and k > 0 else None


@register
class HighwayExit(FlowScenario):
    """Cut across a flow on the right to take a highway exit (§2.2 #30)."""

    xml_type = "HighwayExit"

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        source = ctx.map.get_waypoint(location_parameter(ctx, "start_actor_flow"))
        sink = ctx.map.get_waypoint(location_parameter(ctx, "end_actor_flow"))
        if source is None or sink is None:
            raise ScenarioSetupError(f"{self.name}: the actor flow's source or sink is off the road")
        # LB2.0's flow follows the planner's route from source to sink; ours keeps to its lane (zero-cost lane
        # changes let the planner wander across lanes on a curved highway) and takes the fork toward the sink
        path = lane_path_to(source, sink)
        if path is None:
            raise ScenarioSetupError(
                f"{self.name}: the lane at start_actor_flow (road {source.road_id} lane {source.lane_id}) does not "
                "lead to end_actor_flow"
            )
        self.path: list[Waypoint] = path
        junction = next((wp.junction_id for wp in self.path if wp.is_junction), None)
        if junction is None:
            raise ScenarioSetupError(f"{self.name}: layout missing: the actor flow crosses no junction")
        route_junctions = {wp.junction_id for wp in ctx.route.waypoints[self.trigger_index :] if wp.is_junction}
        if junction not in route_junctions:
            # as in LB2.0 the scenario then lasts until the route ends (or its timeout)
            log.warning("%s: the route ends before junction %d, where the flow passes the exit", self.name, junction)
        self.junction_id = int(junction)

        def road_after(waypoints: list[Waypoint]) -> int | None:
            inside = [k for k, wp in enumerate(waypoints) if wp.is_junction and wp.junction_id == junction]
            return waypoints[inside[-1] + 1].road_id if inside and inside[-1] + 1 < len(waypoints) else None

        through = {(wp.road_id, wp.lane_id) for wp in self.path if wp.is_junction and wp.junction_id == junction}
        route_after = road_after(list(ctx.route.waypoints[self.trigger_index :]))
        if route_after is not None and route_after == road_after(self.path):
            raise ScenarioSetupError(
                f"{self.name}: the route follows the flow straight through junction {junction} instead of exiting"
            )
        waypoints = ctx.route.waypoints
        entry = next(
            (
                k
                for k in range(self.trigger_index, len(waypoints))
                if waypoints[k].is_junction and waypoints[k].junction_id == junction
            ),
            0,
        )
        #: where the route leaves the highway, when that is a deceleration lane right of the flow's
        self.exit_lane: Waypoint | None = waypoints[entry - 1] if entry > 0 else None
        if self.exit_lane is not None and (self.exit_lane.road_id, self.exit_lane.lane_id) in through | {
            (wp.road_id, wp.lane_id) for wp in self.path
        }:
            self.exit_lane = None
        self._flow_keys: set[tuple[int, int]] = set()
        self._ticks = 0
        self._left = WaitEndIntersection(ctx.map, self.junction_id)

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Remove the flow's lane (and a deceleration lane to the exit) from background traffic."""
        self._flow_keys = {(wp.road_id, wp.lane_id) for wp in self.path if not wp.is_junction}
        self.ctx.sim.background.remove_road_lane(self.path[0])
        if self.exit_lane is not None:
            # a deceleration lane to the exit: background cars there would stop ahead of the ego and close it
            self.ctx.sim.background.remove_road_lane(self.exit_lane)
        self._clear_flow_lane(snapshot)

    def start_flows(self, snapshot: Snapshot) -> None:
        """The pre-populated flow."""
        self.add_flow(self.path, initial_actors=True)

    def _clear_flow_lane(self, snapshot: Snapshot) -> None:
        """RemoveRoadLane on the flow's lane beside the ego, while the ego is not on it yet.

        Repeated because the background traffic starts after the trigger and places the vehicles of the ego's lane
        along the route, which crosses into the flow's lane; those must go too.
        """
        ego = self.ctx.ego(snapshot)
        here = self.ctx.map.get_waypoint(ego.location) if ego is not None else None
        if here is None or (here.road_id, here.lane_id) in self._flow_keys:
            return
        beside = min(self.path, key=lambda wp: wp.transform.location.distance_2d(ego.location))
        if beside.road_id == here.road_id and not beside.is_junction:
            self.ctx.sim.background.remove_road_lane(beside)

    def step(self, snapshot: Snapshot) -> None:
        """Keep the flow's lane free of background traffic."""
        self._ticks += 1
        if self._ticks % CLEAR_EVERY == 0:
            self._clear_flow_lane(snapshot)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego has left the exit junction."""
        ego = self.ctx.ego(snapshot)
        return ego is not None and self._left.check(ego)
