"""Highway merges (§2.2 #35): HighwayCutIn.

A car waits on the on-ramp at the XML's ``other_actor_location``. At the trigger the merge junction is cleared, the
ramp entry removed from background traffic and the road after the junction kept free for 170 m; the car then drives
down the ramp at the speed that brings it 10 m past the merge junction's exit (on the acceleration lane) exactly
when the ego reaches its own junction exit (scenario_runner's SyncArrivalWithAgent: straight-line distances, the
car's speed is its distance over the ego's time to arrival; CARLA's ConstantVelocityAgent, which takes a leader's
speed and coasts after a collision). Once within 5 m of its target while the ego has not yet passed its exit, it
cuts into the ego's lane at 80 % of the ego's speed: 0.3 s on its lane, a 2 s lane change, 3 s in the ego's lane,
braking for vehicles in its path as CARLA's BasicAgent does; then it is removed. Should the ego pass its exit
first, LB2.0's car never cuts in and follows its lane; ours does so to the end of its lane walk and is removed.
"""

from __future__ import annotations

import logging
import math
from enum import Enum
from typing import ClassVar

import numpy as np

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.flows import FlowScenario
from b2d_data.scenarios.catalog.interurban import flow_lane_path, location_parameter
from b2d_data.scenarios.catalog.junctions import JunctionScenario
from b2d_data.scenarios.catalog.road_geometry import (
    is_driving,
    lane_walk,
    move_along,
    same_direction_driving_neighbour,
    same_direction_lanes,
)
from b2d_data.scenarios.controllers import ConstantVelocityAgent, PathTrack, park
from b2d_data.scenarios.framework import (
    SCENARIO_ROLE,
    ScenarioContext,
    ScenarioSetupError,
    ScenarioStatus,
    register,
)
from b2d_data.scenarios.triggers import is_in_front
from b2d_data.sim import blueprints
from b2d_data.sim.api import ScenarioHint, Snapshot

log = logging.getLogger(__name__)

#: The cut-in car reaches this far past the merge junction's exit when the ego reaches its own exit (m).
CUT_IN_DISTANCE = 10.0
#: The road after the junction kept free of background traffic (m).
EXTRA_SPACE = 170.0
#: The cut-in: time on its own lane, time of the lane change, time in the ego's lane (s); speed as ego's share.
SAME_LANE_TIME, CHANGE_TIME, OTHER_LANE_TIME = 0.3, 2.0, 3.0
SPEED_SHARE = 0.8
#: Fastest the cut-in car drives while it times its arrival (m/s; not in LB2.0, whose forced speed is unbounded).
MAX_SYNC_SPEED = 35.0
#: LB2.0 ``SyncArrivalWithAgent(..., end_dist=5)``: the sync ends within this straight-line distance of the target (m).
SYNC_END_DISTANCE = 5.0
#: CARLA's BasicAgent (the agent of LB2.0's ``CutIn`` and the base of its ConstantVelocityAgent) looks for vehicles
#: within ``_base_vehicle_threshold`` (5 m) + ``_speed_ratio`` (1) × its speed [m/s] and brakes at ``_max_brake`` 0.5.
AGENT_BASE_THRESHOLD = 5.0
AGENT_MAX_BRAKE = 0.5
#: How far the car's lane walk reaches from ``other_actor_location`` (m).
LANE_WALK = 400.0


class _Phase(str, Enum):
    WAITING = "waiting"
    SYNC = "sync"
    CUT_IN = "cut_in"
    DONE = "done"


