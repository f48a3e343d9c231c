"""RouteCriteria: every route-level criterion of a Bench2Drive route, updated together, plus the route timeout.

The order is the leaderboard's (``route_scenario._create_test_criteria``): completion, outside lanes, collisions,
red lights, stop signs, min speed (20 checkpoints), route deviation (30 m, terminating), agent blocked (60 s,
terminating). Scenario criteria events (scenario timeout, yield to emergency vehicle) come from the scenario
manager and are appended after them.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from b2d_data.format import leaderboard as lb
from b2d_data.scenarios.criteria.base import Criterion, Infraction
from b2d_data.scenarios.criteria.blocked import ActorBlockedTest
from b2d_data.scenarios.criteria.collision import CollisionTest
from b2d_data.scenarios.criteria.lanes import OutsideRouteLanesTest
from b2d_data.scenarios.criteria.route_progress import (
    InRouteTest,
    MinimumSpeedRouteTest,
    RouteCompletionTest,
    RouteTimeout,
)
from b2d_data.scenarios.criteria.traffic_rules import RunningRedLightTest, RunningStopTest
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import ActorState, Snapshot

if TYPE_CHECKING:
    from b2d_data.maps import Map

log = logging.getLogger(__name__)

#: Bench2Drive's values (upstream LB2.0: 4 checkpoints, 180 s).
MIN_SPEED_CHECKPOINTS = 20
BLOCKED_MAX_TIME = 60.0  # s
BLOCKED_MIN_SPEED = 0.1  # m/s
OFFROAD_MAX = 30.0  # m

#: Names of the switches scenarios may send (the scenario runner's blackboard keys).
SWITCH_WRONG_DIRECTION = "AC_SwitchWrongDirectionTest"
SWITCH_ACTOR_BLOCKED = "AC_SwitchActorBlockedTest"


@dataclass(frozen=True)
class CriteriaResult:
    """What the statistics need from a finished route: completion, every event in order, route timeout."""

    score_route: float
    events: tuple[Infraction, ...]
    route_timeout: bool = False

    @property
    def target_reached(self) -> bool:
        """The statistics manager's rule: route completion of 100."""
        return self.score_route >= 100


def as_infraction(event: Any, frame: int = 0) -> Infraction:
    """An :class:`Infraction` from a scenario criteria event.

    Accepted: an Infraction, an object with ``key``/``message`` attributes (optionally ``frame``/``percentage``),
    or a ``(key, message)`` pair.
    """
    if isinstance(event, Infraction):
        return event
    if isinstance(event, tuple) and len(event) == 2:
        return Infraction(str(event[0]), str(event[1]), frame)
    key, message = getattr(event, "key", None), getattr(event, "message", None)
    if key is None or message is None:
        raise TypeError(f"cannot read a scenario criteria event of type {type(event).__name__}: "
                        "expected an Infraction, an object with 'key' and 'message', or a (key, message) pair")
    if key not in lb.INFRACTION_KEYS:
        raise ValueError(f"scenario event has unknown infraction key {key!r}; known: {', '.join(lb.INFRACTION_KEYS)}")
    return Infraction(str(key), str(message), int(getattr(event, "frame", frame) or frame),
                      percentage=getattr(event, "percentage", None))


class RouteCriteria:
    """The route criteria of one run; call :meth:`update` once per tick and :meth:`terminate` once at the end."""

    def __init__(self, map: Map, route: DenseRoute, ego_id: int, checkpoints: int = MIN_SPEED_CHECKPOINTS,
                 blocked_max_time: float = BLOCKED_MAX_TIME) -> None:
        self.ego_id = ego_id
        self.route = route
        self.route_completion = RouteCompletionTest(route)
        self.outside_lanes = OutsideRouteLanesTest(map, route)
        self.collision = CollisionTest(ego_id)
        self.red_light = RunningRedLightTest(map)
        self.stop_sign = RunningStopTest(map)
        self.min_speed = MinimumSpeedRouteTest(route, checkpoints)
        self.in_route = InRouteTest(route, offroad_max=OFFROAD_MAX, terminate_on_failure=True)
        self.blocked = ActorBlockedTest(BLOCKED_MIN_SPEED, blocked_max_time, terminate_on_failure=True)
        self.timeout = RouteTimeout(route)
        self.scenario_events: list[Infraction] = []
        self.terminated = False
        self._last_ego: ActorState | None = None

    @property
    def criteria(self) -> list[Criterion]:
        """The route criteria in the leaderboard's order."""
        return [self.route_completion, self.outside_lanes, self.collision, self.red_light, self.stop_sign,
                self.min_speed, self.in_route, self.blocked]  # fmt: skip

    # ------------------------------------------------------------------------------------------------ per tick

    def update(self, snapshot: Snapshot, ego: ActorState | None = None, route_index: int | None = None) -> None:
        """Update every criterion and the route timeout with this tick's snapshot.

        ``route_index`` is accepted for symmetry with the scenario manager; each criterion keeps its own index
        with its own window, as in the leaderboard.
        """
        if self.terminated:
            return
        if ego is None:
            ego = snapshot.actors[self.ego_id]
        self._last_ego = ego
        for criterion in self.criteria:
            criterion.update(snapshot, ego)
        self.timeout.update(snapshot, ego)

    def switch(self, name: str, active: bool) -> None:
        """Apply a scenario's switch request (:data:`SWITCH_WRONG_DIRECTION` or :data:`SWITCH_ACTOR_BLOCKED`)."""
        if name == SWITCH_WRONG_DIRECTION:
            self.outside_lanes.switch_wrong_direction(active)
        elif name == SWITCH_ACTOR_BLOCKED:
            self.blocked.switch(active)
        else:
            known = f"{SWITCH_WRONG_DIRECTION}, {SWITCH_ACTOR_BLOCKED}"
            raise ValueError(f"unknown criteria switch {name!r}; known: {known}")

    def add_scenario_events(self, events: Iterable[Any], frame: int = 0) -> None:
        """Append the scenario criteria's events (ScenarioTimeoutTest, YieldToEmergencyVehicleTest, ...)."""
        self.scenario_events.extend(as_infraction(e, frame) for e in events)

    @property
    def stop_reason(self) -> str | None:
        """Why the route ends now: ``completed``, a failure message, or None to keep going."""
        if self.route_completion.stops_route:
            return "completed"
        if self.in_route.stops_route:
            return "Agent deviated from the route"
        if self.blocked.stops_route:
            return "Agent got blocked"
        if self.timeout.timed_out:
            return "Agent timed out"
        return None

    # ------------------------------------------------------------------------------------------------ the end

    def terminate(self, snapshot: Snapshot, ego: ActorState | None = None) -> None:
        """Close every criterion (min speed adds its last checkpoint); later updates are ignored."""
        if self.terminated:
            return
        if ego is None:
            ego = snapshot.actors.get(self.ego_id, self._last_ego)
        if ego is not None:
            for criterion in self.criteria:
                criterion.terminate(snapshot, ego)
        self.terminated = True

    @property
    def events(self) -> list[Infraction]:
        """Every event so far: route criteria in order, then the scenario events."""
        out: list[Infraction] = []
        for criterion in self.criteria:
            out.extend(criterion.events)
        out.extend(self.scenario_events)
        return out

    @property
    def score_route(self) -> float:
        """Route completion in percent (2 decimals)."""
        return round(self.route_completion.actual_value, 2)

    def result(self) -> CriteriaResult:
        """The criteria's outcome for the statistics."""
        return CriteriaResult(self.score_route, tuple(self.events), self.timeout.timed_out)
