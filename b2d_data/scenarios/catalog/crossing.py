"""DynamicObjectCrossing (§2.2 #14): a pedestrian steps out from behind a prop on the sidewalk into the road.

A blocker (``blocker_model``: a prop, turned 90° toward the road, or a parked car along it; generated routes draw
the models of LB2.0's routes_training.xml, LB2.0's vending machine when the XML gives none) stands ``distance`` m
ahead on the first sidewalk reached walking ``direction``-wards over the lanes (any type or direction, as
LB2.0's ``_initialize_actors``; 1.5 m beyond the last lane where none is reached). At the trigger the pedestrian
appears just beyond it facing the road (turned by ``crossing_angle``) and stands there (as LB2.0 places it); when
the ego's time to arrival at the lane point abreast of the blocker drops below ``2.1 + 0.1 × floor(angle / 5)`` s
(or within 6 m) it walks at 2 m/s for twice its distance to the lane, and is removed with the blocker. The
scenario ends 40 m later. ``direction`` left across a two-way road's centre line is refused: LB2.0's walk would
go back and forth between lanes ±1 for good.
"""

from __future__ import annotations

import logging
import math

from b2d_data.format.transform import Vector3D
from b2d_data.maps import LaneType, Map, Waypoint
from b2d_data.scenarios.catalog.actor_choices import DEFAULT_BLOCKER_MODEL, half_extent, random_walker
from b2d_data.scenarios.catalog.layout import STRAIGHTISH, Layout, register_layouts, rightmost
from b2d_data.scenarios.catalog.road_geometry import (
    find_side_lane,
    is_driving,
    is_outermost_driving,
    lateral_offset,
    move_along,
    offset_transform,
    walk_through_junctions,
    walk_to_sidewalk,
)
from b2d_data.scenarios.controllers import WalkerController, park
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, TimeToArrivalTrigger
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


