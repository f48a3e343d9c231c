"""YieldToEmergencyVehicle (§2.2 #17): an emergency vehicle with sirens approaches from behind in the ego's lane.

At the trigger the ego's lane is removed from background traffic and the vehicle appears ``distance`` m behind the
trigger point; a constant-velocity agent drives it at the ego's speed + 25 m/s (90 km/h), braking for vehicles in
its path. That is LB2.0's arithmetic: ``AdaptiveConstantVelocityAgentBehavior`` sets the agent's km/h target to
``get_speed(ego)`` [km/h] ``+ speed_increment * 3.6`` with ``speed_increment=25`` (atomic_behaviors.py), so the
increment is 25 m/s whatever its docstring says. A vehicle in its path within 10 m + its speed [m/s] sets its
speed to that vehicle's at once (CARLA's ConstantVelocityAgent hazard rule), so it closes in and tails an ego that
does not give way. The scenario ends 10 s after the vehicle came within 50 m of the
ego, or once it is in front of the ego (``WaitUntilInFront``: past the ego's lane point the two half-lengths ahead,
and within 10 m of it) and drove 50 m more; YieldToEmergencyVehicleTest then fails if the vehicle is still behind
the ego.
"""

from __future__ import annotations

import logging

from b2d_data.scenarios.catalog.actor_choices import SIREN_LIGHTS, random_emergency_vehicle
from b2d_data.scenarios.catalog.layout import STRAIGHTISH, Layout, multi_lane_any, register_layouts
from b2d_data.scenarios.catalog.road_geometry import (
    move_along,
    offset_transform,
    same_direction_driving_neighbour,
)
from b2d_data.scenarios.controllers import ConstantVelocityAgent, PathTrack, follow_lane
from b2d_data.scenarios.criteria.base import Criterion
from b2d_data.scenarios.framework import (
    Scenario,
    ScenarioContext,
    ScenarioSetupError,
    ScenarioStatus,
    YieldToEmergencyVehicleTest,
    register,
)
from b2d_data.scenarios.triggers import DistanceTrigger, DriveDistance, Timer, wait_until_in_front
from b2d_data.sim.api import ScenarioHint, Snapshot

log = logging.getLogger(__name__)


