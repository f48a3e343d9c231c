"""OppositeVehicleTakingPriority (§2.2 #38): a car crosses an unsignalised junction in front of the ego.

The red-light runner's behaviour (adversary 30 m before the junction on the ``direction`` entry, TTA trigger
(2.2 s, 12 m) at the conflict point, straight crossing at 60 km/h ignoring everything, removed 10 m past its exit)
at a junction without lights, with the junction entries stopped; the adversary is an emergency vehicle with its
sirens on, as in LB2.0 (both types share one ``_initialize_actors`` there).
"""

from __future__ import annotations

from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.catalog.red_light_runner import OppositeVehicleRunningRedLight, red_light_runner_directions
from b2d_data.scenarios.framework import ScenarioSetupError, register
from b2d_data.sim.api import Snapshot


@register
class OppositeVehicleTakingPriority(OppositeVehicleRunningRedLight):
    """A car takes priority over the ego at an unsignalised junction."""

    xml_type = "OppositeVehicleTakingPriority"
    signalized = False

    def build(self) -> None:
        """Check that the junction has no traffic light."""
        if self.junction_lights(self.ctx.sim.snapshot()):
            raise ScenarioSetupError(
                f"{self.name}: layout 'unsignalized junction' missing: junction {self.junction.id} has traffic lights"
            )

    def start(self, snapshot: Snapshot) -> None:
        """Prepare the junction (entries stopped) and place the adversary."""
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=True, remove_entries=[self.spawn_waypoint],
            remove_exits=[self.sink_waypoint], stop_entries=True, extend_road_exit=0.0,
        )  # fmt: skip
        self.spawn_adversary()

    def on_end(self) -> None:
        """No lights to release."""


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "OppositeVehicleTakingPriority": Layout(
        "unsignalized_junction", "an unsignalised junction crossed straight (or turning left) with a straight "
        "crossing entry", turns=("straight", "left"), signalized=False, junction_extra=red_light_runner_directions),
})  # fmt: skip
