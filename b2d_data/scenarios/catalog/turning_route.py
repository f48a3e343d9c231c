"""VehicleTurningRoutePedestrian and VehicleTurningRoute (§2.2 #20, #21): someone crosses the road the ego turns into.

VehicleTurningRoutePedestrian: from the trigger on a pedestrian stands on the exit road's sidewalk just past the
junction (left side for a right turn, right side for a left turn, as LB2.0's), facing across; when the ego's time to
arrival at the first exit-lane point (+0.5 m) drops below 2.2 s (or within 6 m) it walks across the whole exit road
at 1.8 m/s and is removed.
VehicleTurningRoute: a ``vehicle.diamondback.century`` bicycle on the right side of the exit road 11 m after the
first exit point, facing the road; TTA (1.8 s, 6 m) on that lane point; it crosses at 1.8 m/s for twice its distance
to the lane point and is removed. Both end when the ego has driven 40 m more.

The background is left alone at the trigger; when the crosser starts (at the TTA trigger) the background leaves the
crossing space: LB2.0's ``LeaveCrossingSpace(collision_wp)`` removes the opposite vehicles within 20 m of the lane
left of the crossing point and stops those within 30 m.

VehicleTurningRoutePedestrian keeps LB2.0's own CollisionTest in route mode (VehicleTurningRoute returns none): the
route adds it to its criteria, so a collision from the trigger to the scenario's end is counted twice.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from b2d_data.format.transform import Vector3D
from b2d_data.maps import LaneType, Waypoint
from b2d_data.scenarios.catalog.actor_choices import random_walker
from b2d_data.scenarios.catalog.junctions import JunctionScenario
from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.catalog.road_geometry import (
    find_side_lane,
    lateral_offset,
    move_along,
    offset_transform,
    opposite_driving_neighbour,
    outermost_lane,
)
from b2d_data.scenarios.controllers import ConstantVelocityAgent, PathTrack, WalkerController, park
from b2d_data.scenarios.criteria.base import Criterion
from b2d_data.scenarios.criteria.collision import CollisionTest
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, TimeToArrivalTrigger
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)

#: VehicleTurningRoute's crosser (object_crash_intersection.py requests this blueprint).
BICYCLE = "vehicle.diamondback.century"


def road_side_offset(wp: Waypoint, side: str) -> float:
    """Signed lateral offset (m, + right) from ``wp``'s lane centre to the road's ``side`` sidewalk, or 1.5 m past
    the outermost lane where there is none (the far side of a two-way road is reached over the opposite lanes)."""
    sign = 1.0 if side == "right" else -1.0
    base, walk_side = wp, side
    if side == "left":
        opposite = opposite_driving_neighbour(outermost_lane(wp, "left"))
        if opposite is not None:
            base, walk_side = opposite, "right"  # the opposite lanes' right is the ego's left
    sidewalk = find_side_lane(base, walk_side, LaneType.SIDEWALK)
    if sidewalk is not None:
        return lateral_offset(wp, sidewalk)
    outer = outermost_lane(base, walk_side)
    return lateral_offset(wp, outer) + sign * (0.5 * outer.lane_width + 1.5)


class _TurningRouteScenario(JunctionScenario):
    """The junction set-up both share: the route turns, the crosser waits on the exit road."""

    required_turn = ("left", "right")
    scenario_timeout = None
    timeout_test = False
    end_distance = 40.0
    min_trigger_distance = 6.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        if self.ego_exit is None:
            raise ScenarioSetupError(f"{self.name}: layout missing: the route ends inside junction {self.junction.id}")
        self._removed = False
        self._after = DriveDistance(self.end_distance)

    def lane_point(self, distance: float) -> Waypoint:
        """The exit-lane waypoint ``distance`` m after the junction (junction-free, else a setup error)."""
        wp = move_along(self.ego_exit, distance) if distance > 0 else self.ego_exit
        if wp is None or wp.is_junction:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: no junction-free exit lane {distance:.1f} m after junction "
                f"{self.junction.id}"
            )
        return wp

    def leave_crossing_space(self) -> None:
        """LB2.0's ``LeaveCrossingSpace(self._collision_wp)`` as the crosser starts (route mode)."""
        self.ctx.sim.background.leave_crossing_space(self.collision_waypoint)


