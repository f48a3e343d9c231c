"""EnterActorFlow (§2.2 #29): the ego enters a road through a junction and merges into fast traffic on it.

One constant-speed :class:`~b2d_data.scenarios.catalog.flows.ActorFlow` per same-direction lane runs from
``start_actor_flow`` (before the junction, on the flow's entry) through the junction to ``end_actor_flow`` (on the
road the ego enters), pre-populated, including inside the junction. The background clears the junction, removes the
flow's entry lanes, extends the road exit by the flow's after-junction length + 20 m and switches the route sources
off. The scenario ends when the ego gets within 2 m of a flow's sink, or after 240 s.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import ClassVar

from b2d_data.format.transform import Location
from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog import enter_flow_v2 as ramp
from b2d_data.scenarios.catalog.flows import FlowScenario
from b2d_data.scenarios.catalog.junctions import JunctionScenario, walk_back_to_source
from b2d_data.scenarios.catalog.layout import Layout, register_layouts, register_param_layouts, xml_location
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    entries_from,
    flow_into_exit,
    lane_walk,
    move_along,
    same_direction_driving_neighbour,
    same_direction_lanes,
    same_lane,
)
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, register
from b2d_data.scenarios.param_ranges import TRAINING
from b2d_data.sim.api import ScenarioHint, Snapshot

log = logging.getLogger(__name__)

#: The ego must get this close to a flow's sink (m).
SINK_REACHED = 2.0


def flow_lanes_path(ctx: ScenarioContext, source: Waypoint, sink: Waypoint) -> list[Waypoint]:
    """Lane waypoints 1 m apart from ``source`` to ``sink`` as the leaderboard's planner routes them."""
    pairs = ctx.map.interpolate_trajectory([source.transform.location, sink.transform.location])
    path = [wp for wp, _ in pairs]
    if len(path) < 2 or path[-1].transform.location.distance_2d(sink.transform.location) > 3.0:
        raise ScenarioSetupError(
            f"{ctx.config.name}: no lane path from the flow source on road {source.road_id} to its sink on road "
            f"{sink.road_id}"
        )
    return path


@register
class EnterActorFlow(FlowScenario, JunctionScenario):
    """Merge into a dense flow on the road entered through the junction (§2.2 #29)."""

    xml_type = "EnterActorFlow"
    #: LB2.0's defaults (actor_flow.py EnterActorFlow: ``flow_speed`` 10 m/s, ``source_dist_interval`` [20, 50]);
    #: bench2drive220, routes_training and generated routes always set both.
    default_interval: ClassVar[tuple[float, float]] = (20.0, 50.0)
    default_flow_speed: ClassVar[float] = 10.0
    route_sources_off = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        source = self._lane_point("start_actor_flow")
        sink = self._lane_point("end_actor_flow")
        # pair the lanes from the road centre outwards, as the two ends may have different lane ids
        sources = sorted(same_direction_lanes(source), key=lambda wp: abs(wp.lane_id))
        sinks = sorted(same_direction_lanes(sink), key=lambda wp: abs(wp.lane_id))
        self.paths = [flow_lanes_path(ctx, a, b) for a, b in zip(sources, sinks)]
        self.sources = sources[: len(self.paths)]
        self.sinks = [path[-1] for path in self.paths]
        after = lane_walk(self.ego_exit, 500.0) if self.ego_exit is not None else []
        target = sink.transform.location
        self.after_junction = next(
            (float(k) for k, wp in enumerate(after) if wp.transform.location.distance_2d(target) < 4.0), 50.0
        )
        #: The sink of the flow lane the ego changes into from a lane of its own (an on-ramp's acceleration lane);
        #: None where the ego turns straight into a flow's lane.
        self.merge_sink: Waypoint | None = self._merge_sink()

    def _merge_sink(self) -> Waypoint | None:
        exit_wp = self.ego_exit
        if exit_wp is None or any(same_lane(wp, exit_wp) for path in self.paths for wp in path):
            return None
        left = same_direction_driving_neighbour(exit_wp, "left")
        if left is None:
            return None
        return next((path[-1] for path in self.paths if any(same_lane(wp, left) for wp in path)), None)

    def _lane_point(self, tag: str) -> Waypoint:
        coords = [self.ctx.config.parameter(tag, axis) for axis in ("x", "y", "z")]
        if coords[0] is None or coords[1] is None:
            raise ScenarioSetupError(f"{self.name}: parameter <{tag} x=... y=...> missing")
        try:
            loc = Location(float(coords[0]), float(coords[1]), float(coords[2] or 0.0))
        except ValueError:
            raise ScenarioSetupError(f"{self.name}: parameter <{tag}> has non-numeric coordinates") from None
        wp = self.ctx.map.get_waypoint(loc)
        if wp is None or wp.transform.location.distance_2d(loc) > 3.0:
            raise ScenarioSetupError(f"{self.name}: <{tag}> at ({loc.x:.1f}, {loc.y:.1f}) is not on a driving lane")
        return wp

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Clear the junction, remove the flows' entry lanes, keep the road after the junction free."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=self.sources, remove_exits=[],
            stop_entries=False, extend_road_exit=self.after_junction + 20.0,
        )  # fmt: skip

    def start_flows(self, snapshot: Snapshot) -> None:
        """One pre-populated flow per lane."""
        for path in self.paths:
            self.add_flow(path, initial_actors=True)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego is within 2 m of a sink."""
        ego = self.ctx.ego(snapshot)
        return ego is not None and any(ego.location.distance_2d(s.transform.location) < SINK_REACHED for s in self.sinks)

    def hint(self) -> ScenarioHint | None:
        """The flows' hint; on an on-ramp also the sink of the lane the ego merges into (merge gap acceptance)."""
        hint = super().hint()
        if hint is None or self.merge_sink is None:
            return hint
        sink = self.merge_sink.transform.location
        return dataclasses.replace(hint, extra={**hint.extra, "sink_x": sink.x, "sink_y": sink.y, "sink_z": sink.z})


