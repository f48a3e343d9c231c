"""What the junction scenarios share: locating the route's junction and scheduling forced traffic-light states."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import ClassVar

from b2d_data.maps import Junction, LaneType, Waypoint
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    junction_lanes,
    junction_lights,
    lane_walk,
    move_along,
    same_lane,
    yaw_diff,
)
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import Simulator, Snapshot, TrafficLightInfo, TrafficLightState

log = logging.getLogger(__name__)

#: How far after the trigger point (along the route) generated-route placement accepts a junction scenario's
#: junction (m). A placement rule only: at build the junction may be any distance ahead, as in LB2.0.
JUNCTION_SEARCH = 100.0


def junction_entry(route: DenseRoute, trigger_index: int, max_distance: float | None = None) -> int | None:
    """Index of the first route point inside a junction after the trigger (within ``max_distance`` m if given)."""
    # LB2.0 (e.g. signalized_junction_left_turn.py / green_traffic_light.py ``_initialize_actors``) walks 1 m steps
    # from the trigger until a junction waypoint, with no distance limit; its walk ends only where the lane does.
    s = route.cumulative_length
    for j in range(trigger_index, len(route.waypoints)):
        if max_distance is not None and s[j] - s[trigger_index] > max_distance:
            return None
        if route.waypoints[j].is_junction:
            return j
    return None


class JunctionScenario(Scenario):
    """A scenario at the first junction the route enters after its trigger point, however far (as LB2.0).

    Sets ``junction``, ``ego_entry`` (route waypoint just before the junction), ``ego_exit`` (just after it, None if
    the route ends inside), ``ego_turn`` ('left'/'right'/'straight'/'uturn') and ``lanes`` (every connection).
    """

    junction_layout: ClassVar[bool] = True
    required_turn: ClassVar[tuple[str, ...]] = ()
    #: The scenario needs traffic lights at its junction (``b2d_data.scenarios.junction_signals`` adds CARLA-style
    #: ones where the OpenDRIVE file has none).
    signalized: ClassVar[bool] = False

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        route = ctx.route
        entry = junction_entry(route, self.trigger_index)
        if entry is None:
            # LB2.0's lane walk raises where the lane ends before a junction; ours ends where the route does
            raise ScenarioSetupError(
                f"{self.name}: layout missing: the route enters no junction after the trigger point"
            )
        inside = route.waypoints[entry]
        self.junction: Junction = ctx.map.junctions[inside.junction_id]
        self.entry_index = entry
        self.ego_entry: Waypoint = (
            route.waypoints[entry - 1] if entry > 0 else (move_along(inside, 3.0, forward=False) or inside)
        )
        exit_index = next((k for k in range(entry, len(route.waypoints)) if not route.waypoints[k].is_junction), None)
        self.exit_index = exit_index
        self.ego_exit: Waypoint | None = route.waypoints[exit_index] if exit_index is not None else None
        self.lanes: list[JunctionLane] = junction_lanes(self.junction)
        if self.ego_exit is None:
            self.ego_turn = "straight"
        else:
            angle = yaw_diff(self.ego_entry.transform.rotation.yaw, self.ego_exit.transform.rotation.yaw)
            lane = JunctionLane(self.junction.id, inside, inside, self.ego_entry, self.ego_exit, angle)
            self.ego_turn = lane.turn
        if self.required_turn and self.ego_turn not in self.required_turn:
            raise ScenarioSetupError(
                f"{self.name}: layout missing: the route must turn {' or '.join(self.required_turn)} at junction "
                f"{self.junction.id}, it goes {self.ego_turn}"
            )

    def junction_lights(self, snapshot: Snapshot) -> list[TrafficLightInfo]:
        """The traffic lights of the scenario's junction."""
        return junction_lights(snapshot.traffic_lights, self.ctx.map, self.junction)

    def require_lights(self, snapshot: Snapshot) -> list[TrafficLightInfo]:
        """The junction's lights; a junction without any raises (the signalised layout is missing)."""
        lights = self.junction_lights(snapshot)
        if not lights:
            raise ScenarioSetupError(
                f"{self.name}: layout 'signalized junction' missing: junction {self.junction.id} has no traffic lights"
            )
        return lights


def lights_of_lane(lights: Sequence[TrafficLightInfo], wp: Waypoint) -> list[TrafficLightInfo]:
    """Every light with a stop waypoint on ``wp``'s lane; if none, the light whose stop line is nearest."""
    exact = [info for info in lights if any(same_lane(stop, wp) for stop in info.stop_waypoints)]
    if exact:
        return exact
    best, best_d = None, float("inf")
    for info in lights:
        for stop in info.stop_waypoints:
            d = stop.transform.location.distance_2d(wp.transform.location)
            if d < best_d:
                best, best_d = info, d
    return [best] if best is not None else []


