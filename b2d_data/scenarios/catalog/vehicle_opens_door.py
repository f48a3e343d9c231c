"""VehicleOpensDoorTwoWays (§2.2 #13): a car parked beside the ego's lane opens its door into it on a two-way road.

The car (a model with doors that open) stands ``distance`` m ahead in the lane on the ``direction`` side (any lane, as
LB2.0's; generated routes put it in a parking lane or shoulder), pushed toward the ego's lane by (side-lane width −
car half-width) / 4. When the ego's time to arrival at the
lane point beside the car drops below 3 s (or it is within 10 m) the door on the traffic side opens and the background
behind the ego stops; 5 s later the wrong-direction check is switched off, the opposite background is switched off
and a flow starts. The scenario ends 50 m past the car (or after 240 s); the background behind then resumes.

The flow is LB2.0's, not ParkedObstacleTwoWays' opposite one: ``OppositeActorFlow(parked_wp.get_left_lane(), ...)``
(vehicle_opens_door.py) is anchored on the lane left of the parked car. For ``direction=right``
(``parked_wp = front_wp.get_right_lane()``) that is the ego's own driving lane: its source lies
``1.5 × limit [km/h] + 30`` m behind the car on that lane and its sink as far ahead (both stopping before a
junction), so in CARLA the ego meets an empty opposite lane and cars coming up behind it in its own lane. For
``direction=left`` (``parked_wp = front_wp.get_left_lane()``) it is the lane beyond the car, two lanes left of the
ego's. The car's lane point is ``next(distance)[0]`` from the trigger point; the default ``distance`` is LB2.0's 50 m.
"""

from __future__ import annotations

import logging
from typing import ClassVar

from b2d_data.maps import LaneType, Map, Waypoint
from b2d_data.scenarios.catalog.actor_choices import half_extent, random_car_with_doors
from b2d_data.scenarios.catalog.layout import STRAIGHTISH, Layout, register_layouts, two_way_single
from b2d_data.scenarios.catalog.obstacles import OppositeFlowObstacle
from b2d_data.scenarios.catalog.obstacles_placement import opposite_flow_room, opposite_flow_room_at
from b2d_data.scenarios.catalog.road_geometry import (
    move_along,
    neighbour,
    offset_transform,
)
from b2d_data.scenarios.controllers import park
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, register
from b2d_data.scenarios.triggers import Timer, TimeToArrivalTrigger
from b2d_data.sim.api import ActorState, ScenarioHint, Snapshot, VehicleDoor

log = logging.getLogger(__name__)

#: Side lanes a car can be parked in.
SIDE_LANE_TYPES = LaneType.PARKING | LaneType.SHOULDER
#: Narrower side lanes leave the parked car standing mostly in the driving lane.
MIN_SIDE_LANE_WIDTH = 2.0


def side_lane(wp: Waypoint, direction: str) -> Waypoint | None:
    """The parking lane or wide shoulder next to ``wp`` on ``direction``, or None (placement's layout check)."""
    other = neighbour(wp, direction)
    if other is None or not other.lane_type & SIDE_LANE_TYPES or other.lane_width < MIN_SIDE_LANE_WIDTH:
        return None
    return other