def cut_in_path(start: Waypoint, speed: float) -> np.ndarray:
    """Points 1 m apart from ``start`` (on the lane right of the target) into its left neighbour: ``speed`` ×
    (0.3 s straight, 2 s smooth lateral shift, 3 s on the new lane)."""
    target = same_direction_driving_neighbour(start, "left")
    if target is None:
        raise ScenarioSetupError(f"no lane left of road {start.road_id} lane {start.lane_id} to cut into")
    keep, change, after = speed * SAME_LANE_TIME, speed * CHANGE_TIME, speed * OTHER_LANE_TIME
    rows = []
    for i, wp in enumerate(lane_walk(target, keep + change + after + 2.0)):
        s = float(i)
        t = min(max((s - keep) / max(change, 1e-6), 0.0), 1.0)
        w = t * t * (3.0 - 2.0 * t)  # smooth start and end of the lateral move
        right = wp.get_right_lane()
        loc = wp.transform.location
        if w < 1.0 and right is not None and is_driving(right):
            r = right.transform.location
            x, y = r.x + w * (loc.x - r.x), r.y + w * (loc.y - r.y)
        elif w < 1.0:
            yaw = math.radians(wp.transform.rotation.yaw)
            off = (1.0 - w) * wp.lane_width
            x, y = loc.x - math.sin(yaw) * off, loc.y + math.cos(yaw) * off
        else:
            x, y = loc.x, loc.y
        rows.append((x, y, loc.z))
    return np.array(rows)