@register
class VehicleTurningRoutePedestrian(_TurningRouteScenario):
    """A pedestrian crosses the exit road of the ego's turn."""

    xml_type = "VehicleTurningRoutePedestrian"
    sync_time = 2.2
    walker_speed = 1.8

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.collision_waypoint = self.lane_point(0.5)
        # LB2.0 (object_crash_intersection.py) starts the walker at right_wp when entry × exit has z < 0 (a left
        # turn) and at left_wp otherwise: always the side of the exit road away from the turn's inner corner
        side = "left" if self.ego_turn == "right" else "right"
        self.start_lateral = road_side_offset(self.collision_waypoint, side)
        other = road_side_offset(self.collision_waypoint, "left" if side == "right" else "right")
        self.walk_distance = abs(self.start_lateral - other)
        self._tta = TimeToArrivalTrigger(
            self.collision_waypoint.transform.location, self.sync_time, self.min_trigger_distance
        )
        self.walker: int | None = None
        self._walk: WalkerController | None = None
        self._yaw = 270.0 if side == "right" else 90.0

    def start(self, snapshot: Snapshot) -> None:
        """The pedestrian appears on the exit road's sidewalk, facing across.

        LB2.0 spawns it at build 200 m underground and lifts it into place at the trigger
        (object_crash_intersection.py).
        """
        base = self.collision_waypoint
        candidates = [
            offset_transform(base, lateral=self.start_lateral, forward=f, z=1.0, yaw=self._yaw)
            for f in (0.0, 0.5, 1.0, 1.5)
        ]
        self.walker = self.spawn(random_walker(self.ctx.rng), candidates[0], retries=candidates[1:])

    def extra_criteria(self) -> list[Criterion]:
        """A second CollisionTest on the ego, from the trigger to the end.

        LB2.0's ``VehicleTurningRoutePedestrian._create_test_criteria`` returns ``[CollisionTest(ego)]`` in route
        mode too (object_crash_intersection.py), unlike VehicleTurningRoute's empty list; the route criteria take it
        in and the statistics multiply every criterion's events, so such a collision costs its factor twice.
        """
        return [CollisionTest(self.ctx.ego_id)]

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """TTA trigger → walk across the exit road → remove → 40 m more."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        if self._walk is None and self.walker is not None:
            if not self._tta.check(ego):
                return ScenarioStatus.RUNNING
            self.leave_crossing_space()
            heading = math.radians(self.collision_waypoint.transform.rotation.yaw + self._yaw)
            self._walk = WalkerController(
                self.ctx.sim, self.walker, Vector3D(math.cos(heading), math.sin(heading), 0.0), self.walker_speed,
                self.walk_distance,
            )  # fmt: skip
        if self._walk is not None and not self._removed:
            self._walk.run_step(snapshot)
            if not self._walk.done:
                return ScenarioStatus.RUNNING
            self._removed = True
            if self.walker is not None:
                self.destroy(self.walker)
        return ScenarioStatus.SUCCESS if self._after.check(ego) else ScenarioStatus.RUNNING


@register
class VehicleTurningRoute(_TurningRouteScenario):
    """A bicycle crosses the exit road of the ego's turn."""

    xml_type = "VehicleTurningRoute"
    sync_time = 1.8
    bicycle_speed = 1.8
    exit_distance = 11.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.collision_waypoint = self.lane_point(self.exit_distance)
        self.start_lateral = road_side_offset(self.collision_waypoint, "right")
        self.cross_distance = 2.0 * abs(self.start_lateral)
        self._tta = TimeToArrivalTrigger(
            self.collision_waypoint.transform.location, self.sync_time, self.min_trigger_distance
        )
        self.bicycle: int | None = None
        self._agent: ConstantVelocityAgent | None = None

    def _crossing(self) -> np.ndarray:
        start = offset_transform(self.collision_waypoint, lateral=self.start_lateral)
        end = offset_transform(self.collision_waypoint, lateral=self.start_lateral - self.cross_distance)
        return np.array([[start.location.x, start.location.y, start.location.z],
                         [end.location.x, end.location.y, end.location.z]])  # fmt: skip

    def build(self) -> None:
        """The bicycle at the exit road's right edge, facing across."""
        base = self.collision_waypoint
        candidates = [
            offset_transform(base, lateral=self.start_lateral, forward=f, z=0.2, yaw=270.0) for f in (0.0, 1.0, -1.0)
        ]
        self.bicycle = self.spawn(BICYCLE, candidates[0], retries=candidates[1:])
        park(self.ctx.sim, self.bicycle)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """TTA trigger → cross at 1.8 m/s → remove → 40 m more."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        if self._agent is None and self.bicycle is not None:
            if not self._tta.check(ego):
                return ScenarioStatus.RUNNING
            self.leave_crossing_space()
            self._agent = ConstantVelocityAgent(self.ctx.sim, self.bicycle, PathTrack(self._crossing()),
                                                self.bicycle_speed)  # fmt: skip
        if self._agent is not None and not self._removed:
            self._agent.run_step(snapshot)
            if not self._agent.done:
                return ScenarioStatus.RUNNING
            self._removed = True
            if self.bicycle is not None:
                self.destroy(self.bicycle)
        return ScenarioStatus.SUCCESS if self._after.check(ego) else ScenarioStatus.RUNNING


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "VehicleTurningRoutePedestrian": Layout(
        "junction_turn", "a junction where the route turns", turns=("left", "right"), departure=(45.0, 50.0)),
    "VehicleTurningRoute": Layout(
        "junction_turn", "a junction where the route turns", turns=("left", "right"), departure=(50.0, 55.0)),
})  # fmt: skip
