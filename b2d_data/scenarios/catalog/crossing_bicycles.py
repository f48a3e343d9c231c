"""CrossingBicycleFlow (§2.2 #36): a flow of bicycles rides straight through the junction on a bike lane while the
ego turns across it.

The bicycles (CARLA's bicycle blueprints, each with its rider) ride from ``start_actor_flow`` on the bike lane
through the junction to 40 m past its exit at ``flow_speed`` m/s, ignoring lights and every vehicle (the ego too,
collision or not: LB2.0's ``BicycleFlow`` drives them with BasicAgents set to ``ignore_vehicles`` and has no
collision sensor), the path pre-populated, a new one once the last has ridden a gap drawn from
``source_dist_interval``. On a signalised junction the ego's light is
red for 5 s, then green (the others red). The background clears the junction and stops its entries; unlike LB2.0
the route sources are off while the bicycles ride. The scenario ends when the ego leaves the junction, or after
240 s.
"""

from __future__ import annotations

import logging
from typing import ClassVar

from b2d_data.format.transform import Location
from b2d_data.maps import LaneType, Map, Waypoint
from b2d_data.scenarios.catalog.flows import FlowScenario
from b2d_data.scenarios.catalog.junctions import (
    JunctionScenario,
    LightSchedule,
    light_states,
    lights_of_lane,
    walk_back_to_source,
)
from b2d_data.scenarios.catalog.layout import Layout, register_layouts, xml_location
from b2d_data.scenarios.catalog.road_geometry import JunctionLane, entries_from, find_side_lane, lane_walk
from b2d_data.scenarios.framework import ScenarioContext, ScenarioError, ScenarioSetupError, register
from b2d_data.scenarios.triggers import WaitEndIntersection
from b2d_data.sim import blueprints
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)

#: The bicycle path continues this far past the junction exit (m).
PAST_EXIT = 40.0
#: The longest bike-lane walk from the source to the junction (m).
MAX_APPROACH = 200.0


def bicycle_path(source: Waypoint, junction_id: int | None = None, past_exit: float = PAST_EXIT) -> list[Waypoint]:
    """Bike-lane waypoints 1 m apart from ``source`` straight through the next junction (or junction
    ``junction_id``) to ``past_exit`` m beyond it; raises when the lane meets no such junction."""
    walk = lane_walk(source, MAX_APPROACH + 100.0 + past_exit)
    inside = [k for k, wp in enumerate(walk) if wp.is_junction and junction_id in (None, wp.junction_id)]
    if not inside or inside[0] == 0:
        where = "junction" if junction_id is None else f"junction {junction_id}"
        raise ScenarioSetupError(
            f"the bike lane from road {source.road_id} lane {source.lane_id} does not ride into the {where} ahead"
        )
    last = inside[0]
    while last + 1 < len(walk) and walk[last + 1].is_junction:
        last += 1
    end = last + 1 + int(past_exit)
    if end >= len(walk) or any(wp.is_junction for wp in walk[last + 1 : end + 1]):
        raise ScenarioSetupError(
            f"the bike lane from road {source.road_id} lane {source.lane_id} does not continue {past_exit:.0f} m "
            "past the junction"
        )
    return walk[: end + 1]


def bike_lane_at(town: Map, loc: Location) -> Waypoint | None:
    """The bike-lane waypoint nearest ``loc`` (None if no bike lane lies within 3 m)."""
    wp = town.get_waypoint(loc, lane_type=LaneType.BIKING)
    if wp is None or wp.transform.location.distance_2d(loc) > 3.0:
        return None
    return wp


@register
class CrossingBicycleFlow(FlowScenario, JunctionScenario):
    """Turn across a flow of bicycles riding straight through the junction on a bike lane (§2.2 #36)."""

    xml_type = "CrossingBicycleFlow"
    green_light_delay: ClassVar[float] = 5.0
    #: LB2.0's default ``source_dist_interval`` (cross_bicycle_flow.py); generated routes always set it.
    default_interval: ClassVar[tuple[float, float]] = (20.0, 50.0)
    # A deviation from LB2.0: no new route vehicles ahead of the ego while the bicycles ride. One spawned after the
    # clearing that turns across the flow waits for a gap the dense flow never leaves, and the ego behind it.
    route_sources_off = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        x, y = ctx.config.parameter("start_actor_flow", "x"), ctx.config.parameter("start_actor_flow", "y")
        if x is None or y is None:
            raise ScenarioSetupError(f"{self.name}: parameter <start_actor_flow x=... y=...> missing")
        try:
            loc = Location(float(x), float(y), float(ctx.config.parameter("start_actor_flow", "z") or 0.0))
        except ValueError:
            raise ScenarioSetupError(f"{self.name}: <start_actor_flow> has non-numeric coordinates") from None
        source = bike_lane_at(ctx.map, loc)
        if source is None:
            raise ScenarioSetupError(
                f"{self.name}: layout 'bike_lane' missing: no bike lane at start_actor_flow ({loc.x:.1f}, {loc.y:.1f})"
            )
        try:
            self.path = bicycle_path(source, self.junction.id)
        except ScenarioSetupError as exc:
            raise ScenarioSetupError(f"{self.name}: layout 'bike_lane' missing: {exc}") from None
        self.lights: LightSchedule | None = None
        self._left = WaitEndIntersection(ctx.map, self.junction.id)

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Clear the junction and stop its entries (the route sources stop too, see ``route_sources_off``)."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=[], remove_exits=[], stop_entries=True,
            extend_road_exit=0.0,
        )  # fmt: skip

    def start_flows(self, snapshot: Snapshot) -> None:
        """The pre-populated bicycle flow and the lights."""
        bikes = blueprints.filter_ids("vehicle.*", base_type="bicycle")
        self.add_flow(self.path, initial_actors=True, blueprint_ids=bikes, yield_after_collision=False)
        lights = self.junction_lights(snapshot)
        if lights:
            ego_lights = lights_of_lane(lights, self.ego_entry)
            self.lights = LightSchedule(self.ctx.sim, [
                (light_states(lights, []), self.green_light_delay), (light_states(lights, ego_lights), None),
            ])  # fmt: skip
            self.lights.update(snapshot)

    def step(self, snapshot: Snapshot) -> None:
        """Run the light schedule."""
        if self.lights is not None:
            self.lights.update(snapshot)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego has left the junction."""
        ego = self.ctx.ego(snapshot)
        return ego is not None and self._left.check(ego)

    def restore_background(self) -> None:
        """Release the lights."""
        if self.lights is not None:
            self.lights.release()


# ------------------------------------------------------------------------------------------------ placement


#: CrossingBicycleFlow's bicycles start this far before the junction on the bike lane (m).
BICYCLE_FLOW_BACK = 30.0


def _bicycle_flow(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """A bike lane right of an opposite entry that runs straight through the junction: the flow's start and end."""
    for entry in entries_from(lanes, conn.entry, "opposite"):
        bike = find_side_lane(entry, "right", LaneType.BIKING)
        if bike is None:
            continue
        start = walk_back_to_source(bike, BICYCLE_FLOW_BACK)
        try:
            path = bicycle_path(start, conn.junction_id)
        except ScenarioError:
            continue
        return [{"start_actor_flow": xml_location(start), "end_actor_flow": xml_location(path[-1])}]
    return []


register_layouts({
    "CrossingBicycleFlow": Layout(
        "bike_lane", "a junction where the route turns left across an opposite bike lane that continues straight "
        "through it", turns=("left",), junction_extra=_bicycle_flow),
})  # fmt: skip
