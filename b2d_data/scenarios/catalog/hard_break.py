"""HardBreakRoute (§2.2 #16): the background vehicles in front of the ego brake to a stop at once."""

from __future__ import annotations

import logging

from b2d_data.scenarios.catalog.layout import Layout, any_lane, register_layouts
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, Timer
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


@register
class HardBreakRoute(Scenario):
    """At the trigger every background vehicle ahead stops; 10 s later they resume; ends 15 m later."""

    xml_type = "HardBreakRoute"
    scenario_timeout = None
    timeout_test = False
    stop_duration = 10.0
    end_distance = 15.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self._stopped = Timer(self.stop_duration)
        self._released = False
        self._after = DriveDistance(self.end_distance)

    def start(self, snapshot: Snapshot) -> None:
        """Order the front vehicles to stop."""
        self.ctx.sim.background.stop_front_vehicles()
        self._stopped.check(snapshot)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Release them after 10 s; SUCCESS once the ego drove 15 m more."""
        if not self._released:
            if not self._stopped.check(snapshot):
                return ScenarioStatus.RUNNING
            self.ctx.sim.background.start_front_vehicles()
            self._released = True
        return ScenarioStatus.SUCCESS if self._after.check(self.ctx.ego(snapshot)) else ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """Never leave the front vehicles stopped."""
        if not self._released:
            self.ctx.sim.background.start_front_vehicles()
            self._released = True


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "HardBreakRoute": Layout("road", "any driving lane, 60 m junction-free", any_lane, clear_after=60.0),
})  # fmt: skip
