"""Two slow bicycles ride at the right edge of the ego's lane: HazardAtSideLane (§2.2 #11, multi-lane road) and
HazardAtSideLaneTwoWays (§2.2 #12, two-way road: the bicycles are passed through the opposite lane)."""

from __future__ import annotations

import logging

from b2d_data.format.transform import Transform
from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.actor_choices import random_bicycle
from b2d_data.scenarios.catalog.layout import (
    STRAIGHTISH,
    Layout,
    multi_lane_rightmost,
    register_layouts,
    two_way_single,
)
from b2d_data.scenarios.catalog.road_geometry import (
    first_junction_ahead,
    move_along,
    offset_transform,
    opposite_driving_neighbour,
    same_direction_driving_neighbour,
)
from b2d_data.scenarios.controllers import PATH_STEP, LaneFollowingAgent, follow_lane, park
from b2d_data.scenarios.criteria import SWITCH_WRONG_DIRECTION
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DistanceTrigger, DriveDistance, Timer, is_in_front
from b2d_data.sim.api import ScenarioHint, Snapshot

log = logging.getLogger(__name__)


@register
class HazardAtSideLane(Scenario):
    """Bicycles at ``distance`` and ``distance + 9`` m ride at ``bicycle_speed`` for ``bicycle_drive_distance`` m.

    At the trigger the background leaves ``distance + 29`` m free and keeps 30 m extra space; 5 s after the ego
    came within 50 m of the first bicycle the background speed is capped at ``speed``; the scenario ends once the
    ego is ahead of the last bicycle and drove 50 m more, or after 240 s.

    One deviation from LB2.0: a ride that would take the bicycles into a junction ends ``junction_margin`` m before
    it (:meth:`ride`). A generated route ends before the junction that follows the scenario's stretch, so bicycles
    riding on would stop beyond the route's end, where no ego passes them and the scenario never ends: parked for
    good past a junction's exit, they held a background car at the junction's entry (waiting for room there, as
    TM's cars do), and the ego behind it, 10 m short of the end, until TickRuntime (base's routes 8300 and 8600 on
    Town101).
    """

    xml_type = "HazardAtSideLane"
    bicycle_gap = 9.0
    offset_fraction = 0.55  # of the half lane width, to the right
    trigger_distance = 50.0
    wait_duration = 5.0
    end_distance = 50.0
    #: Metres between the front bicycle's stop and the junction its ride would have entered.
    junction_margin = 3.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.distance = ctx.value("distance", 100.0)
        self.max_speed = ctx.value("speed", 60.0)
        self.bicycle_speed = ctx.value("bicycle_speed", 10.0)
        self.drive_distance = ctx.value("bicycle_drive_distance", 50.0)
        first = move_along(self.trigger_waypoint, self.distance)
        second = move_along(first, self.bicycle_gap) if first is not None else None
        if first is None or second is None or first.is_junction or second.is_junction:
            raise ScenarioSetupError(f"{self.name}: no junction-free lane {self.distance + 9:.0f} m after the trigger")
        self.check_layout(first)
        self._waypoints = (first, second)
        self.bicycles: list[int] = []
        self._agents: list[LaneFollowingAgent] = []
        self._approach = DistanceTrigger(self.trigger_distance)
        self._wait = Timer(self.wait_duration)
        self._capped = False
        self._passed = False
        self._after = DriveDistance(self.end_distance)

    def check_layout(self, first: Waypoint) -> None:
        """Needs a same-direction driving lane left of the first bicycle to pass them."""
        if same_direction_driving_neighbour(first, "left") is None:
            raise ScenarioSetupError(
                f"{self.name}: layout 'multi_lane' missing: no same-direction driving lane left of road "
                f"{first.road_id} lane {first.lane_id} to pass the bicycles"
            )

    def react(self) -> None:
        """5 s after the ego came within 50 m of the first bicycle: cap the background's speed."""
        self.ctx.sim.background.set_max_speed(self.max_speed / 3.6)

    def unreact(self) -> None:
        """Undo :meth:`react` at the end."""
        self.ctx.sim.background.set_max_speed(None)

    def _lateral(self, width: float) -> float:
        return self.offset_fraction * width / 2.0

    def build(self) -> None:
        """Two bicycles standing at the right edge of the lane."""
        for wp in self._waypoints:
            lateral = self._lateral(wp.lane_width)
            transform: Transform = offset_transform(wp, lateral=lateral, z=0.2)
            retries = [offset_transform(wp, lateral=lateral, forward=f, z=0.2) for f in (1.0, 2.0)]
            actor_id = self.spawn(random_bicycle(self.ctx.rng), transform, retries=retries)
            park(self.ctx.sim, actor_id)
            self.bicycles.append(actor_id)

    def ride(self) -> float:
        """Metres each bicycle rides: ``bicycle_drive_distance``, or less where the front bicycle's lane enters a
        junction sooner (both ride the same distance, keeping their gap: they ignore each other)."""
        reach = self.drive_distance + self.junction_margin + PATH_STEP
        found = first_junction_ahead(self._waypoints[-1], reach, PATH_STEP)
        if found is None:
            return self.drive_distance
        # the junction begins after the last lane point outside it, one step before its first point
        return max(0.0, min(self.drive_distance, found[1] - PATH_STEP - self.junction_margin))

    def start(self, snapshot: Snapshot) -> None:
        """Clear the road ahead and start both bicycles."""
        bg = self.ctx.sim.background
        bg.leave_space_in_front(self.distance + 29.0)
        bg.change_road_behavior(extra_space=30.0)
        ride = self.ride()
        for actor_id, wp in zip(self.bicycles, self._waypoints):
            path = follow_lane(wp, self.drive_distance + 30.0)
            self._agents.append(LaneFollowingAgent(
                self.ctx.sim, actor_id, path, self.bicycle_speed / 3.6, lateral_offset=self._lateral(wp.lane_width),
                max_distance=ride, accel=1.0, ignore=self.bicycles,
            ))  # fmt: skip

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Ride, cap the background near the bicycles, end 50 m after overtaking them."""
        for agent in self._agents:
            agent.run_step(snapshot)
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        first = snapshot.actors.get(self.bicycles[0])
        last = snapshot.actors.get(self.bicycles[-1])
        target = first.location if first is not None else self._waypoints[0].transform.location
        if not self._capped and self._approach.check(ego, target) and self._wait.check(snapshot):
            self._capped = True
            self.react()
        if not self._passed:
            self._passed = last is None or is_in_front(ego, last)
            if not self._passed:
                return ScenarioStatus.RUNNING
        return ScenarioStatus.SUCCESS if self._after.check(ego) else ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Undo the reaction and the extra space."""
        bg = self.ctx.sim.background
        if self._capped:
            self.unreact()
        if self._agents:
            bg.change_road_behavior(extra_space=0.0)

    def hint(self) -> ScenarioHint | None:
        """First and last bicycle, on the right."""
        if not self.bicycles:
            return None
        return ScenarioHint(self.xml_type, self.bicycles[0], self.bicycles[-1], direction="right")


