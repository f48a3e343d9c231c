"""ParkingCrossingPedestrian (§2.2 #15): a pedestrian steps out into the road from in front of a parked car.

A car stands parked (hand brake) in the ``direction``-side parking lane ``distance`` m after the trigger; the
pedestrian appears at the trigger just in front of it (car half length + 0.5 m), facing the road (turned by
``crossing_angle``), and stands there until the ego's time to arrival at the lane point abreast of it drops below
``2.15 + 0.1 × floor(angle / 5)`` s (or within 6 m). It then walks 8 m at 2 m/s across the ego's lane and is removed
with the car; the scenario ends 40 m later.

Placement accepts what LB2.0's ``_initialize_actors`` accepts (``object_crash_vehicle.py``, ParkingCrossingPedestrian):
the lane point ``distance`` m on may be anywhere, a junction included, and the car and the walker stand one lane
width to the side of the driving lane, whatever lies there. Where there is a parking lane, the car stands at its
centre and the walker abreast of it, as before; without one (evaluation routes of towns whose streets have none),
LB2.0's rule applies. Generated routes are always placed at a parking lane away from junctions
(``placement.py``), so the fallback only serves evaluation XML routes.
"""

from __future__ import annotations

import logging
import math

from b2d_data.format.transform import Vector3D
from b2d_data.maps import LaneType, Map, Waypoint
from b2d_data.scenarios.catalog.actor_choices import half_extent, random_parked_car, random_walker
from b2d_data.scenarios.catalog.layout import (
    STRAIGHTISH,
    Layout,
    leftmost_beside_parking,
    parking_ahead,
    register_layouts,
    rightmost,
)
from b2d_data.scenarios.catalog.road_geometry import move_along, neighbour, offset_transform
from b2d_data.scenarios.controllers import WalkerController, park
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, TimeToArrivalTrigger
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


@register
class ParkingCrossingPedestrian(Scenario):
    """A pedestrian hidden by a parked car crosses in front of the ego."""

    xml_type = "ParkingCrossingPedestrian"
    scenario_timeout = None
    timeout_test = False
    walker_speed = 2.0
    walk_distance = 8.0
    min_trigger_distance = 6.0
    end_distance = 40.0
    clear_extra = 15.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.distance = ctx.value("distance", 12.0)
        self.direction = ctx.text("direction", "right")
        if self.direction not in ("left", "right"):
            raise ScenarioSetupError(f"{self.name}: direction must be 'left' or 'right', got {self.direction!r}")
        self.crossing_angle = ctx.value("crossing_angle", 0.0)
        self.sign = 1.0 if self.direction == "right" else -1.0
        # LB2.0: ``reference_waypoint.next(distance)[0]``, refused only where the lane has no continuation.
        wp = move_along(self.trigger_waypoint, self.distance)
        if wp is None:
            raise ScenarioSetupError(f"{self.name}: the lane ends within {self.distance:.0f} m of the trigger point")
        side = neighbour(wp, self.direction)
        self.lane_waypoint = wp
        #: The parking lane the car stands in; None: one lane width to the side (LB2.0's ``_get_blocker_transform``).
        self.parking = side if side is not None and side.lane_type & LaneType.PARKING else None
        self.car_model = random_parked_car(ctx.rng)
        car_half_length = half_extent(self.car_model)[0]
        ahead = move_along(wp, car_half_length + 0.5)
        if ahead is None:
            raise ScenarioSetupError(f"{self.name}: the lane ends in front of the parked car")
        self.collision_waypoint = ahead
        walker_spot = neighbour(ahead, self.direction) if self.parking is not None else None
        self.walker_lateral = self.sign * (
            ahead.transform.location.distance_2d(walker_spot.transform.location)
            if walker_spot is not None
            else ahead.lane_width  # LB2.0's ``_get_walker_transform``: one lane width of the walker's lane point
        )
        self.car: int | None = None
        self.walker: int | None = None
        self._walk: WalkerController | None = None
        trigger_time = 2.15 + 0.1 * math.floor(self.crossing_angle / 5.0)
        self._tta = TimeToArrivalTrigger(self.collision_waypoint.transform.location, trigger_time,
                                         self.min_trigger_distance)  # fmt: skip
        self._removed = False
        self._after = DriveDistance(self.end_distance)

    def build(self) -> None:
        """The parked car in the parking lane, else one lane width to the side of the driving lane."""
        if self.parking is not None:
            base, lateral = self.parking.transform, 0.0
        else:
            base, lateral = self.lane_waypoint.transform, self.sign * self.lane_waypoint.lane_width
        transform = offset_transform(base, lateral=lateral, z=0.05)
        retries = [offset_transform(base, lateral=lateral, forward=f, z=0.05) for f in (-1.0, 1.0)]
        self.car = self.spawn(self.car_model, transform, retries=retries)
        park(self.ctx.sim, self.car)

    def start(self, snapshot: Snapshot) -> None:
        """Keep the background away from the crossing; the walker takes its place (object_crash_vehicle.py)."""
        self.ctx.sim.background.leave_space_in_front(self.distance + self.clear_extra)
        self._spawn_walker()

    def _walker_yaw(self) -> float:
        return 270.0 - self.crossing_angle if self.direction == "right" else 90.0 + self.crossing_angle

    def _spawn_walker(self) -> None:
        """The walker, standing where it will step out from, facing the road (LB2.0 places it there at the trigger)."""
        yaw = self._walker_yaw()
        base = self.collision_waypoint
        candidates = [
            offset_transform(base, lateral=self.walker_lateral, forward=f, z=1.0, yaw=yaw) for f in (0.0, 0.4, 0.8, 1.2)
        ]
        self.walker = self.spawn(random_walker(self.ctx.rng), candidates[0], retries=candidates[1:])

    def _start_walk(self) -> None:
        assert self.walker is not None  # spawned by start()
        base = self.collision_waypoint
        yaw = self._walker_yaw()
        heading = math.radians(base.transform.rotation.yaw + yaw)
        self._walk = WalkerController(
            self.ctx.sim, self.walker, Vector3D(math.cos(heading), math.sin(heading), 0.0), self.walker_speed,
            self.walk_distance,
        )  # fmt: skip

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """TTA trigger → walk 8 m → remove → 40 m more."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        if self._walk is None:
            if self._tta.check(ego):
                self._start_walk()
            return ScenarioStatus.RUNNING
        if not self._removed:
            self._walk.run_step(snapshot)
            if not self._walk.done:
                return ScenarioStatus.RUNNING
            self._removed = True
            for actor_id in (self.walker, self.car):
                if actor_id is not None:
                    self.destroy(actor_id)
        return ScenarioStatus.SUCCESS if self._after.check(ego) else ScenarioStatus.RUNNING


# ------------------------------------------------------------------------------------------------ placement


def _parked_car_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """ParkingCrossingPedestrian: a parking lane on the right around a car ``distance`` m after the trigger."""
    return parking_ahead((distance - 2.0, distance + 2.0, distance + 7.0))(town, wp)


register_layouts({
    "ParkingCrossingPedestrian": Layout("parking_lane", "rightmost lane with a parking lane on the right 34–52 m "
                                        "(or leftmost with one on the left) "
                                        "ahead, 100 m junction-free", rightmost, clear_after=100.0,
                                        extra=parking_ahead((34.0, 40.0, 46.0, 52.0)), max_turn=STRAIGHTISH,
                                        reach_param="distance", reach_ok=_parked_car_at,
                                        directions={"right": rightmost, "left": leftmost_beside_parking},
                                        extra_sides=("right",)),
})  # fmt: skip