@register
class YieldToEmergencyVehicle(Scenario):
    """The ego must leave its lane to let an emergency vehicle pass."""

    xml_type = "YieldToEmergencyVehicle"
    scenario_timeout = None
    timeout_test = False
    #: m/s added to the ego's speed: LB2.0 adds ``25 * 3.6`` to a km/h speed (see the module docstring).
    speed_increment = 25.0
    trigger_distance = 50.0
    idle_time = 10.0
    end_distance = 50.0
    lane_refresh_ticks = 10

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.distance = ctx.value("distance", 140.0)
        start = move_along(self.trigger_waypoint, self.distance, forward=False)
        if start is None:
            raise ScenarioSetupError(
                f"{self.name}: the ego's lane does not extend {self.distance:.0f} m behind the trigger"
            )
        wp = self.trigger_waypoint
        if (
            same_direction_driving_neighbour(wp, "left") is None
            and same_direction_driving_neighbour(wp, "right") is None
        ):
            raise ScenarioSetupError(
                f"{self.name}: layout 'multi_lane' missing: road {wp.road_id} lane {wp.lane_id} has no same-direction "
                "lane to yield into"
            )
        self.start_waypoint = start
        self.ev: int | None = None
        self._agent: ConstantVelocityAgent | None = None
        self._close = DistanceTrigger(self.trigger_distance)
        self._idle = Timer(self.idle_time)
        self._passed = False
        self._ev_after = DriveDistance(self.end_distance)
        self._test: YieldToEmergencyVehicleTest | None = None
        self._seen = False
        #: The EV's cruising speed (m/s): the ego's speed + :attr:`speed_increment`, updated every tick.
        self.target_speed: float | None = None

    def start(self, snapshot: Snapshot) -> None:
        """Remove the ego's lane from the background, place the emergency vehicle behind and start it."""
        self.ctx.sim.background.remove_road_lane(self.trigger_waypoint)
        transforms = [offset_transform(self.start_waypoint, forward=f, z=0.2) for f in (0.0, -3.0, 3.0, -6.0)]
        self.ev = self.spawn(random_emergency_vehicle(self.ctx.rng), transforms[0], retries=transforms[1:])
        self.ctx.sim.set_light_state(self.ev, SIREN_LIGHTS)
        path = PathTrack.from_waypoints(follow_lane(self.start_waypoint, self.distance + 400.0))
        ego = self.ctx.ego(snapshot)
        speed = (ego.speed() if ego is not None else 0.0) + self.speed_increment
        self.target_speed = speed
        # ConstantVelocityAgent speeds up at once when its path clears; 10 m/s² keeps that character
        self._agent = ConstantVelocityAgent(
            self.ctx.sim,
            self.ev,
            path,
            speed,
            detect_vehicles=True,
            base_threshold=10.0,
            match_leader=True,
            resume_accel=10.0,
        )

    def extra_criteria(self) -> list[Criterion]:
        """YieldToEmergencyVehicleTest on the spawned vehicle."""
        if self.ev is None:
            return []
        self._test = YieldToEmergencyVehicleTest(self.ev)
        return [self._test]

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Drive the vehicle; end 10 s after it came close, or 50 m after it passed the ego."""
        ego = self.ctx.ego(snapshot)
        ev = snapshot.actors.get(self.ev) if self.ev is not None else None
        if ev is None:
            # not in the snapshot yet (spawned this tick), or removed by somebody else
            return ScenarioStatus.SUCCESS if self._seen else ScenarioStatus.RUNNING
        self._seen = True
        if ego is None or self._agent is None:
            return ScenarioStatus.RUNNING
        self.target_speed = ego.speed() + self.speed_increment
        self._agent.speed = self.target_speed
        self._agent.run_step(snapshot)
        if snapshot.frame % self.lane_refresh_ticks == 0:
            # The background keeps removed lanes as offsets from the ego's current lane; once the ego has moved
            # over, the emergency vehicle's lane would be refilled, so it is removed again.
            self.ctx.sim.background.remove_road_lane(self.trigger_waypoint)
        if self._close.check(ego, ev.location) and self._idle.check(snapshot):
            return ScenarioStatus.SUCCESS
        if not self._passed:
            self._passed = wait_until_in_front(self.ctx.map, ev, ego)
        if self._passed and self._ev_after.check(ev):
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Give the lane back to the background (under whichever ego-relative offsets it was removed)."""
        if self.ev is not None:
            for offset in range(-3, 4):
                self.ctx.sim.background.readd_road_lane(offset)

    def hint(self) -> ScenarioHint | None:
        """The emergency vehicle, once it exists."""
        if self.ev is None or self.ev not in self.actors:
            return None
        return ScenarioHint(self.xml_type, self.ev, self.ev, direction="left")


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    # Longer than the others: the scenario may last 10 s after the trigger, ~200 m on a fast road. The vehicle
    # starts ``distance`` m behind the trigger and closes in at 25 km/h (7 m/s): each metre further back takes the
    # ego up to four metres further (at 100 km/h) before the vehicle is near and the 10 s have passed. Generated
    # highways have no 600 m without a ramp junction, so the lengthened stretch may cross junctions straight on.
    "YieldToEmergencyVehicle": Layout("multi_lane", "two same-direction lanes, 35 m behind and 200 m ahead "
                                      "junction-free", multi_lane_any, clear_before=35.0, clear_after=200.0,
                                      max_turn=STRAIGHTISH, length=230.0, reach_param="distance",
                                      reach_ahead=4.0, reach_behind=1.0, reach_through_junctions=True),
})  # fmt: skip