@register
class HighwayCutIn(JunctionScenario):
    """A car from the on-ramp cuts into the ego's lane just after the merge (§2.2 #35)."""

    xml_type = "HighwayCutIn"
    required_turn = ("straight",)
    # LB2.0's HighwayCutIn has no ScenarioTimeout behaviour and, in route mode, no criteria (highway_cut_in.py
    # _create_behavior / _create_test_criteria): no 240 s end, no ScenarioTimeoutTest, no pause of the blocked test.
    scenario_timeout = None
    timeout_test = False

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        start = ctx.map.get_waypoint(location_parameter(ctx, "other_actor_location"))
        if start is None or start.is_junction:
            raise ScenarioSetupError(f"{self.name}: other_actor_location is not on a lane before the junction")
        walk = lane_walk(start, LANE_WALK)
        inside = [k for k, wp in enumerate(walk) if wp.is_junction and wp.junction_id == self.junction.id]
        if not inside or inside[-1] + 1 >= len(walk):
            raise ScenarioSetupError(
                f"{self.name}: layout missing: the lane at other_actor_location does not merge through junction "
                f"{self.junction.id}"
            )
        after = inside[-1] + 1 + round(CUT_IN_DISTANCE)
        if after >= len(walk) or walk[after].is_junction:
            raise ScenarioSetupError(f"{self.name}: the acceleration lane ends within {CUT_IN_DISTANCE:.0f} m")
        if self.ego_exit is None or self.exit_index is None:
            raise ScenarioSetupError(f"{self.name}: the route ends inside junction {self.junction.id}")
        self.start_wp = start
        self.path = walk[: after + 1]
        #: LB2.0's ``target_wp``: 10 m past the merge junction's exit; the ego's reference is its own exit.
        self.target_wp = walk[after]
        # the car's track runs on past the target: LB2.0's car follows its lane while the ego passes its exit first
        self.track = PathTrack.from_waypoints(walk)
        self.actor_id: int | None = None
        self.agent: ConstantVelocityAgent | None = None
        self.phase = _Phase.WAITING
        self.cut_in_speed = 0.0
        self._seen = False

    def start(self, snapshot: Snapshot) -> None:
        """Clear the merge, remove the ramp from background traffic, keep the road ahead free; start the approach.

        The car appears on the ramp now: LB2.0 spawns it at build 200 m underground and lifts it at the trigger
        (highway_cut_in.py).
        """
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=True, clear_ego_entry=False, remove_entries=[self.path[0]], remove_exits=[],
            stop_entries=False, extend_road_exit=EXTRA_SPACE,
        )  # fmt: skip
        spec = blueprints.random_background_car(self.ctx.rng, role_name=SCENARIO_ROLE)
        t = self.start_wp.transform
        transform = Transform(Location(t.location.x, t.location.y, t.location.z + 0.2), Rotation(yaw=t.rotation.yaw))
        self.actor_id = self.spawn(spec.type_id, transform, spec.attributes)
        park(self.ctx.sim, self.actor_id)
        # CARLA's ConstantVelocityAgent (SyncArrivalWithAgent's): a leader in its path within 5 m + its speed sets the
        # forced speed to the leader's; its collision sensor drops the forced velocity for good
        self.agent = ConstantVelocityAgent(
            self.ctx.sim, self.actor_id, self.track, 0.0, detect_vehicles=True, base_threshold=AGENT_BASE_THRESHOLD,
            match_leader=True, stop_at_collision=True, resume_accel=8.0,
        )  # fmt: skip
        self.phase = _Phase.SYNC

    def sync_step(self, snapshot: Snapshot) -> tuple[bool, float]:
        """SyncArrivalWithAgent's update: (cut in now, the car's speed otherwise).

        The car's and the ego's straight-line distances to their targets; the sync ends once the car is within
        :data:`SYNC_END_DISTANCE` of its target while the ego's target still lies ahead of the ego (LB2.0:
        ``(reference_target - ego) · reference_forward > 0``). The speed is the car's distance over the ego's time to
        arrival (0 while the ego stands).
        """
        ego = self.ctx.ego(snapshot)
        actor = snapshot.actors.get(self.actor_id) if self.actor_id is not None else None
        if ego is None or actor is None or self.ego_exit is None:
            return False, 0.0
        target = self.target_wp.transform.location
        distance = actor.location.distance(target)
        reference = self.ego_exit.transform
        if distance < SYNC_END_DISTANCE and not is_in_front(ego, reference):
            return True, 0.0
        ego_distance, ego_speed = ego.location.distance(reference.location), ego.speed()
        if ego_speed <= 0.0 or ego_distance <= 0.0:
            return False, 0.0
        return False, min(MAX_SYNC_SPEED, distance * ego_speed / ego_distance)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Time the arrival, then cut in; SUCCESS once the cut-in is over."""
        if self.agent is None or self.actor_id is None:
            return ScenarioStatus.SUCCESS  # nothing was spawned
        if self.actor_id not in snapshot.actors:
            # spawned this tick (not in the snapshot yet), or removed by somebody else since
            return ScenarioStatus.SUCCESS if self._seen else ScenarioStatus.RUNNING
        self._seen = True
        if self.phase is _Phase.SYNC:
            cut_in, speed = self.sync_step(snapshot)
            if cut_in:
                ego = self.ctx.ego(snapshot)
                self._begin_cut_in(snapshot, ego.speed() if ego is not None else 0.0)
            else:
                self.agent.speed = speed
        if self.agent.done:
            # the cut-in is over, or (sync) the ego passed its exit first and the car reached its lane walk's end
            self.destroy(self.actor_id)
            self.phase = _Phase.DONE
            return ScenarioStatus.SUCCESS
        self.agent.run_step(snapshot)
        return ScenarioStatus.RUNNING

    def _begin_cut_in(self, snapshot: Snapshot, ego_speed: float) -> None:
        actor = snapshot.actors[self.actor_id]
        here = self.ctx.map.get_waypoint(actor.location)
        if here is None or here.is_junction or same_direction_driving_neighbour(here, "left") is None:
            here = self.path[-1]
        self.cut_in_speed = max(SPEED_SHARE * ego_speed, 1.0)
        track = PathTrack(cut_in_path(here, self.cut_in_speed))
        # LB2.0's CutIn drives a BasicAgent: it brakes for a vehicle in its path within 5 m + its speed [m/s]
        self.agent = ConstantVelocityAgent(
            self.ctx.sim, self.actor_id, track, self.cut_in_speed, detect_vehicles=True,
            base_threshold=AGENT_BASE_THRESHOLD, speed_ratio=1.0 / 3.6, max_brake=AGENT_MAX_BRAKE,
        )  # fmt: skip
        self.phase = _Phase.CUT_IN
        log.debug("%s: cut-in at %.1f m/s", self.name, self.cut_in_speed)


class _SlowTrafficMerge(FlowScenario):
    """Common part of the two MergerIntoSlowTraffic types: a slow, pre-populated flow from ``start_actor_flow`` to
    ``end_actor_flow`` on the lane the ego merges into; SUCCESS once the ego is within 2 m of its sink.

    The expert learns the sink from the hint and merges with gap acceptance (:mod:`b2d_data.expert.merging`).
    """

    #: V2 (LB2.0's MergerIntoSlowTrafficV2) leaves the junction as it is but removes the lanes 10 m after the
    #: route's junction exit from background traffic.
    v2: ClassVar[bool] = False
    route_sources_off = True

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.path: list[Waypoint] = flow_lane_path(ctx)
        #: LB2.0 ends the scenario when the ego comes within 2 m of the sink point of any same-direction lane
        #: (one ``InTriggerDistanceToLocation`` per ``get_same_dir_lanes(sink_wp)``); a route that stops short of the
        #: sink, or passes it more than 2 m from every lane's point, leaves the flow running until the route ends.
        self.sinks: list[Waypoint] = same_direction_lanes(self.path[-1])
        inside = [k for k, wp in enumerate(self.path) if wp.is_junction]
        #: metres of flow past the junction
        self.after_junction = float(len(self.path) - 1 - inside[-1]) if inside else 0.0
        self.exit_lanes: list[Waypoint] = self._exit_lanes() if self.v2 else []

    def _exit_lanes(self) -> list[Waypoint]:
        """V2: the same-direction lanes 10 m after the route leaves its first junction past the trigger (LB2.0's
        ``generate_target_waypoint_in_route`` then ``next(10)``); none (logged) when the route meets no junction."""
        waypoints = self.ctx.route.waypoints
        entry = next((k for k in range(self.trigger_index, len(waypoints)) if waypoints[k].is_junction), None)
        leave = None
        if entry is not None:
            leave = next((k for k in range(entry, len(waypoints)) if not waypoints[k].is_junction), None)
        after = move_along(waypoints[leave], 10.0) if leave is not None else None
        if after is None:
            log.warning("%s: no route lane 10 m after the merge junction; no exit lanes removed", self.name)
            return []
        return same_direction_lanes(after)

    def prepare_background(self, snapshot: Snapshot) -> None:
        """LB2.0's HandleJunctionScenario at the trigger (the route sources stop too).

        V1 clears the junction and the ego's entry, removes the flow's source lane and keeps the road free for the
        flow's length past the junction + 20 m. V2 clears the ego's entry only, removes the source lane and the
        lanes after the exit. LB2.0's V2 keeps the road free (the same length) only once the ego has left the
        junction, with a second HandleJunctionScenario; ours asks at the trigger: the space only holds back road
        spawns, and those are off (SwitchRouteSources) until the scenario ends, so it acts from the same moment.
        """
        self.ctx.sim.background.handle_junction_scenario(
            clear_junction=not self.v2, clear_ego_entry=True, remove_entries=[self.path[0]],
            remove_exits=self.exit_lanes, stop_entries=False, extend_road_exit=self.after_junction + 20.0,
        )  # fmt: skip

    def start_flows(self, snapshot: Snapshot) -> None:
        """The pre-populated flow."""
        self.add_flow(self.path, initial_actors=True)

    def finished(self, snapshot: Snapshot) -> bool:
        """The ego is within 2 m of the sink point of any same-direction lane."""
        return self.ego_near_sink(snapshot, self.sinks)

    def hint(self) -> ScenarioHint | None:
        """While the flow runs: the sink the ego merges towards."""
        if self.flow is None or not self.flow.active:
            return None
        sink = self.path[-1].transform.location
        return ScenarioHint(self.xml_type, None, None, extra={"sink_x": sink.x, "sink_y": sink.y, "sink_z": sink.z},
                            paths=self.flow.paths_ahead())


@register
class MergerIntoSlowTraffic(_SlowTrafficMerge):
    """Merge from an on-ramp into a slow flow (§2.2 #31)."""

    xml_type = "MergerIntoSlowTraffic"


@register
class MergerIntoSlowTrafficV2(_SlowTrafficMerge):
    """Merge from a dedicated entry into a slow single-lane flow, Town06-style (§2.2 #32)."""

    xml_type = "MergerIntoSlowTrafficV2"
    v2 = True
