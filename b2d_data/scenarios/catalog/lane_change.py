"""SequentialLaneChange (§2.2 #43, clip name ``LaneChange``): a route with successive lane changes, no actors.

The route itself is the scenario: its keypoints move from lane to lane on a multi-lane road, so the leaderboard's
planner inserts CHANGELANELEFT/RIGHT commands the expert has to follow through background traffic. The scenario
ends when the ego has driven 200 m after the trigger point, or after 240 s (ScenarioTimeoutTest).
"""

from __future__ import annotations

import numpy as np

from b2d_data.maps import LaneChange, Waypoint
from b2d_data.scenarios.catalog.layout import KEYPOINT_SPACING, Layout, multi_lane_any, register_layouts
from b2d_data.scenarios.catalog.road_geometry import lane_walk, move_along, same_direction_driving_neighbour
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


# ------------------------------------------------------------------------------------------------ placement


def _lane_change_ok(wp: Waypoint, side: str) -> Waypoint | None:
    """The same-direction driving lane on ``side`` when the marking allows changing into it."""
    other = same_direction_driving_neighbour(wp, side)
    allowed = LaneChange.LEFT if side == "left" else LaneChange.RIGHT
    return other if other is not None and wp.lane_change & allowed else None


#: SequentialLaneChange: metres before the first lane change and between the first and the second.
SEQUENTIAL_RUNS = ((50.0, 60.0), (35.0, 45.0))
#: SequentialLaneChange: the first keypoint after a lane change is this far ahead in the new lane. The planner
#: lands 5 m ahead in the new lane (CARLA's ``trace_route``); a keypoint closer than that makes the next leg
#: start behind where it landed, and the route would double back.
SEQUENTIAL_CHANGE_REACH = 6.0


def _sequential_lanes(trigger: Waypoint, rng: np.random.Generator, length: float) -> list[Waypoint] | None:
    """Lane waypoints 2 m apart over ``length`` m that change lane twice (``SEQUENTIAL_RUNS``): first into a
    neighbour (side drawn at random among those allowed), then on the same way if a further lane exists, else back.
    Across each change the keypoints jump ``SEQUENTIAL_CHANGE_REACH`` m."""
    step = KEYPOINT_SPACING
    sides = ["left", "right"] if rng.uniform() < 0.5 else ["right", "left"]
    path = [trigger]
    travelled = 0.0
    first: str | None = None
    for change in range(3):
        run = float(rng.uniform(*SEQUENTIAL_RUNS[change])) if change < 2 else length - travelled
        walk = lane_walk(path[-1], run, step=step)
        if (len(walk) - 1) * step < run - 1e-6 or any(wp.is_junction for wp in walk):
            return None
        path += walk[1:]
        travelled += (len(walk) - 1) * step
        if change == 2:
            break
        order = sides if first is None else [first, "right" if first == "left" else "left"]
        target = None
        for side in order:
            target = _lane_change_ok(path[-1], side)
            if target is not None:
                first = first or side
                break
        ahead = move_along(target, SEQUENTIAL_CHANGE_REACH, step=step) if target is not None else None
        if ahead is None or ahead.is_junction:
            return None
        path.append(ahead)
        travelled += SEQUENTIAL_CHANGE_REACH
    return path


register_layouts({
    "SequentialLaneChange": Layout(
        "multi_lane", "two or more same-direction lanes with broken markings, 140 m junction-free", multi_lane_any,
        clear_before=0.0, clear_after=140.0, pre=(0.0, 0.0), length=140.0, path_builder=_sequential_lanes),
})  # fmt: skip
