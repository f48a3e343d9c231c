"""ParkingExit (§2.2 #2): the ego starts parked between two cars in the parking lane and must merge into traffic.

At build the ego is moved from the route's first point into the parking lane beside it, pushed toward the outer
edge by (lane width − ego half width) / 4; parked cars stand ``front_vehicle_distance`` m ahead and
``behind_vehicle_distance`` m behind, equally displaced; a car appears in the driving lane beside the ego and drives
off (removed after 50 m). The background's road spawn spacing becomes ``flow_distance`` (25 m) until the ego drove
``front_vehicle_distance + 15`` m, which ends the scenario (or the 240 s timeout). The expert inserts the ego's own
waypoint at the front of its route because the ego no longer stands on the first route point.
"""

from __future__ import annotations

import logging

from b2d_data.format.rig import EGO_HALF_EXTENT
from b2d_data.format.transform import Transform
from b2d_data.maps import LaneType, Map, Waypoint
from b2d_data.scenarios.catalog.actor_choices import half_extent, random_parked_car
from b2d_data.scenarios.catalog.layout import Layout, any_lane, register_layouts
from b2d_data.scenarios.catalog.road_geometry import is_driving, move_along, neighbour, offset_transform
from b2d_data.scenarios.controllers import LaneFollowingAgent, park
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


@register
class ParkingExit(Scenario):
    """Leave a parking slot between two parked cars."""

    xml_type = "ParkingExit"
    side_end_distance = 50.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.direction = ctx.text("direction", "right")
        if self.direction not in ("left", "right"):
            raise ScenarioSetupError(f"{self.name}: direction must be 'left' or 'right', got {self.direction!r}")
        self.front_distance = ctx.value("front_vehicle_distance", 20.0)
        self.behind_distance = ctx.value("behind_vehicle_distance", 10.0)
        self.flow_distance = ctx.value("flow_distance", 25.0)
        self.sign = 1.0 if self.direction == "right" else -1.0
        reference = self.trigger_waypoint
        parking = neighbour(reference, self.direction)
        if parking is None or not parking.lane_type & LaneType.PARKING:
            raise ScenarioSetupError(
                f"{self.name}: layout 'parking_lane' missing: no parking lane to the {self.direction} of road "
                f"{reference.road_id} lane {reference.lane_id} at the trigger point"
            )
        front = move_along(parking, self.front_distance)
        behind = move_along(parking, self.behind_distance, forward=False)
        if front is None or behind is None:
            raise ScenarioSetupError(f"{self.name}: the parking lane is too short for the cars in front and behind")
        self.reference = reference
        self.parking = parking
        self._parked_slots = (front, behind)
        self.side_car: int | None = None
        self._side_agent: LaneFollowingAgent | None = None
        self._end = DriveDistance(self.front_distance + 15.0)

    def _displaced(self, wp: Waypoint, half_width: float) -> Transform:
        return offset_transform(wp, lateral=self.sign * (wp.lane_width - half_width) / 4.0, z=0.05)

    def build(self) -> None:
        """Parked cars, the ego moved into its slot, the car beside it."""
        sim = self.ctx.sim
        for wp in self._parked_slots:
            type_id = random_parked_car(self.ctx.rng)
            actor_id = self.spawn(type_id, self._displaced(wp, half_extent(type_id)[1]))
            park(sim, actor_id)
        sim.set_transform(self.ctx.ego_id, self._displaced(self.parking, EGO_HALF_EXTENT[1]))
        type_id = random_parked_car(self.ctx.rng)
        self.side_car = self.spawn(
            type_id,
            offset_transform(self.reference, z=0.2),
            retries=[offset_transform(self.reference, forward=f, z=0.2) for f in (-3.0, -6.0)],
        )
        park(sim, self.side_car)

    def start(self, snapshot: Snapshot) -> None:
        """Sparser background on the route lane; the car beside the ego drives off."""
        self.ctx.sim.background.change_road_behavior(spawn_dist=self.flow_distance)
        if self.side_car is not None:
            limit = self.ctx.map.speed_limit(self.reference) / 3.6
            self._side_agent = LaneFollowingAgent(
                self.ctx.sim, self.side_car, self.reference, limit, ignore=[self.ctx.ego_id]
            )

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Drive the side car for 50 m then remove it; SUCCESS once the ego drove front distance + 15 m."""
        if self._side_agent is not None and self.side_car is not None:
            self._side_agent.run_step(snapshot)
            if self._side_agent.travelled >= self.side_end_distance:
                self.destroy(self.side_car)
                self.side_car, self._side_agent = None, None
        ego = self.ctx.ego(snapshot)
        return ScenarioStatus.SUCCESS if self._end.check(ego) else ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Back to the normal spawn spacing."""
        self.ctx.sim.background.change_road_behavior(spawn_dist=15.0)


# ------------------------------------------------------------------------------------------------ placement


def _parking_slot(town: Map, wp: Waypoint) -> bool:
    """A parking lane on the right that extends 14 m back and forward."""
    return _slot_beside(wp, "right")


def _left_slot(wp: Waypoint) -> bool:
    """A driving lane with a parking lane on its left that extends 14 m back and forward (a one-way road's left
    kerb; a two-way road's left lane is the opposite one)."""
    return is_driving(wp) and _slot_beside(wp, "left")


def _slot_beside(wp: Waypoint, side: str) -> bool:
    parking = neighbour(wp, side)
    if parking is None or not parking.lane_type & LaneType.PARKING:
        return False
    for forward in (True, False):
        end = move_along(parking, 14.0, forward=forward)
        if end is None or not end.lane_type & LaneType.PARKING:
            return False
    return True


register_layouts({
    "ParkingExit": Layout("parking_lane", "a parking lane right of a driving lane (or left of it), 40 m "
                          "junction-free", any_lane,
                          clear_before=0.0, clear_after=40.0, pre=(0.0, 0.0), extra=_parking_slot,
                          directions={"right": any_lane, "left": _left_slot}, extra_sides=("right",)),
})  # fmt: skip
