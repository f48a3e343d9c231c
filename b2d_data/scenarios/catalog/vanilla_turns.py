"""Bench2Drive's plain junction turns (§2.2 #39–#42): no actors, only forced lights or the map's stop sign.

VanillaSignalizedTurnEncounterRedLight: every light of the junction red for 5 s, then the ego's light green and
the others red until the end. VanillaSignalizedTurnEncounterGreenLight: the ego's light green (others red) for 5 s,
then every light red for 5 s; the scenario ends with that sequence (Bench2Drive's parallel succeeds on its first
child) unless the ego has left the junction before. Either way, at its end every light forced goes back to the state
it had at the trigger, as TrafficLightFreezer.terminate restores it (Bench2Drive's ``vanilla_turn.py``).
VanillaNonSignalizedTurnEncounterStopsign: nothing is forced; the route's stop sign is judged by the route criteria.
VanillaNonSignalizedTurn: a turn with background traffic only (generated at unsignalised junctions; route files may
put it at a signalised one, whose lights are left alone). All end 10 m after the ego left the junction; they carry
a ScenarioTimeoutTest that never fires (there is no ScenarioTimeout behaviour).
"""

from __future__ import annotations

import logging

from b2d_data.scenarios.catalog.junctions import JunctionScenario, LightSchedule, light_states, lights_of_lane
from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, WaitEndIntersection
from b2d_data.sim.api import Snapshot, TrafficLightInfo, TrafficLightState

log = logging.getLogger(__name__)


class VanillaJunctionTurn(JunctionScenario):
    """Ends 10 m after the ego has left the junction."""

    scenario_timeout = None
    timeout_test = True
    end_distance = 10.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self._left = WaitEndIntersection(ctx.map, self.junction.id)
        self._after = DriveDistance(self.end_distance)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """SUCCESS 10 m after the junction."""
        ego = self.ctx.ego(snapshot)
        if ego is not None and self._left.check(ego) and self._after.check(ego):
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING


class ScheduledLightsTurn(VanillaJunctionTurn):
    """A turn at a signalised junction whose lights follow a fixed schedule from the trigger on.

    Bench2Drive runs the schedule as a sequence of TrafficLightFreezers in parallel with the end condition; the
    scenario ends with whichever finishes first (a schedule whose phases are all timed ends it), and the freezer
    running then restores the state each light had when it began, which is the state at the trigger (an earlier
    freezer restored it before the next one froze it again). Our lights have no per-light timings to restore: the
    junction's cycle ran on meanwhile, and each light keeps its restored state until that cycle next changes stage.
    """

    signalized = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.lights: LightSchedule | None = None
        #: Each light's state at the trigger, restored at the end.
        self.states_at_trigger: dict[int, TrafficLightState] = {}
        self._schedule_start: float | None = None
        self._restored = False

    def phases(self, lights: list[TrafficLightInfo]) -> list[tuple[dict[int, TrafficLightState], float | None]]:
        """The schedule's (states, duration) phases for the junction's lights (each subclass gives its own)."""
        raise TypeError(f"{type(self).__name__} must define phases(): the light schedule it runs")

    def build(self) -> None:
        """Check that the junction is signalised."""
        self.require_lights(self.ctx.sim.snapshot())

    def start(self, snapshot: Snapshot) -> None:
        """Remember the lights' states, start the light schedule."""
        lights = self.require_lights(snapshot)
        self.states_at_trigger = {info.id: info.state for info in lights}
        self.lights = LightSchedule(self.ctx.sim, self.phases(lights))
        self._schedule_start = snapshot.timestamp
        self.lights.update(snapshot)

    def schedule_length(self) -> float | None:
        """Seconds from the trigger to the end of the schedule (None: its last phase lasts until the end)."""
        if self.lights is None or any(duration is None for _, duration in self.lights.phases):
            return None
        return sum(duration for _, duration in self.lights.phases if duration is not None)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Advance the lights; SUCCESS 10 m after the junction or when a timed schedule is over."""
        if self.lights is not None:
            self.lights.update(snapshot)
        length = self.schedule_length()
        start = self._schedule_start
        # the same test LightSchedule uses to leave its last phase, so both happen at this tick
        if length is not None and start is not None and snapshot.timestamp - start >= length - 1e-9:
            self._restore()
            return ScenarioStatus.SUCCESS
        return super().update(snapshot)

    def _restore(self) -> None:
        """Release the lights, each in its state at the trigger until its junction's cycle next changes stage."""
        if self.lights is None or self._restored:
            return
        self._restored = True
        self.lights.release()
        for light_id, state in sorted(self.states_at_trigger.items()):
            self.ctx.sim.set_traffic_light_state(light_id, state, freeze=False)

    def on_end(self) -> None:
        """Give the lights back as TrafficLightFreezer.terminate does."""
        self._restore()