# ------------------------------------------------------------------------------------------------ placement


#: EnterActorFlow's flow starts this far before the junction (less where an earlier junction is nearer) and ends
#: this far after it (m), as in Bench2Drive's routes (45-60 m before, 20-25 m after).
ENTER_FLOW_BACK, ENTER_FLOW_AFTER = 55.0, 22.0


def _enter_flow(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """A left entry whose straight lane reaches the road the ego turns right into: the flow's start and end."""
    for entry in entries_from(lanes, conn.entry, "left"):
        flow = flow_into_exit(lanes, entry, conn.exit, turn="straight")
        if flow is None:
            continue
        end = move_along(flow.exit, ENTER_FLOW_AFTER, step=2.0)
        if end is None or end.is_junction:
            continue
        start = walk_back_to_source(flow.entry, ENTER_FLOW_BACK)
        return [{"start_actor_flow": xml_location(start), "end_actor_flow": xml_location(end)}]
    return []


register_layouts({
    "EnterActorFlow": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns right into a road that a left "
        "entry's straight lane continues on", turns=("right",), signalized=False, departure=(35.0, 45.0),
        junction_extra=_enter_flow),
})  # fmt: skip
# routes_training's 36 EnterActorFlow routes all join Town12's highway by on-ramps (ramps at 7-45 deg to it, flows
# 145-317 m long at 15-20 m/s, 15-30 / 30-70 m apart): a non-yielding flow that dense is entered at its own speed from
# a lane of one's own, not by a turn from a standstill (bench2drive220's routes, 12-19 m/s, include urban turns).
register_param_layouts(TRAINING.name, {
    "EnterActorFlow": Layout(
        "highway_ramps", "an on-ramp whose lane runs on beside a highway (>= 80 km/h) lane after its junction (the "
        "flows run on every highway lane)", turns=("straight", "left", "right"), junction_ok=ramp.dedicated_entry,
        junction_extra=ramp.flow_beside, approach=ramp.APPROACH, departure=ramp.DEPARTURE,
        trigger_offset=ramp.TRIGGER_OFFSET, merge_left_after=ramp.MERGE_AFTER),
})  # fmt: skip
