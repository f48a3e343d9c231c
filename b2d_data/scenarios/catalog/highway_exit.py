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

import numpy as np

from b2d_data.maps import Map, Waypoint
from b2d_data.scenarios.catalog.flows import FlowScenario
from b2d_data.scenarios.catalog.highway_placement import HIGHWAY_MIN_LIMIT, MERGE_MAX_ANGLE
from b2d_data.scenarios.catalog.interurban import location_parameter
from b2d_data.scenarios.catalog.junctions import walk_back_to_source
from b2d_data.scenarios.catalog.layout import KEYPOINT_SPACING, Layout, register_layouts, through_junction, xml_location
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    junction_lanes,
    lane_walk,
    move_along,
    same_direction_driving_neighbour,
    same_lane,
)
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


# ------------------------------------------------------------------------------------------------ placement


#: change and the junction (or the change into a deceleration lane); where the deceleration lane is at least
#: ``EXIT_LANE_MIN_WIDTH`` m wide, the share of it before the junction where the route enters it.
EXIT_START_RUN, EXIT_CHANGE_RUN, EXIT_LANE_SHARE = (15.0, 25.0), (85.0, 105.0), (0.35, 0.55)
EXIT_LANE_MIN_WIDTH = 3.0
#: HighwayExit's flow starts this far behind the route's start and ends this far past the junction (m), as in
#: Bench2Drive's routes (26-28 m behind the trigger point).
EXIT_FLOW_BEHIND, EXIT_FLOW_AFTER = 28.0, 30.0


def _exit_lanes(conn: JunctionLane, lanes: list[JunctionLane]) -> tuple[JunctionLane, Waypoint] | None:
    """For an exit connection: the flow lane's connection staying on the highway and the ego's lane left of it.

    The flow lane is the exit lane itself where it also goes straight on (Town04), else the lane left of it (a
    deceleration lane, the generated towns). ``conn`` is an exit when no other lane of its road goes its way.
    """
    e = conn.entry
    sign = e.lane_id > 0
    others = [o for o in lanes if o.entry.road_id == e.road_id and (o.entry.lane_id > 0) == sign]
    highway = {o.exit.road_id for o in others if o.entry.lane_id != e.lane_id}
    if not highway or conn.exit.road_id in highway:
        return None
    own = [o for o in others if o.entry.lane_id == e.lane_id and o.exit.road_id in highway]
    flow_entry = e if own else same_direction_driving_neighbour(e, "left")
    if flow_entry is None:
        return None
    through = [o for o in others if o.entry.lane_id == flow_entry.lane_id and o.exit.road_id in highway]
    ego_lane = same_direction_driving_neighbour(flow_entry, "left")
    if not through or ego_lane is None:
        return None
    straight = min(through, key=lambda o: abs(o.angle))
    if conn.angle <= straight.angle:  # the exit leaves to the left
        return None
    return straight, ego_lane


def _highway_exit(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """A highway (>= 80 km/h) lane leaving by an exit on the right, with a flow lane and the ego's lane left of it."""
    found = _exit_lanes(conn, lanes)
    return (
        found is not None
        and min(town.speed_limit(conn.entry), town.speed_limit(found[0].exit)) >= HIGHWAY_MIN_LIMIT
        and conn.angle - found[0].angle < MERGE_MAX_ANGLE  # a ramp leaving at a shallow angle, not a side street
    )


def _wide_run_back(wp: Waypoint, min_width: float, cap: float) -> float:
    """Metres back from ``wp`` along its lane while the lane is at least ``min_width`` m wide (2 m steps)."""
    run, current = 0.0, wp
    while run < cap:
        prev = move_along(current, KEYPOINT_SPACING, forward=False, step=KEYPOINT_SPACING)
        if prev is None or prev.is_junction or prev.lane_width < min_width or prev.lane_id != current.lane_id:
            break
        run, current = run + KEYPOINT_SPACING, prev
    return run


def _exit_route(conn: JunctionLane, rng: np.random.Generator) -> tuple[list[Waypoint], Waypoint] | None:
    """The ego's lane, a change right across the flow lane, (a change into the deceleration lane,) the exit."""
    step = KEYPOINT_SPACING
    junction = conn.start.get_junction()
    found = _exit_lanes(conn, junction_lanes(junction)) if junction is not None else None
    if found is None:
        return None
    flow_entry = same_direction_driving_neighbour(found[1], "right")
    if flow_entry is None:
        return None
    d_fe = 0.0
    decel = not same_lane(flow_entry, conn.entry)
    if decel:
        wide = _wide_run_back(conn.entry, EXIT_LANE_MIN_WIDTH, 200.0)
        if wide < 30.0:
            return None
        d_fe = step * round(float(rng.uniform(*EXIT_LANE_SHARE)) * wide / step)
    d_gf = d_fe + step * round(float(rng.uniform(*EXIT_CHANGE_RUN)) / step)
    d_start = d_gf + step * round(float(rng.uniform(*EXIT_START_RUN)) / step)
    f_gf = move_along(flow_entry, d_gf, forward=False, step=step)
    g_gf = same_direction_driving_neighbour(f_gf, "left") if f_gf is not None else None
    if g_gf is None:
        return None
    g_run = lane_walk(g_gf, d_start - d_gf, forward=False, step=step)
    f_next = move_along(f_gf, step, step=step)
    if len(g_run) * step < d_start - d_gf or f_next is None:
        return None
    path = list(reversed(g_run)) + lane_walk(f_next, d_gf - d_fe - step, step=step)
    if decel:
        e_next = same_direction_driving_neighbour(move_along(path[-1], step, step=step) or path[-1], "right")
        if e_next is None:
            return None
        path += lane_walk(e_next, d_fe - step, step=step)
    through = through_junction(conn, float(rng.uniform(30.0, 40.0)), 30.0)
    if through is None or any(wp.is_junction for wp in path):
        return None
    return path + through, path[int(rng.integers(0, 2))]


def _exit_flow(conn: JunctionLane | None, path: list[Waypoint]) -> dict[str, dict[str, str]] | None:
    """The flow: from ``EXIT_FLOW_BEHIND`` m behind the route's start on the lane right of it to
    ``EXIT_FLOW_AFTER`` m past the junction on the highway."""
    junction = conn.start.get_junction() if conn is not None else None
    found = _exit_lanes(conn, junction_lanes(junction)) if conn is not None and junction is not None else None
    beside = same_direction_driving_neighbour(path[0], "right")
    if found is None or beside is None:
        return None
    source = walk_back_to_source(beside, EXIT_FLOW_BEHIND, step=2.0)
    sink = move_along(found[0].exit, EXIT_FLOW_AFTER)
    if sink is None or sink.is_junction:
        return None
    return {"start_actor_flow": xml_location(source), "end_actor_flow": xml_location(sink)}


register_layouts({
    "HighwayExit": Layout(
        "highway_exit", "a highway (>= 80 km/h) exit on the right, with a flow lane to cross and the ego's lane left "
        "of it", turns=("straight", "right"), junction_ok=_highway_exit, approach=(20.0, 30.0),
        departure=(30.0, 40.0), route_path=_exit_route, path_parameters=_exit_flow),
})  # fmt: skip
