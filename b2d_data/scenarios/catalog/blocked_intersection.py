"""BlockedIntersection (§2.2 #22): a car stands still just after the junction where the ego turns.

At the trigger a car with its brake lights on appears 5 m after the junction exit on the route (physics off); the
junction is cleared of background traffic and its entries stopped, and the route is kept clear up to the blocker. When the ego comes within 13 m of it, it stays
10 s more and is removed; the scenario then ends. The 240 s ScenarioTimeout applies.
"""

from __future__ import annotations

import logging

from b2d_data.scenarios.catalog.actor_choices import random_parked_car
from b2d_data.scenarios.catalog.junctions import JunctionScenario
from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.catalog.road_geometry import move_along, offset_transform
from b2d_data.scenarios.controllers import park
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import Timer, horizontal_distance
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)

#: CARLA's VehicleLightState flag name of the brake lights.
BRAKE_LIGHTS = "Brake"


@register
class BlockedIntersection(JunctionScenario):
    """Wait behind a car blocking the junction exit."""

    xml_type = "BlockedIntersection"
    required_turn = ("left", "right")
    blocker_distance = 5.0
    trigger_distance = 13.0
    block_time = 10.0
    blocker_clearance = 5.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        spot = move_along(self.ego_exit, self.blocker_distance) if self.ego_exit is not None else None
        if spot is None or spot.is_junction:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: no lane {self.blocker_distance:.0f} m after junction {self.junction.id}"
            )
        self.blocker_waypoint = spot
        self.blocker: int | None = None
        self._wait = Timer(self.block_time)
        self._reached = False

    def start(self, snapshot: Snapshot) -> None:
        """Clear the junction, stop its entries, place the blocker."""
        sim = self.ctx.sim
        sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=[], remove_exits=[self.blocker_waypoint],
            stop_entries=True, extend_road_exit=0.0,
        )  # fmt: skip
        # background cars on the route ahead would queue behind the blocker in front of the ego, and the blocker
        # waits for the ego: keep the route clear up to it
        route = self.ctx.route
        blocker_s = route.cumulative_length[route.closest_index(self.blocker_waypoint.transform.location)]
        ego_s = route.cumulative_length[self.ego_route_point(snapshot)]
        sim.background.leave_space_in_front(float(blocker_s - ego_s) + self.blocker_clearance)
        transforms = [offset_transform(self.blocker_waypoint, forward=f, z=0.05) for f in (0.0, 1.0, 2.0)]
        self.blocker = self.spawn(random_parked_car(self.ctx.rng), transforms[0], retries=transforms[1:])
        sim.set_simulate_physics(self.blocker, False)
        sim.set_light_state(self.blocker, BRAKE_LIGHTS)
        park(sim, self.blocker)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Within 13 m of the blocker: 10 s more, then remove it and end."""
        ego = self.ctx.ego(snapshot)
        if ego is None or self.blocker is None:
            return ScenarioStatus.RUNNING
        if not self._reached:
            blocker = snapshot.actors.get(self.blocker)
            if blocker is not None and horizontal_distance(ego.location, blocker.location) < self.trigger_distance:
                self._reached = True
                log.debug("%s: ego within %.0f m of the blocker", self.name, self.trigger_distance)
            return ScenarioStatus.RUNNING
        if self._wait.check(snapshot):
            self.destroy(self.blocker)
            self.blocker = None
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "BlockedIntersection": Layout(
        "junction_turn", "a junction where the route turns", turns=("left", "right")),
})  # fmt: skip