@register
class HazardAtSideLaneTwoWays(HazardAtSideLane):
    """The bicycles of :class:`HazardAtSideLane` on a two-way road (§2.2 #12).

    5 s after the ego came within 50 m of the first bicycle the wrong-direction check is switched off and the
    opposite background spawns every ``frequency`` m (sparser). At the end the opposite spacing goes back to 40 m,
    but the wrong-direction check stays off for the rest of the route: LB2.0's behaviour ends with
    ``SwitchWrongDirectionTest(False)`` (route_obstacles.py, HazardAtSideLaneTwoWays._create_behavior), not True.
    """

    xml_type = "HazardAtSideLaneTwoWays"
    #: The opposite background's spawn distance outside the scenario (LB2.0's default).
    opposite_spawn_dist = 40.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.frequency = ctx.value("frequency", 100.0)
        self._triggered = False

    def check_layout(self, first: Waypoint) -> None:
        """Needs an opposite driving lane left of the first bicycle."""
        if opposite_driving_neighbour(first) is None:
            raise ScenarioSetupError(
                f"{self.name}: layout 'two_way_street' missing: no opposite driving lane left of road "
                f"{first.road_id} lane {first.lane_id} to pass the bicycles"
            )

    def react(self) -> None:
        """Allow the wrong direction and thin out the opposite background."""
        self.request_switch(SWITCH_WRONG_DIRECTION, False)
        self.ctx.sim.background.change_opposite_behavior(spawn_dist=self.frequency)

    def unreact(self) -> None:
        """Restore the opposite background's spacing (the wrong-direction test stays as :meth:`on_end` leaves it)."""
        self.ctx.sim.background.change_opposite_behavior(spawn_dist=self.opposite_spawn_dist)

    def start(self, snapshot: Snapshot) -> None:
        """As :class:`HazardAtSideLane`; remembers that the scenario ran (its end switches the test off)."""
        self._triggered = True
        super().start(snapshot)

    def on_end(self) -> None:
        """Undo the reaction; a scenario that ran leaves the wrong-direction test off, as LB2.0's does."""
        super().on_end()
        if self._triggered:
            # LB2.0 appends SwitchWrongDirectionTest(False) after the scenario's main behaviour whether or not the
            # reaction happened; the test is never switched back on by this scenario.
            self.request_switch(SWITCH_WRONG_DIRECTION, False)


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "HazardAtSideLane": Layout("multi_lane", "two same-direction lanes (ego on the right one), 130 m junction-free",
                               multi_lane_rightmost, clear_after=130.0, max_turn=STRAIGHTISH,
                               reach_param="distance"),
    "HazardAtSideLaneTwoWays": Layout("two_way_street", "one lane each way, 130 m junction-free",
                                      two_way_single, clear_after=130.0, max_turn=STRAIGHTISH,
                                      reach_param="distance"),
})  # fmt: skip