@register
class DynamicObjectCrossing(Scenario):
    """An occluded pedestrian crossing in front of the ego."""

    xml_type = "DynamicObjectCrossing"
    scenario_timeout = None
    timeout_test = False
    walker_speed = 2.0
    min_trigger_distance = 6.0
    end_distance = 40.0
    spawn_retries = 6
    retry_step = 0.4

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.distance = ctx.value("distance", 12.0)
        self.direction = ctx.text("direction", "right")
        if self.direction not in ("left", "right"):
            raise ScenarioSetupError(f"{self.name}: direction must be 'left' or 'right', got {self.direction!r}")
        self.blocker_model = ctx.text("blocker_model", DEFAULT_BLOCKER_MODEL)
        self.crossing_angle = ctx.value("crossing_angle", 0.0)
        self.sign = 1.0 if self.direction == "right" else -1.0
        # LB2.0 walks on through junctions (get_location_in_distance_from_wp(..., False)) and takes the map's lane
        # at the location reached; a spot inside a junction is accepted
        walked = walk_through_junctions(self.trigger_waypoint, self.distance)
        wp = ctx.map.get_waypoint(walked.transform.location) or walked
        self.lane_waypoint = wp
        walk = walk_to_sidewalk(wp, self.direction)
        if walk is None:
            raise ScenarioSetupError(
                f"{self.name}: no sidewalk to the {self.direction}: the lanes across the centre line lead back to "
                "the ego's side (LB2.0's walk there does not end)"
            )
        self.has_sidewalk = bool(walk[-1].lane_type & LaneType.SIDEWALK)
        # LB2.0: at the sidewalk's centre, else 1.5 m beyond the last lane's centre (``_get_sidewalk_transform``)
        self.blocker_lateral = self.sign * (abs(lateral_offset(wp, walk[-1])) + (0.0 if self.has_sidewalk else 1.5))
        #: LB2.0 turns props 90° toward the road and leaves vehicles along it (yaw 0).
        self.blocker_is_vehicle = "vehicle" in self.blocker_model
        self.blocker_yaw = 0.0 if self.blocker_is_vehicle else 90.0 * self.sign
        blocker_extent = half_extent(self.blocker_model)
        # the blocker's extent along the lane: y for a turned prop, x for a vehicle
        self.walker_forward = blocker_extent[0 if self.blocker_is_vehicle else 1] + 0.5 + 0.3
        self.collision_waypoint = move_along(wp, self.walker_forward) or wp
        self.blocker: int | None = None
        self.walker: int | None = None
        self._walk: WalkerController | None = None
        trigger_time = 2.1 + 0.1 * math.floor(self.crossing_angle / 5.0)
        # LB2.0 times the walker to the lane point abreast of the blocker (``_collision_wp``), not of the walker
        self._tta = TimeToArrivalTrigger(self.lane_waypoint.transform.location, trigger_time, self.min_trigger_distance)
        self._removed = False
        self._after = DriveDistance(self.end_distance)

    def build(self) -> None:
        """The blocker prop on the sidewalk."""
        yaw = self.blocker_yaw
        transform = offset_transform(self.lane_waypoint, lateral=self.blocker_lateral, yaw=yaw)
        retries = [
            offset_transform(self.lane_waypoint, lateral=self.blocker_lateral, forward=f, yaw=yaw) for f in (1.0, -1.0)
        ]
        self.blocker = self.spawn(self.blocker_model, transform, retries=retries)
        if self.blocker_is_vehicle:
            park(self.ctx.sim, self.blocker)  # LB2.0 turns its physics off: it stays put

    def start(self, snapshot: Snapshot) -> None:
        """Keep the background away from the crossing; the walker takes its place (object_crash_vehicle.py)."""
        self.ctx.sim.background.leave_space_in_front(self.distance + 10.0)
        self._spawn_walker()

    def _walker_yaw(self) -> float:
        return 270.0 - self.crossing_angle if self.direction == "right" else 90.0 + self.crossing_angle

    def _spawn_walker(self) -> None:
        """The walker, standing where it will step out from, facing the road (LB2.0 places it there at the trigger)."""
        yaw = self._walker_yaw()
        base = self.collision_waypoint
        candidates = [
            offset_transform(base, lateral=self.blocker_lateral, forward=k * self.retry_step, z=1.0, yaw=yaw)
            for k in range(self.spawn_retries)
        ]
        self.walker = self.spawn(random_walker(self.ctx.rng), candidates[0], retries=candidates[1:])

    def _start_walk(self) -> None:
        assert self.walker is not None  # spawned by start()
        base = self.collision_waypoint
        yaw = self._walker_yaw()
        heading = math.radians(base.transform.rotation.yaw + yaw)
        to_lane = abs(self.blocker_lateral)
        self._walk = WalkerController(
            self.ctx.sim,
            self.walker,
            Vector3D(math.cos(heading), math.sin(heading), 0.0),
            self.walker_speed,
            2.0 * to_lane,
        )

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """TTA trigger → walk across → remove → 40 m more."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        if self._walk is None:
            if self._tta.check(ego):
                # LB2.0 (route mode): LeaveCrossingSpace(self._collision_wp) as the walker sets off
                self.ctx.sim.background.leave_crossing_space(self.lane_waypoint)
                self._start_walk()
            return ScenarioStatus.RUNNING
        if not self._removed:
            self._walk.run_step(snapshot)
            if not self._walk.done:
                return ScenarioStatus.RUNNING
            self._removed = True
            for actor_id in (self.walker, self.blocker):
                if actor_id is not None:
                    self.destroy(actor_id)
        return ScenarioStatus.SUCCESS if self._after.check(ego) else ScenarioStatus.RUNNING


# ------------------------------------------------------------------------------------------------ placement


def _sidewalk_ahead(town: Map, wp: Waypoint) -> bool:
    """A sidewalk on the right where the blocker and the pedestrian stand (40–51 m after the trigger)."""
    return _sidewalk_at(town, wp, 40.0)


def _sidewalk_at(town: Map, wp: Waypoint, distance: float) -> bool:
    """A sidewalk on the right ``distance`` to ``distance + 11`` m after the trigger (blocker, then pedestrian)."""
    ahead: Waypoint | None = move_along(wp, distance, step=10.0)
    for step in (5.0, 6.0, 0.0):
        if ahead is None or find_side_lane(ahead, "right", LaneType.SIDEWALK) is None:
            return False
        if step:
            ahead = move_along(ahead, step, step=step)
    return True


def _sidewalk_on_left(wp: Waypoint) -> bool:
    """The leftmost driving lane of its direction, with a sidewalk reached walking left as LB2.0 walks (one-way
    roads: a two-way road's walk crosses the centre line and never ends)."""
    if not is_driving(wp) or not is_outermost_driving(wp, "left"):
        return False
    walk = walk_to_sidewalk(wp, "left")
    return walk is not None and bool(walk[-1].lane_type & LaneType.SIDEWALK)


register_layouts({
    "DynamicObjectCrossing": Layout("sidewalk", "rightmost lane with a sidewalk on the right (or leftmost with one on "
                                    "the left), 110 m junction-free", rightmost, clear_after=110.0,
                                    extra=_sidewalk_ahead, max_turn=STRAIGHTISH, reach_param="distance",
                                    reach_ok=_sidewalk_at, directions={"right": rightmost, "left": _sidewalk_on_left},
                                    extra_sides=("right",)),
})  # fmt: skip
