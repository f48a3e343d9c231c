"""b2d-data's privileged expert as a Leaderboard 2.0 agent (``b2d-eval run --agent expert``).

Like PDM-Lite, the expert is privileged: instead of sensors it reads the world state, the dense route and the running
scenarios' hints through the data provider (``CarlaDataProvider.get_b2d_route()``, b2d-data's extension of the
scenario runner's provider). It asks for no sensor, so an evaluation with it is physics only. Its driving is the
collection's expert (``ExpertConfig.for_builtin()``), seeded by the route's simulator seed.
"""

from __future__ import annotations

import carla
from leaderboard.autoagents import autonomous_agent
from srunner.scenariomanager.carla_data_provider import CarlaDataProvider

from b2d_data.expert import Expert, ExpertConfig


def get_entry_point() -> str:
    """The agent class the Leaderboard instantiates."""
    return "ExpertAgent"


class ExpertAgent(autonomous_agent.AutonomousAgent):
    """The PDM-Lite-style expert driving through the Leaderboard agent API."""

    def setup(self, path_to_conf_file: str) -> None:
        """No configuration: the expert's parameters are the collection's."""
        self.track = autonomous_agent.Track.SENSORS
        self._expert: Expert | None = None

    def sensors(self) -> list[dict]:
        """Privileged: no sensor."""
        return []

    def run_step(self, input_data: dict, timestamp: float) -> carla.VehicleControl:
        """The expert's control for this tick."""
        route = CarlaDataProvider.get_b2d_route()
        if self._expert is None:
            seed = int(getattr(route.sim, "seed", 0))
            self._expert = Expert(route.map, route.route, ExpertConfig.for_builtin(), seed=seed)
        control = self._expert.run_step(route.snapshot, route.hints)
        return carla.VehicleControl(throttle=control.throttle, steer=control.steer, brake=control.brake,
                                    hand_brake=control.hand_brake, reverse=control.reverse)
