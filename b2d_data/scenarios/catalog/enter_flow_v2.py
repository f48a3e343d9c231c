"""EnterActorFlowV2 (LB2.0 training type, not in Bench2Drive): the ego enters a highway by an entry with a lane of its
own, beside one fast flow on the highway lane next to it.

Reference: scenario_runner ``leaderboard-2.0``, ``srunner/scenarios/actor_flow.py`` (line numbers are Bench2Drive's
identical copy, ``scenario_runner/srunner/scenarios/actor_flow.py``):

- ``__init__`` is EnterActorFlow's (:67-94): ``start_actor_flow`` / ``end_actor_flow`` locations, ``flow_speed``
  (default 10 m/s), ``source_dist_interval`` (default [20, 50] m), sink distance 2 m, ScenarioTimeout 240 s.
- ``_create_behavior`` (:165-227), unlike EnterActorFlow:

  - ONE ``ActorFlow`` from the source point's lane to the sink (pre-populated, ``initial_actors`` and
    ``initial_junction``), not one per lane;
  - the scenario ends when the ego is within 2 m of the sink point of ANY same-direction lane at the sink
    (``InTriggerDistanceToLocation`` per ``get_same_dir_lanes(sink_wp)``), or at the 240 s ScenarioTimeout;
  - at the start: ``HandleJunctionScenario(clear_junction=False, clear_ego_entry=True, remove_entries=[source_wp],
    remove_exits=get_same_dir_lanes(exit_wp), stop_entries=False, extend_road_exit=0)`` where ``exit_wp`` is the
    route's first waypoint after the ego's junction (``generate_target_waypoint_in_route``) moved 10 m on, then
    ``SwitchRouteSources(False)``;
  - in parallel, once the ego has left a junction (``WaitEndIntersection`` without an id), a second
    ``HandleJunctionScenario`` with only ``extend_road_exit`` = 20 m + the flow route's length from its last
    junction waypoint to the sink (the global planner's trace, summed backwards; the trace ends at the loop
    variable, i.e. the last lane ``get_same_dir_lanes(sink_wp)`` lists: the same road beside the flow's own sink,
    so the length differs by the planner's lane changes, a few metres at most; ours measures the flow's lane);
  - ``SwitchRouteSources(True)`` when the scenario ends.
- ``_create_test_criteria`` (:144-152): ScenarioTimeoutTest (a CollisionTest only outside route mode).

Ours: a :class:`~b2d_data.scenarios.catalog.flows.FlowScenario` (the flow types' shared shape). The flow's lane
path is :func:`~b2d_data.scenarios.catalog.interurban.flow_lane_path` (the lane straight on, else the route
planner's trace, as ActorFlow's ``trace_route``), 1 m apart, so the extension is 20 m plus the number of path points
after its last junction point. The second background request goes to whichever junction our
background treats as next when the ego leaves its junction, as LB2.0's ``_extent_road_exit_space`` takes the active
junction or else the next one. The expert gets the flow's sink in the hint and merges with the gap acceptance of
:mod:`b2d_data.expert.merging`.

Placement (generated towns; Town12/13's entries with a lane of their own do not exist there): the route comes down an
on-ramp through its merge junction onto the acceleration lane, which runs on as the ego's own lane beside the
highway's right lane, and changes into that lane :data:`MERGE_AFTER` m after the junction. The flow runs on that
highway lane from :data:`FLOW_BACK` m before the junction to :data:`FLOW_AFTER` m after it (LB2.0's routes: the
source ~50 m beside the trigger point, the sink 460-510 m on; our highways are shorter).
"""

from __future__ import annotations

import logging
from typing import ClassVar

from b2d_data.maps import Map, Waypoint
from b2d_data.scenarios.catalog.flows import SINK_DISTANCE, FlowScenario
from b2d_data.scenarios.catalog.interurban import flow_lane_path, location_parameter
from b2d_data.scenarios.catalog.junctions import JunctionScenario, walk_back_to_source
from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    move_along,
    same_direction_driving_neighbour,
    same_direction_lanes,
    same_lane,
)
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, register
from b2d_data.scenarios.triggers import WaitEndIntersection
from b2d_data.sim.api import ScenarioHint, Snapshot

log = logging.getLogger(__name__)

#: Added to the flow's length after its junction for the road-exit extension (m; the reference's ``extra_space``).
EXTRA_SPACE = 20.0
#: ``exit_wp`` lies this far after the route's junction exit (m; ``exit_wp.next(10)[0]``).
EXIT_OFFSET = 10.0

# -- placement on generated towns ----------------------------------------------------------------------------------
#: Highways are at least this fast (km/h), as for the other highway layouts.
HIGHWAY_MIN_LIMIT = 80.0
#: Largest heading change (deg) of an on-ramp's connection (a ramp merging at a shallow angle, not a side street).
MERGE_MAX_ANGLE = 60.0
#: The flow starts this far up the highway before the merge junction and ends this far after its exit (m).
FLOW_BACK, FLOW_AFTER = 60.0, 110.0
#: Route: metres before the junction, after it, of the trigger after the route's start, and on the ego's own lane
#: after the junction before the planned change into the flow's lane.
APPROACH, DEPARTURE, TRIGGER_OFFSET = (40.0, 50.0), (125.0, 135.0), (2.0, 6.0)
MERGE_AFTER = (25.0, 45.0)


