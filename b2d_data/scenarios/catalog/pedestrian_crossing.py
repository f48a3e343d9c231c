"""PedestrianCrossing (§2.2 #19): a group of three pedestrians crosses the road in front of the ego at a junction.

At the trigger the walkers appear on the right sidewalk by the last lane point before the junction (offsets toward
the junction / right of the sidewalk (0.4, 1.5), (1, 2.5), (1.6, 0.5) m, as LB2.0's), facing the road. When the
ego's time to arrival at that lane point drops below 3.5 s (or it is within 12 m), each starts after its own random
delay (0–1.5 s) at its own speed (1.3–2.0 m/s), walks 2.3 × its distance to the lane point across the road and
disappears. The ego's entry of the junction is cleared of background traffic. The scenario ends when the ego has
driven 40 m after the last walker left.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

from b2d_data.format.transform import Transform, Vector3D
from b2d_data.maps import LaneType
from b2d_data.scenarios.catalog.actor_choices import random_walker
from b2d_data.scenarios.catalog.junctions import JunctionScenario
from b2d_data.scenarios.catalog.layout import Layout, register_layouts
from b2d_data.scenarios.catalog.road_geometry import JunctionLane, find_side_lane, offset_transform
from b2d_data.scenarios.catalog.turning_route import road_side_offset
from b2d_data.scenarios.controllers import WalkerController
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, TimeToArrivalTrigger, horizontal_distance
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


@dataclass
class _Walker:
    """One walker of the group: where it starts, its delay and speed, its controller once it walks."""

    transform: Transform
    delay: float
    speed: float
    distance: float
    actor_id: int | None = None
    walk: WalkerController | None = None
    start_time: float | None = None
    gone: bool = False


@register
class PedestrianCrossing(JunctionScenario):
    """Three pedestrians cross at the junction entry."""

    xml_type = "PedestrianCrossing"
    scenario_timeout = None
    timeout_test = False
    #: (forward, right) offsets (m) of the walkers from the sidewalk point.
    walker_offsets = ((0.4, 1.5), (1.0, 2.5), (1.6, 0.5))
    sync_time = 3.5
    min_trigger_distance = 12.0
    max_delay = 1.5
    speed_range = (1.3, 2.0)
    walk_factor = 2.3
    end_distance = 40.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.collision_waypoint = self.ego_entry
        sidewalk = find_side_lane(self.collision_waypoint, "right", LaneType.SIDEWALK)
        if sidewalk is None:
            raise ScenarioSetupError(
                f"{self.name}: layout 'sidewalk' missing: no sidewalk right of road {self.ego_entry.road_id} lane "
                f"{self.ego_entry.lane_id} before junction {self.junction.id}"
            )
        side = road_side_offset(self.collision_waypoint, "right")
        half = 0.5 * sidewalk.lane_width
        heading = math.radians(self.collision_waypoint.transform.rotation.yaw + 270.0)
        self.direction = Vector3D(math.cos(heading), math.sin(heading), 0.0)
        self.walkers: list[_Walker] = []
        centre = self.collision_waypoint.transform.location
        for forward, right in self.walker_offsets:
            # keep each walker on the sidewalk (the offsets are CARLA's, for its wider sidewalks)
            lateral = side + max(-half + 0.3, min(half - 0.3, right - 1.5))
            # LB2.0 (pedestrian_crossing.py) steps each walker ``forward`` m past the last lane point,
            # toward the junction
            t = offset_transform(self.collision_waypoint, lateral=lateral, forward=forward, z=1.0, yaw=270.0)
            delay = float(ctx.rng.uniform(0.0, self.max_delay))
            speed = float(ctx.rng.uniform(*self.speed_range))
            distance = self.walk_factor * horizontal_distance(t.location, centre)
            self.walkers.append(_Walker(t, delay, speed, distance))
        self._tta = TimeToArrivalTrigger(centre, self.sync_time, self.min_trigger_distance)
        self._crossing = False
        self._after = DriveDistance(self.end_distance)

    def start(self, snapshot: Snapshot) -> None:
        """Clear the ego's entry of the junction; the three walkers appear on the sidewalk.

        LB2.0 spawns them at build 200 m underground and lifts them into place at the trigger
        (pedestrian_crossing.py).
        """
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=False, clear_ego_entry=True, remove_entries=[], remove_exits=[], stop_entries=False,
            extend_road_exit=0.0,
        )  # fmt: skip
        for w in self.walkers:
            retries = [offset_transform(w.transform, forward=-f) for f in (0.5, 1.0, 1.5)]
            w.actor_id = self.spawn(random_walker(self.ctx.rng), w.transform, retries=retries)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """TTA trigger → each walker crosses after its delay → removed → 40 m more."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        if not self._crossing:
            if not self._tta.check(ego):
                return ScenarioStatus.RUNNING
            self._crossing = True
            for w in self.walkers:
                w.start_time = snapshot.timestamp + w.delay
        for w in self.walkers:
            if w.gone or w.actor_id is None or w.start_time is None:
                continue
            if w.walk is None:
                if snapshot.timestamp < w.start_time - 1e-9:
                    continue
                w.walk = WalkerController(self.ctx.sim, w.actor_id, self.direction, w.speed, w.distance)
            w.walk.run_step(snapshot)
            if w.walk.done:
                self.destroy(w.actor_id)
                w.gone = True
        if not all(w.gone or w.actor_id is None for w in self.walkers):
            return ScenarioStatus.RUNNING
        return ScenarioStatus.SUCCESS if self._after.check(ego) else ScenarioStatus.RUNNING


# ------------------------------------------------------------------------------------------------ placement


def _sidewalk_at_entry(conn: JunctionLane, lanes: list[JunctionLane]) -> list[dict[str, dict[str, str]]]:
    """Junction entries with a sidewalk on the right and no parking lane before it (where PedestrianCrossing's
    group waits; parked cars would stop the walkers)."""
    current = conn.entry
    while True:
        right = current.get_right_lane()
        if right is None or right.lane_id * current.lane_id <= 0 or right.lane_type & LaneType.PARKING:
            return []
        if right.lane_type & LaneType.SIDEWALK:
            return [{}]
        current = right


register_layouts({
    "PedestrianCrossing": Layout(
        "sidewalk_junction", "a junction entry with a sidewalk on the right", turns=("straight", "left", "right"),
        junction_extra=_sidewalk_at_entry, trigger_offset=(4.0, 10.0)),
})  # fmt: skip
