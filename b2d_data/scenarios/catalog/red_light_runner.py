"""OppositeVehicleRunningRedLight (§2.2 #37): an emergency vehicle crosses the junction against its red light.

The adversary waits 30 m before the junction on the ``direction`` entry (left, right or opposite of the ego's);
when the ego's time to arrival at the conflict point drops below 2.2 s (or it is within 12 m) the adversary
crosses straight at 60 km/h with a constant-velocity agent ignoring everything (until its first collision, after
which it coasts), for the time it needs to reach 10 m past its exit, and is removed. The lights are frozen: the
ego's green, every other one red. The scenario ends when the ego has left the junction. The conflict point is where
the ego's and the adversary's entry lines cross (LB2.0), except for ``opposite`` (see ``_conflict_point``).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from b2d_data.format.transform import Location
from b2d_data.scenarios.catalog.actor_choices import SIREN_LIGHTS, random_emergency_vehicle
from b2d_data.scenarios.catalog.junctions import (
    JunctionScenario,
    LightSchedule,
    junction_flow_path,
    light_states,
    lights_of_lane,
)
from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    connection,
    entries_from,
    line_intersection,
    offset_transform,
    straightest_connection,
)
from b2d_data.scenarios.controllers import ConstantVelocityAgent, PathTrack, park
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import Timer, TimeToArrivalTrigger, WaitEndIntersection
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


@register
class OppositeVehicleRunningRedLight(JunctionScenario):
    """An emergency vehicle with sirens runs a red light across the ego's path."""

    xml_type = "OppositeVehicleRunningRedLight"
    signalized = True
    scenario_timeout = None
    timeout_test = False
    source_distance = 30.0
    sink_distance = 10.0
    adversary_speed = 60.0 / 3.6
    sync_time = 2.2
    min_trigger_distance = 12.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.direction = ctx.text("direction", "right")
        entries = entries_from(self.lanes, self.ego_entry, self.direction)
        if not entries:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: junction {self.junction.id} has no entry from the {self.direction}"
            )
        entry = entries[0]
        # LB2.0 (opposite_vehicle_taking_priority.py ``_initialize_actors``): the sink follows
        # ``generate_target_waypoint(source, 0)``, the straightest branch whatever its angle
        straight = straightest_connection(self.lanes, entry)
        if straight is None:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: the {self.direction} entry of junction {self.junction.id} has no "
                "connection through it"
            )
        try:
            self.path = junction_flow_path(straight, self.source_distance, self.sink_distance, back_step=1.0)
        except ScenarioSetupError as exc:
            raise ScenarioSetupError(f"{self.name}: layout missing: {exc}") from None
        self.spawn_waypoint, self.sink_waypoint = self.path[0], self.path[-1]
        self.conflict = self._conflict_point(entry)
        self.adversary: int | None = None
        self._agent: ConstantVelocityAgent | None = None
        self._tta = TimeToArrivalTrigger(self.conflict, self.sync_time, self.min_trigger_distance)
        crossing = self.spawn_waypoint.transform.location.distance(self.sink_waypoint.transform.location)
        self._crossing = Timer(crossing / self.adversary_speed)
        self._left = WaitEndIntersection(ctx.map, self.junction.id)
        self.lights: LightSchedule | None = None
        self._crossed = False

    def _conflict_point(self, entry) -> Location:
        """Where the ego's and the adversary's entry lines cross (LB2.0's ``get_geometric_linear_intersection``).

        For ``direction=opposite`` (placement's choice for a left-turning ego) those lines are near-parallel and
        LB2.0's point lies far away or nowhere, so the adversary would never start: there the conflict point is
        where the ego's route inside the junction meets the adversary's path.
        """
        if self.direction == "opposite":
            route = self.ctx.route
            stop = self.exit_index if self.exit_index is not None else len(route.waypoints)
            ego_xy = route.locations[self.entry_index : stop, :2]
            adv = np.array([[wp.transform.location.x, wp.transform.location.y] for wp in self.path])
            if len(ego_xy):
                d = np.hypot(ego_xy[:, None, 0] - adv[None, :, 0], ego_xy[:, None, 1] - adv[None, :, 1])
                i, k = np.unravel_index(int(np.argmin(d)), d.shape)
                if d[i, k] < 2.0:
                    return route.location(self.entry_index + int(i))
        crossing = line_intersection(self.ego_entry, entry)
        if crossing is None:
            raise ScenarioSetupError(
                f"{self.name}: the adversary's path from the {self.direction} does not cross the ego's route"
            )
        return crossing

    def build(self) -> None:
        """Check that the junction is signalised."""
        self.require_lights(self.ctx.sim.snapshot())

    def start(self, snapshot: Snapshot) -> None:
        """Prepare the junction, place the adversary, freeze the lights (ego green, others red)."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=[self.spawn_waypoint],
            remove_exits=[self.sink_waypoint], stop_entries=False, extend_road_exit=0.0,
        )  # fmt: skip
        self.spawn_adversary()
        lights = self.require_lights(snapshot)
        states = light_states(lights, lights_of_lane(lights, self.ego_entry))
        self.lights = LightSchedule(self.ctx.sim, [(states, None)])
        self.lights.update(snapshot)

    def spawn_adversary(self) -> None:
        """A seeded emergency vehicle with its sirens on at the source, parked until the trigger.

        LB2.0's ``_initialize_actors`` (opposite_vehicle_taking_priority.py), shared by both junction-crossing types,
        requests any ``special_type='emergency'`` vehicle and turns its special lights on.
        """
        transforms = [offset_transform(self.spawn_waypoint, forward=f, z=0.2) for f in (0.0, -2.0, -4.0, 2.0)]
        self.adversary = self.spawn(random_emergency_vehicle(self.ctx.rng), transforms[0], retries=transforms[1:])
        self.ctx.sim.set_light_state(self.adversary, SIREN_LIGHTS)
        park(self.ctx.sim, self.adversary)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Wait for the ego's time to arrival, let the adversary cross, then wait for the ego to leave the junction."""
        if self.lights is not None:
            self.lights.update(snapshot)
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        left = self._left.check(ego)
        if self.adversary is not None and self._agent is None and self._tta.check(ego):
            log.debug(
                "%s: adversary starts (ego %.1f m from the conflict point)",
                self.name,
                math.hypot(ego.location.x - self.conflict.x, ego.location.y - self.conflict.y),
            )
            track = PathTrack.from_waypoints(self.path)
            # ConstantVelocityAgentBehavior's CARLA agent drops its forced velocity at its first collision
            self._agent = ConstantVelocityAgent(self.ctx.sim, self.adversary, track, self.adversary_speed,
                                                stop_at_collision=True)  # fmt: skip
        if self._agent is not None and not self._crossed:
            self._agent.run_step(snapshot)
            if self._crossing.check(snapshot) or self._agent.done:
                self._crossed = True
                if self.adversary is not None:
                    self.destroy(self.adversary)
        return ScenarioStatus.SUCCESS if self._crossed and left else ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Release the lights."""
        if self.lights is not None:
            self.lights.release()


# ------------------------------------------------------------------------------------------------ placement


def red_light_runner_directions(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Directions whose straight crossing meets the ego: left/right for a straight ego, opposite for a left turn."""
    directions = ("left", "right") if conn.turn == "straight" else ("opposite",) if conn.turn == "left" else ()
    out = []
    for direction in directions:
        for entry in entries_from(lanes, conn.entry, direction):
            if connection(lanes, entry, "straight") is not None:
                out.append({"direction": {"value": direction}})
                break
    return out


register_layouts({
    "OppositeVehicleRunningRedLight": Layout(
        "signalized_junction", "a signalised junction crossed straight (or turning left) with a straight crossing "
        "entry", turns=("straight", "left"), signalized=True, junction_extra=red_light_runner_directions),
})  # fmt: skip