def highway_beside(conn: JunctionLane, lanes: list[JunctionLane]) -> JunctionLane | None:
    """The connection of the same junction that runs straight from another road into the lane left of ``conn``'s
    exit (the highway lane an on-ramp's own lane runs beside), None when there is none."""
    left = same_direction_driving_neighbour(conn.exit, "left")
    if left is None:
        return None
    for other in lanes:
        if other.turn == "straight" and other.entry.road_id != conn.entry.road_id and same_lane(other.exit, left):
            return other
    return None


def dedicated_entry(town: Map, conn: JunctionLane, lanes: list[JunctionLane]) -> bool:
    """The route comes down an on-ramp through its junction onto a lane of its own beside a highway lane (>= 80 km/h)."""
    if abs(conn.angle) >= MERGE_MAX_ANGLE:
        return False
    highway = highway_beside(conn, lanes)
    if highway is None:
        return False
    return min(town.speed_limit(highway.entry), town.speed_limit(highway.exit)) >= HIGHWAY_MIN_LIMIT


def _xml_location(wp: Waypoint) -> dict[str, str]:
    loc = wp.transform.location
    return {"x": f"{loc.x:.1f}", "y": f"{loc.y:.1f}", "z": f"{loc.z:.1f}"}


def flow_beside(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """The flow's source ``FLOW_BACK`` m up the highway lane before the junction (less where a junction comes first)
    and its sink ``FLOW_AFTER`` m after the junction on the same lane; none when that lane meets a junction first."""
    highway = highway_beside(conn, lanes)
    if highway is None:
        return []
    source = walk_back_to_source(highway.entry, FLOW_BACK)
    sink = move_along(highway.exit, FLOW_AFTER, step=5.0)
    if sink is None or sink.is_junction:
        return []
    return [{"start_actor_flow": _xml_location(source), "end_actor_flow": _xml_location(sink)}]


# -- the scenario ---------------------------------------------------------------------------------------------------
@register
class EnterActorFlowV2(FlowScenario, JunctionScenario):
    """Enter a highway on a lane of one's own beside one fast, pre-populated flow (actor_flow.py EnterActorFlowV2)."""

    xml_type = "EnterActorFlowV2"
    #: EnterActorFlow's defaults, which V2 inherits (actor_flow.py :85-86).
    default_interval: ClassVar[tuple[float, float]] = (20.0, 50.0)
    default_flow_speed: ClassVar[float] = 10.0
    #: SwitchRouteSources(False) before the flow, (True) after it.
    route_sources_off = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.path: list[Waypoint] = flow_lane_path(ctx)
        self.source = self.path[0]
        sink = ctx.map.get_waypoint(location_parameter(ctx, "end_actor_flow"))
        if sink is None:
            raise ScenarioSetupError(f"{self.name}: end_actor_flow is off the road")
        #: The end condition's points: the sink on every same-direction lane (get_same_dir_lanes(sink_wp)).
        self.sinks: list[Waypoint] = same_direction_lanes(sink)
        inside = [k for k, wp in enumerate(self.path) if wp.is_junction]
        #: The second request's road-exit extension: 20 m + the flow's metres from its last junction point.
        self.extra_space = EXTRA_SPACE + (float(len(self.path) - 1 - inside[-1]) if inside else 0.0)
        exit_wp = move_along(self.ego_exit, EXIT_OFFSET) if self.ego_exit is not None else None
        if exit_wp is None:
            raise ScenarioSetupError(
                f"{self.name}: the route has no lane {EXIT_OFFSET:.0f} m after junction {self.junction.id}"
            )
        #: Lanes removed from background traffic after the junction (get_same_dir_lanes(exit_wp)).
        self.exit_lanes: list[Waypoint] = same_direction_lanes(exit_wp)
        self._left_junction = WaitEndIntersection(ctx.map)  # no junction id, as the reference's
        self._extended = False

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Keep the ego's entry clear, remove the flow's own entry and the lanes after the junction, no extension."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=False, clear_ego_entry=True, remove_entries=[self.source], remove_exits=self.exit_lanes,
            stop_entries=False, extend_road_exit=0.0,
        )  # fmt: skip

    def start_flows(self, snapshot: Snapshot) -> None:
        """One pre-populated flow on the source's lane."""
        self.add_flow(self.path, sink_distance=SINK_DISTANCE, initial_actors=True)

    def step(self, snapshot: Snapshot) -> None:
        """Once the ego has left a junction: extend the road exit (the reference's second HandleJunctionScenario)."""
        ego = self.ctx.ego(snapshot)
        if ego is not None and not self._extended and self._left_junction.check(ego):
            self._extended = True
            self.ctx.sim.background.handle_junction_scenario(extend_road_exit=self.extra_space)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego is within 2 m of the sink point of any same-direction lane."""
        return self.ego_near_sink(snapshot, self.sinks)

    def hint(self) -> ScenarioHint | None:
        """While the flow runs: the flow's sink on its lane (the expert's merge gap acceptance)."""
        if self.flow is None or not self.flow.active:
            return None
        sink = self.path[-1].transform.location
        return ScenarioHint(self.xml_type, None, None, extra={"sink_x": sink.x, "sink_y": sink.y, "sink_z": sink.z})


register_layouts({
    "EnterActorFlowV2": Layout(
        "highway_ramps", "an on-ramp whose lane runs on beside a highway (>= 80 km/h) lane after its junction",
        turns=("straight", "left", "right"), junction_ok=dedicated_entry, junction_extra=flow_beside,
        approach=APPROACH, departure=DEPARTURE, trigger_offset=TRIGGER_OFFSET, merge_left_after=MERGE_AFTER),
})  # fmt: skip