@register
class VehicleOpensDoorTwoWays(OppositeFlowObstacle):
    """A parked car opens its door into the ego's lane; the ego overtakes it through the opposite lane."""

    xml_type = "VehicleOpensDoorTwoWays"
    #: LB2.0's default ``distance`` (vehicle_opens_door.py), not the 120 m of the other obstacle scenarios.
    default_distance = 50.0
    jumps_to_obstacle = True
    clear_extra = 20.0
    tta_time: ClassVar[float] = 3.0
    tta_distance: ClassVar[float] = 10.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self._door_trigger = TimeToArrivalTrigger(self.obstacle_waypoint.transform.location, self.tta_time,
                                                  self.tta_distance)  # fmt: skip
        self._flow_wait = Timer(self.wait_duration)
        self.door_opened = False
        self._stopped_back = False

    def place_site(self) -> None:
        """The lane the car stands in: whatever lies to the ``direction`` side of the car's lane point.

        LB2.0 (vehicle_opens_door.py ``_initialize_actors``) takes ``front_wp.get_right_lane()`` /
        ``get_left_lane()`` of any type and width and refuses only where there is none; generated routes still put
        the car in a parking lane (or a 2 m shoulder) through their layout check (:func:`side_lane`).
        """
        side = neighbour(self.obstacle_waypoint, self.direction)
        if side is None:
            wp = self.obstacle_waypoint
            raise ScenarioSetupError(
                f"{self.name}: no lane {self.direction} of road {wp.road_id} lane {wp.lane_id} at the car"
            )
        self.side_waypoint = side

    def flow_anchor(self) -> Waypoint:
        """The parked car's lane point: LB2.0's flow runs on ``parked_wp.get_left_lane()`` (:meth:`flow_lane`),
        the ego's lane for ``right``, two lanes left of it for ``left``; a missing one is LB2.0's only refusal."""
        return self.side_waypoint

    def build(self) -> None:
        """The parked car, pushed toward the driving lane, hand brake on."""
        type_id = random_car_with_doors(self.ctx.rng)
        half_width = half_extent(type_id)[1]
        toward_road = -self.sign * (self.side_waypoint.lane_width - half_width) / 4.0
        wp = self.side_waypoint
        transform = offset_transform(wp, lateral=toward_road, z=0.2)
        retries = [offset_transform(wp, lateral=toward_road, forward=f, z=0.2) for f in (1.0, 2.0, -1.0)]
        self.first_id = self.spawn(type_id, transform, retries=retries)
        park(self.ctx.sim, self.first_id)

    def should_react(self, snapshot: Snapshot, ego: ActorState) -> bool:
        """The door opens at the TTA trigger; the opposite flow starts 5 s later."""
        if not self.door_opened and self._door_trigger.check(ego):
            self.open_door()
        return self.door_opened and self._flow_wait.check(snapshot)

    def open_door(self) -> None:
        """Open the traffic-side front door and stop the background behind the ego."""
        if self.first_id is None:
            return
        door = VehicleDoor.FL if self.direction == "right" else VehicleDoor.FR
        self.ctx.sim.open_door(self.first_id, door)
        self.ctx.sim.background.stop_back_vehicles()
        self.door_opened = self._stopped_back = True
        log.debug("%s: door %s opened", self.name, door.name)

    def on_end(self) -> None:
        """Restore the flow's changes and let the background behind the ego drive again."""
        super().on_end()
        if self._stopped_back:
            self.ctx.sim.background.start_back_vehicles()

    def hint(self) -> ScenarioHint | None:
        """The parked car (no last actor), on the ``direction`` side."""
        if self.first_id is None:
            return None
        return ScenarioHint(self.xml_type, self.first_id, None, direction=self.direction, extra=self.hint_extra())


# ------------------------------------------------------------------------------------------------ placement


def _door_side_lane(town: Map, wp: Waypoint) -> bool:
    """A parking lane (or wide shoulder) on the right where the car may stand (37–59 m after the trigger), and room
    for the opposite flow around it."""
    ahead: Waypoint | None = move_along(wp, 37.0, step=37.0)
    for _ in range(4):
        if ahead is None or side_lane(ahead, "right") is None:
            return False
        ahead = move_along(ahead, 7.0, step=7.0)
    return opposite_flow_room(town, wp)


def _door_side_lane_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """:func:`_door_side_lane` for a car ``distance`` m after the trigger."""
    for d in (distance, distance + 5.0):
        ahead = move_along(wp, d, step=5.0)
        if ahead is None or side_lane(ahead, "right") is None:
            return False
    return opposite_flow_room_at(town, wp, distance)


register_layouts({
    "VehicleOpensDoorTwoWays": Layout("parking_lane", "one lane each way with a parking lane (or a shoulder of "
                                      "2 m) on the right 37–59 m ahead, 115 m junction-free", two_way_single,
                                      clear_after=115.0, extra=_door_side_lane, max_turn=STRAIGHTISH,
                                      reach_param="distance", reach_ok=_door_side_lane_at),
})  # fmt: skip
