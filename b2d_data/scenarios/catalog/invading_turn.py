"""InvadingTurn (§2.2 #18): oncoming cars cut into the ego's lane on a two-way road; the ego keeps to the right.

The flow source lies on the opposite lane ``distance + 30`` m ahead of the trigger; from it an opposite flow (a car
every 40 m at the ego lane's speed limit) drives toward the trigger, offset by ``−(offset + lane width / 2 − 0.7)``
m with the sink's lane width (as LB2.0), so that it reaches ≈ ``offset`` m past the centre line into the ego's lane.
Cones stand on the opposite lane every 5 m, ceil(distance / 10) of them, starting 15 m from the source toward the
ego, 0.4 lane widths toward that lane's outer edge (the reason the flow drives so far left). The ego's lane and the
normal opposite traffic are taken out of the background while the scenario runs; it ends when the ego is in front
of the source point and within 50 m of it, or after 240 s. No flow car appears while the ego is within 15 m of the
source (not in LB2.0, see start()).
"""

from __future__ import annotations

import logging

from b2d_data.format.transform import Transform
from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.actor_choices import CONSTRUCTION_CONE
from b2d_data.scenarios.catalog.flows import FlowScenario, flow_path
from b2d_data.scenarios.catalog.layout import Layout, register_layouts, two_way_single
from b2d_data.scenarios.catalog.road_geometry import move_along, offset_transform, opposite_driving_neighbour
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, register
from b2d_data.scenarios.triggers import is_in_front
from b2d_data.sim.api import ScenarioHint, Snapshot

log = logging.getLogger(__name__)


@register
class InvadingTurn(FlowScenario):
    """Cones on the opposite lane push an oncoming flow ``offset`` m into the ego's lane."""

    xml_type = "InvadingTurn"
    source_extra = 30.0
    #: LB2.0 ``_create_obstacle``: from ``source.next(10)[0]`` it steps 5 m and puts a cone, while the cones so far
    #: span less than ``distance / 2``: ceil(distance / 10) cones, the first 15 m from the source.
    cone_start = 10.0
    cone_gap = 5.0
    cone_side = 0.4  # of the opposite lane's width, toward its outer edge
    flow_gap = 40.0
    #: The flow's offset keeps this much of the car inside its own lane before ``offset`` is added (LB2.0).
    edge_margin = 0.7
    #: Not in LB2.0: no flow car appears at the source while the ego is within this distance (m) of it; see start().
    hero_clearance = 15.0
    #: LB2.0 ends the scenario once the ego is in front of the source point and within this distance (m) of it.
    check_distance = 50.0
    opposite_off = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.distance = ctx.value("distance", 100.0)
        self.offset = ctx.value("offset", 0.25)
        reach = self.distance + self.source_extra
        ahead = move_along(self.trigger_waypoint, reach)
        if ahead is None:
            raise ScenarioSetupError(f"{self.name}: the ego's lane ends within {reach:.0f} m of the trigger")
        source = opposite_driving_neighbour(ahead)
        sink = opposite_driving_neighbour(self.trigger_waypoint)
        if source is None or sink is None:
            wp = ahead if source is None else self.trigger_waypoint
            raise ScenarioSetupError(
                f"{self.name}: layout 'two_way_street' missing: no opposite driving lane left of road {wp.road_id} "
                f"lane {wp.lane_id} for the invading flow"
            )
        self.source_reference = ahead
        self.flow_waypoints = flow_path(source, sink, reach + 30.0)
        # LB2.0 ``_true_offset``: from the sink's lane width (the lane at the trigger), not the source's.
        self.lateral = -(self.offset + sink.lane_width / 2.0 - self.edge_margin)
        self.cone_waypoints = self._cone_waypoints(source)
        self.cones: list[int] = []

    def _cone_waypoints(self, source: Waypoint) -> list[Waypoint]:
        out: list[Waypoint] = []
        wp = move_along(source, self.cone_start)
        spanned = 0.0
        while wp is not None and spanned < 0.5 * self.distance:
            wp = move_along(wp, self.cone_gap)
            if wp is None:
                break
            out.append(wp)
            spanned += self.cone_gap
        if not out:
            raise ScenarioSetupError(f"{self.name}: the opposite lane ends before its first cone")
        return out

    def cone_transforms(self) -> list[Transform]:
        """Cones toward the opposite lane's outer edge, from the one nearest the source toward the ego."""
        return [offset_transform(wp, lateral=self.cone_side * wp.lane_width) for wp in self.cone_waypoints]

    def _put_up_cones(self) -> None:
        """The cones, spawned at the trigger: LB2.0 keeps them 200 m underground until then (invading_turn.py)."""
        for transform in self.cone_transforms():
            self.cones.append(self.spawn(CONSTRUCTION_CONE, transform))

    def prepare_background(self, snapshot: Snapshot) -> None:
        """Empty the ego's lane (the opposite traffic pauses too)."""
        self.ctx.sim.background.remove_road_lane(self.trigger_waypoint)

    def start_flows(self, snapshot: Snapshot) -> None:
        """Put up the cones, start the invading flow.

        The flow cars stop only for a box inside their swept path (no margin): the ego keeping right leaves them
        a few tenths of a metre, and with a margin each would stop before it and wait for ever.

        A departure from LB2.0's InvadingActorFlow, which spawns whenever its last car is 40 m from the source:
        ours holds the next car back while the ego is within ``hero_clearance`` of the source. Our cars appear at
        their offset, half in the ego's lane, where the expert's shift (it ends 10 m after the last cone, 5 m
        before the source) no longer keeps the ego clear of them; one spawned 5–7 m in front of an ego arriving at
        10 m/s was hit at once (routes 160003 / 160004 on Town101). LB2.0's car appears on its lane centre and its
        BasicAgent steers it out; tried here, our car steering out at full lock while it crawls off the source
        made the expert stop for it and then meet it at walking pace: 11 of 20 routes instead of 17. 15 m: at
        10 m/s (72 % of 50 km/h) the ego needs 4.7 m and two ticks (1 m) to stop, the two cars touch at about 5 m
        centre to centre, and the new car rolls toward the ego meanwhile.
        """
        self._put_up_cones()
        limit = self.ctx.map.speed_limit(self.trigger_waypoint)
        self.add_flow(self.flow_waypoints, limit / 3.6, (self.flow_gap, self.flow_gap), constant_velocity=False,
                      lateral_offset=self.lateral, lateral_margin=0.0, hero_clearance=self.hero_clearance)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego is in front of the flow's source point and within 50 m of it."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return False
        reference = self.source_reference.transform
        near = ego.location.distance(reference.location) < self.check_distance  # 3D, as WaitUntilInFrontPosition
        return near and is_in_front(ego, reference)

    def restore_background(self) -> None:
        """Give the ego's lane back to the background."""
        self.ctx.sim.background.readd_road_lane(0)

    def hint(self) -> ScenarioHint | None:
        """The cone nearest the ego first, the one nearest the source last, and the offset."""
        if not self.cones:
            return None
        return ScenarioHint(self.xml_type, self.cones[-1], self.cones[0], offset=self.offset)

    @property
    def flow_actor_ids(self) -> list[int]:
        """The live flow vehicles."""
        return self.flow.actor_ids if self.flow is not None else []


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "InvadingTurn": Layout("two_way_street", "one lane each way, 100 m junction-free", two_way_single,
                           clear_after=100.0, reach_param="distance"),
})  # fmt: skip