def light_states(
    lights: Sequence[TrafficLightInfo],
    green: Sequence[TrafficLightInfo],
    default: TrafficLightState = TrafficLightState.RED,
) -> dict[int, TrafficLightState]:
    """A state per light: GREEN for those in ``green``, ``default`` for the others."""
    green_ids = {info.id for info in green}
    return {info.id: (TrafficLightState.GREEN if info.id in green_ids else default) for info in lights}


class LightSchedule:
    """scenario_runner's TrafficLightFreezer sequence: phases of forced states, each for a duration or until the end.

    A phase with duration ``None`` lasts until :meth:`release`; once the last timed phase is over the lights are
    released to their normal cycle with the state each had before the schedule first touched it, as
    ``TrafficLightFreezer.terminate`` restores them (its per-light timings excepted: our lights have none).
    """

    def __init__(self, sim: Simulator, phases: Sequence[tuple[Mapping[int, TrafficLightState], float | None]]) -> None:
        self.sim = sim
        self.phases = list(phases)
        self._index = -1
        self._phase_start = 0.0
        self._touched: set[int] = set()
        self._before: dict[int, TrafficLightState] = {}
        self._released = False
        self._last: Snapshot | None = None

    def _apply(self, index: int, snapshot: Snapshot) -> None:
        self._index = index
        self._phase_start = snapshot.timestamp
        for light_id, state in sorted(self.phases[index][0].items()):
            info = snapshot.traffic_lights.get(light_id)
            if light_id not in self._touched and info is not None:
                self._before[light_id] = info.state
            self.sim.set_traffic_light_state(light_id, state, freeze=True)
            self._touched.add(light_id)

    def update(self, snapshot: Snapshot) -> None:
        """Apply the first phase, then move on when a phase's duration is over."""
        self._last = snapshot
        if self._released or not self.phases:
            return
        if self._index < 0:
            self._apply(0, snapshot)
            return
        duration = self.phases[self._index][1]
        if duration is not None and snapshot.timestamp - self._phase_start >= duration - 1e-9:
            if self._index + 1 < len(self.phases):
                self._apply(self._index + 1, snapshot)
            else:
                self.release(snapshot)

    def release(self, snapshot: Snapshot | None = None) -> None:
        """Unfreeze every light this schedule touched, back in the state it had before (until its cycle next
        changes stage)."""
        if self._released:
            return
        self._released = True
        snapshot = snapshot if snapshot is not None else self._last
        current = snapshot.traffic_lights if snapshot is not None else {}
        for light_id in sorted(self._touched):
            info = current.get(light_id)
            now = info.state if info is not None else TrafficLightState.RED
            self.sim.set_traffic_light_state(light_id, self._before.get(light_id, now), freeze=False)


def rightmost_driving(wp: Waypoint) -> Waypoint:
    """The rightmost same-direction driving lane next to ``wp``."""
    current = wp
    while True:
        other = current.get_right_lane()
        if other is None or not other.lane_type & LaneType.DRIVING or other.lane_id * current.lane_id <= 0:
            return current
        current = other


def junction_flow_path(conn: JunctionLane, back: float, ahead: float, back_step: float = 5.0) -> list[Waypoint]:
    """Lane waypoints 1 m apart of a flow through ``conn``: from ``back`` m before its entry (stopping at a previous
    junction, in ``back_step`` steps like ActorFlow's source search) to ``ahead`` m after its exit.

    The sink is LB2.0's ``sink_exit_wp.next(sink_dist)[0]`` (signalized_junction_right_turn.py and its siblings):
    the walk goes on through a junction on the exit road (straightest branch), as CARLA's ``next`` does; Bench2Drive
    v0.0.4 validation route 24948 (Town07 junction 68, junction 123 36 m after it) was refused for that.
    """
    source = walk_back_to_source(conn.entry, back, back_step)
    approach: list[Waypoint] = [conn.entry]
    current = conn.entry
    while current.transform.location.distance_2d(source.transform.location) > 0.75 and len(approach) < back + 10:
        options = current.previous(1.0)
        if not options or options[0].is_junction:
            break
        current = min(options, key=lambda o: o.transform.location.distance_2d(source.transform.location))
        approach.append(current)
    inside: list[Waypoint] = [conn.start]
    while len(inside) < 300:
        options = [o for o in inside[-1].next(1.0) if o.is_junction and o.road_id == conn.start.road_id]
        if not options:
            break
        inside.append(options[0])
    after = lane_walk(conn.exit, ahead)
    return list(reversed(approach)) + inside + after


def walk_back_to_source(entry: Waypoint, distance: float, step: float = 5.0) -> Waypoint:
    """The source point ``distance`` m before a junction entry, stopping before a previous junction (ActorFlow's
    source search, 5 m steps)."""
    source = entry
    walked = 0.0
    while walked < distance:
        options = source.previous(step)
        if not options or options[0].is_junction:
            break
        source = options[0]
        walked += step
    return source
