"""SequentialLaneChange (§2.2 #43, clip name ``LaneChange``): a route with successive lane changes, no actors.

The route itself is the scenario: its keypoints move from lane to lane on a multi-lane road, so the leaderboard's
planner inserts CHANGELANELEFT/RIGHT commands the expert has to follow through background traffic. The scenario
ends when the ego has driven 200 m after the trigger point, or after 240 s (ScenarioTimeoutTest).
"""

from __future__ import annotations

from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance
from b2d_data.sim.api import Snapshot

#: The scenario ends after the ego drove this far from the trigger point (m).
END_DISTANCE = 200.0


@register
class SequentialLaneChange(Scenario):
    """Successive lane changes along the route (§2.2 #43); nothing is spawned."""

    xml_type = "SequentialLaneChange"

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self._driven = DriveDistance(END_DISTANCE)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """SUCCESS once the ego has driven 200 m."""
        return ScenarioStatus.SUCCESS if self._driven.check(self.ctx.ego(snapshot)) else ScenarioStatus.RUNNING
