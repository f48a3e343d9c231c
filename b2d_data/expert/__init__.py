"""The PDM-Lite-style privileged expert (expert-and-scenarios.md §1).

``Expert(map, route, config, seed).run_step(snapshot, hints) -> VehicleControl``; after each step
``expert.state`` (:class:`ExpertState`) holds what the data agent records. It sees only the simulator protocol
(``b2d_data.sim.api``), the map and the format package.
"""

from b2d_data.expert.config import CARLA_LINEAR_REGRESSION_PARAMS, ExpertConfig
from b2d_data.expert.expert import Expert
from b2d_data.expert.state import CloseSignal, ExpertState, to_ego_frame

__all__ = [
    "CARLA_LINEAR_REGRESSION_PARAMS", "CloseSignal", "Expert", "ExpertConfig", "ExpertState", "to_ego_frame",
]  # fmt: skip
