"""PriorityAtJunction (LB2.0 training type, not in Bench2Drive): the ego's light held green until it has crossed.

Reference: scenario_runner ``leaderboard-2.0``, ``srunner/scenarios/green_traffic_light.py`` (Bench2Drive ships the
same file as ``scenario_runner/srunner/scenarios/green_traffic_light.py``; line numbers are that copy's):

- ``__init__`` (:31-46): no XML parameter; ``timeout`` 80 s (the BasicScenario timeout, unused on routes).
- ``_initialize_actors`` (:48-66): the junction is the first one met walking the ego's lane from the trigger point in
  1 m steps; a lane that ends first raises ``ValueError`` (the leaderboard then skips the scenario).
- ``_get_traffic_lights`` (:68-77): every light of that junction (none: ``ValueError``); the ego's light is the first
  traffic-light landmark (type ``1000001``) on the ego's lane before the junction. That one is set GREEN, every
  other light of the junction RED.
- ``_create_behavior`` (:79-86): a parallel that succeeds on its first finished child: ``WaitEndIntersection(ego,
  junction)`` and ``TrafficLightFreezer(states)`` with no duration (its default, 10 000 s: frozen until the parallel
  ends, when its ``terminate`` gives each light back the state it had). No background request at all (no
  HandleJunctionScenario, no source switch), no ScenarioTimeout.
- ``_create_test_criteria`` (:88-93): none, not even a ScenarioTimeoutTest.

Ours: the junction is the route's first after the trigger, however far (:class:`JunctionScenario`; the reference
walks the lane, ours the route, the same junction unless the route leaves the lane's way first; generated-route
placement keeps it within 100 m); the ego's light is the one whose stop line is on the route's lane before the
junction (:func:`~b2d_data.scenarios.catalog.junctions.lights_of_lane`). The freezing is a one-phase
:class:`~b2d_data.scenarios.catalog.junctions.LightSchedule` released when the ego has left the junction, which
restores the states the lights had at the trigger.

Placement (generated towns): a signalised junction the route drives through, any turn (:data:`LAYOUT_TURNS`). On a
route file, a junction without lights in the OpenDRIVE file gets none generated for this type (LB2.0 cannot find the
ego's landmark there and skips the scenario; our build raises and the evaluation skips it too).
"""

from __future__ import annotations

import logging

from b2d_data.scenarios.catalog.junctions import JunctionScenario, LightSchedule, light_states, lights_of_lane
from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.framework import ScenarioContext, ScenarioStatus, register
from b2d_data.scenarios.triggers import WaitEndIntersection
from b2d_data.sim.api import Snapshot, TrafficLightState

log = logging.getLogger(__name__)

#: The turns a generated PriorityAtJunction route may make at its junction (the reference takes any).
LAYOUT_TURNS: tuple[str, ...] = ("straight", "left", "right")


@register
class PriorityAtJunction(JunctionScenario):
    """The ego's light green and the junction's others red from the trigger until the ego has left the junction."""

    xml_type = "PriorityAtJunction"
    # No generated lights for it (b2d_data.scenarios.junction_signals): the reference reads the ego's light from the
    # OpenDRIVE landmarks (get_landmarks_of_type, :74), so at a junction whose file has none LB2.0 fails to build the
    # scenario and skips it, as our build does (require_lights). The placement asks for a signalised junction itself.
    signalized = False
    # green_traffic_light.py has no ScenarioTimeout behaviour and no criteria at all
    scenario_timeout = None
    timeout_test = False

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self._left = WaitEndIntersection(ctx.map, self.junction.id)
        self.lights: LightSchedule | None = None
        #: The forced state of each light of the junction (set at the trigger).
        self.states: dict[int, TrafficLightState] = {}

    def build(self) -> None:
        """Check that the junction is signalised (the reference raises without lights)."""
        self.require_lights(self.ctx.sim.snapshot())

    def start(self, snapshot: Snapshot) -> None:
        """Freeze the ego's light green and every other light of the junction red."""
        lights = self.require_lights(snapshot)
        self.states = light_states(lights, lights_of_lane(lights, self.ego_entry))
        self.lights = LightSchedule(self.ctx.sim, [(self.states, None)])
        self.lights.update(snapshot)
        log.debug("%s: lights %s frozen at junction %d", self.name, self.states, self.junction.id)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """SUCCESS once the ego has entered the junction and left it again (WaitEndIntersection)."""
        if self.lights is not None:
            self.lights.update(snapshot)
        ego = self.ctx.ego(snapshot)
        if ego is not None and self._left.check(ego):
            if self.lights is not None:
                self.lights.release(snapshot)
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Give the lights back (TrafficLightFreezer.terminate), also when the route ends first."""
        if self.lights is not None:
            self.lights.release()


register_layouts({
    "PriorityAtJunction": Layout("signalized_junction", "a signalised junction the route drives through",
                                 turns=LAYOUT_TURNS, signalized=True),
})  # fmt: skip
