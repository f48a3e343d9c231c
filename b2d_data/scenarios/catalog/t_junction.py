"""T_Junction (clip name TJunction, §2.2 #44): a route through a three-way junction, background traffic only.

No actors and no parameters: the scenario ends when the ego has driven 200 m after the trigger or after the
240 s ScenarioTimeout (its ScenarioTimeoutTest then records an infraction). Bench2Drive's routes are shorter
than 200 m, so the scenario normally lasts until the route ends. Bench2Drive's ``t_junction.py``
``_initialize_actors`` does nothing, so any trigger on the route sets up, junction ahead or not; only placement
puts it before a T-junction (within ``JUNCTION_SEARCH`` m, :attr:`TJunction.junction_layout`).
"""

from __future__ import annotations

from typing import ClassVar

from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.catalog.road_geometry import JunctionLane
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance
from b2d_data.sim.api import Snapshot


def junction_arms(lanes: list[JunctionLane]) -> int:
    """How many roads lead into a junction (3 for a T)."""
    return len({lane.entry.road_id for lane in lanes})


@register
class TJunction(Scenario):
    """A plain drive through a T-junction (at build: any drive, as the reference)."""

    xml_type = "T_Junction"
    junction_layout: ClassVar[bool] = True
    end_distance = 200.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        # the arm count is a placement rule only: CARLA's towns split some T-junctions into several junctions
        self._after = DriveDistance(self.end_distance)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """SUCCESS after 200 m."""
        return ScenarioStatus.SUCCESS if self._after.check(self.ctx.ego(snapshot)) else ScenarioStatus.RUNNING


# ------------------------------------------------------------------------------------------------ placement


def _three_arms(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Junctions where three roads meet (a T)."""
    return [{}] if len({lane.entry.road_id for lane in lanes}) == 3 else []


register_layouts({
    "T_Junction": Layout(
        "t_junction", "a junction of three roads that the route crosses", turns=("left", "right", "straight"),
        junction_extra=_three_arms, approach=(30.0, 38.0), departure=(22.0, 30.0), trigger_offset=(20.0, 26.0)),
})  # fmt: skip