@register
class VanillaSignalizedTurnEncounterRedLight(ScheduledLightsTurn):
    """All lights red for 5 s, then the ego's green: the ego must wait at the stop line, then go (§2.2 #42)."""

    xml_type = "VanillaSignalizedTurnEncounterRedLight"
    green_light_delay = 5.0

    def phases(self, lights: list[TrafficLightInfo]) -> list[tuple[dict[int, TrafficLightState], float | None]]:
        """All red for 5 s, then the ego's light green until the end."""
        ego_green = light_states(lights, lights_of_lane(lights, self.ego_entry))
        return [(light_states(lights, []), self.green_light_delay), (ego_green, None)]


@register
class VanillaSignalizedTurnEncounterGreenLight(ScheduledLightsTurn):
    """The ego's light green for 5 s, then all red for 5 s, then the lights as at the trigger (§2.2 #41)."""

    xml_type = "VanillaSignalizedTurnEncounterGreenLight"
    green_time = 5.0
    red_time = 5.0

    def phases(self, lights: list[TrafficLightInfo]) -> list[tuple[dict[int, TrafficLightState], float | None]]:
        """The ego's light green for 5 s, then all red for 5 s; the scenario ends with the second phase."""
        ego_green = light_states(lights, lights_of_lane(lights, self.ego_entry))
        return [(ego_green, self.green_time), (light_states(lights, []), self.red_time)]


@register
class VanillaNonSignalizedTurn(VanillaJunctionTurn):
    """A plain turn at an unsignalised junction with background traffic (§2.2 #39).

    Bench2Drive's ``VanillaNonSignalizedTurn`` (vanilla_turn.py) only finds the junction and waits for the ego to
    leave it: it never looks at the lights, so a route file may put it at a signalised junction, whose lights then
    run their normal cycle (Bench2Drive v0.0.4 validation route 27870, Town04 junction 621). Generated routes still
    get an unsignalised junction from the placement's layout below.
    """

    xml_type = "VanillaNonSignalizedTurn"


@register
class VanillaNonSignalizedTurnEncounterStopsign(VanillaJunctionTurn):
    """A turn at an unsignalised junction with a stop sign on the ego's approach (§2.2 #40)."""

    xml_type = "VanillaNonSignalizedTurnEncounterStopsign"

    def build(self) -> None:
        """Check that a stop sign governs the ego's approach (a lane of the route's last 30 m before the junction)."""
        route = self.ctx.route
        s = route.cumulative_length
        approach = {
            (wp.road_id, wp.lane_id)
            for k, wp in enumerate(route.waypoints[: self.entry_index])
            if s[self.entry_index] - s[k] <= 30.0
        }
        # CARLA's towns attach stop signs to the junction's connecting lanes
        stop = self.exit_index if self.exit_index is not None else len(route.waypoints)
        approach |= {(wp.road_id, wp.lane_id) for wp in route.waypoints[self.entry_index : stop]}
        for sign in self.ctx.map.stop_signs():
            if any((lane.road_id, lane.lane_id) in approach for lane in sign.lanes):
                return
        entry = self.ego_entry
        raise ScenarioSetupError(
            f"{self.name}: layout 'stop sign' missing: no stop sign governs road {entry.road_id} lane "
            f"{entry.lane_id} before junction {self.junction.id}"
        )


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "VanillaSignalizedTurnEncounterRedLight": Layout(
        "signalized_junction", "a signalised junction where the route turns", turns=("left", "right"),
        signalized=True, approach=(28.0, 36.0), departure=(18.0, 26.0), trigger_offset=(3.0, 5.0)),
    "VanillaNonSignalizedTurnEncounterStopsign": Layout(
        "stop_sign_junction", "an unsignalised junction with a stop sign on the approach where the route turns",
        turns=("left", "right"), signalized=False, stop_sign=True, approach=(28.0, 36.0), departure=(18.0, 26.0),
        trigger_offset=(3.0, 5.0)),
    "VanillaNonSignalizedTurn": Layout(
        "unsignalized_junction", "an unsignalised junction where the route turns", turns=("left", "right"),
        signalized=False, approach=(28.0, 36.0), departure=(18.0, 26.0), trigger_offset=(3.0, 5.0)),
    # bench2drive220's geometry (routes 25968 and 25975 on Town07, measured on the dense route: the route starts
    # 9.8–10.2 m before the junction, the trigger 7.0 m after the start, 2.8–3.2 m before the junction): the route
    # starts 10 m before the junction and the trigger is the keypoint 2 or 4 m before it, so the ego, starting from
    # rest, meets the 5 s of green at the stop line. With the trigger 14–19 m before the junction (approach 16–22 m)
    # an ego that stopped for crossing cars on its way could still have its tail over the line when all lights
    # turned red (3 of 20 routes).
    "VanillaSignalizedTurnEncounterGreenLight": Layout(
        "signalized_junction", "a signalised junction where the route turns", turns=("left", "right"),
        signalized=True, approach=(9.0, 10.0), departure=(24.0, 30.0), trigger_offset=(6.0, 8.0)),
})  # fmt: skip
