"""Criteria that follow the ego along the dense route: completion, deviation, min-speed checkpoints, route timeout.

Each keeps its own route index with its own look-ahead window, as the scenario_runner criteria do (they are not
synchronised with each other, and the windows differ on purpose: 2 for completion and min speed, 5 for
deviation, 3 for the timeout).
"""

from __future__ import annotations

import logging
import math

from b2d_data.format import leaderboard as lb
from b2d_data.scenarios.criteria.base import FAILURE, INIT, RUNNING, SUCCESS, Criterion, Infraction, planar_speed
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import ActorKind, ActorState, Snapshot

log = logging.getLogger(__name__)


class RouteCompletionTest(Criterion):
    """Percentage of the route the ego has passed; success (100) once > 99 % and within 10 m of the end."""

    name = "RouteCompletionTest"
    WINDOW = 2
    DISTANCE_THRESHOLD = 10.0  # m
    PERCENTAGE_THRESHOLD = 99.0  # %

    def __init__(self, route: DenseRoute) -> None:
        super().__init__()
        self.route = route
        self.index = 0
        #: Route completion in percent, rounded to 2 decimals (100 once the target is reached).
        self.actual_value: float = 0.0
        self._target = route.location(len(route) - 1)
        #: Frame of the tick that detected the completion.
        self.completed_frame: int | None = None
        self._done = False

    @property
    def target_reached(self) -> bool:
        """Whether the route counts as completed."""
        return self.test_status == SUCCESS and self.actual_value >= 100

    @property
    def stops_route(self) -> bool:
        """True from the tick after the one that detected completion (the behaviour tree's one-tick lag)."""
        return self._done

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Advance the furthest passed route point."""
        if self.test_status == SUCCESS:
            self._done = True
            return
        location = ego.location
        # The value only changes when a point is passed; the index's own percentage is what it already holds.
        self.index = self.route.passed_index(location, self.index, self.WINDOW)
        self.actual_value = round(self.route.percentage(self.index), 2)
        self.test_status = RUNNING
        if self.actual_value > self.PERCENTAGE_THRESHOLD and location.distance(self._target) < self.DISTANCE_THRESHOLD:
            self.test_status = SUCCESS
            self.actual_value = 100.0
            self.completed_frame = snapshot.frame

    def terminate(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Round the final value (a route that never ran stays at 0)."""
        self.actual_value = round(self.actual_value, 2)
        if self.test_status == INIT:
            self.test_status = FAILURE


class InRouteTest(Criterion):
    """Route deviation: ≥ 30 m from the route, or > 30 % of the route driven 15–30 m away, ends the route."""

    name = "InRouteTest"
    WINDOW = 5
    MAX_ROUTE_PERCENTAGE = 30.0  # %

    def __init__(self, route: DenseRoute, offroad_max: float = 30.0, offroad_min: float | None = None,
                 terminate_on_failure: bool = True) -> None:
        super().__init__(terminate_on_failure)
        self.route = route
        self.offroad_max = offroad_max
        self.offroad_min = offroad_max / 2 if offroad_min is None else offroad_min
        self.index = 0
        self.out_route_distance = 0.0
        self._in_safe_route = True

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Check the distance to the nearest route point of the window."""
        if self.test_status not in (INIT, RUNNING):
            return
        location = ego.location
        closest = self.route.closest_index(location, self.index, self.WINDOW)
        shortest = location.distance_2d(self.route.location(closest))
        off_route = True
        if shortest < self.offroad_max:
            off_route = False
            self._in_safe_route = shortest < self.offroad_min
        if closest != self.index:
            new_dist = float(self.route.cumulative_length[closest] - self.route.cumulative_length[self.index])
            if not self._in_safe_route:
                self.out_route_distance += new_dist
                total = self.route.total_length
                if total > 0 and 100.0 * self.out_route_distance / total > self.MAX_ROUTE_PERCENTAGE:
                    off_route = True
            self.index = closest
        self.test_status = RUNNING
        if off_route:
            self.events.append(Infraction(lb.ROUTE_DEV, lb.route_deviation_message(location), snapshot.frame,
                                          location=location))
            self.test_status = FAILURE


class MinimumSpeedRouteTest(Criterion):
    """Bench2Drive's min-speed test: one event per 1/``checkpoints`` of the route with the ego/traffic speed ratio.

    Every checkpoint gives an event (not only slow ones) and the penalty is unused; a last event is added at the
    end when more than 95 % of the route was passed. Only vehicles with role ``background`` count as traffic.
    """

    name = "MinSpeedTest"
    WINDOW = 2
    RATIO = 1.0

    def __init__(self, route: DenseRoute, checkpoints: int = 20) -> None:
        super().__init__()
        self.route = route
        self.checkpoints = checkpoints
        self._checkpoint_dist = route.total_length / checkpoints
        self.index = 0
        self._current_dist = 0.0
        self._mean_speed = 0.0
        self._actor_speed = 0.0
        self._speed_points = 0
        self.checkpoint_values: list[float | int] = []
        self._frame = 0

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Track progress, close a checkpoint when passed, then add this tick's speeds."""
        self._frame = snapshot.frame
        self.test_status = RUNNING if self.test_status == INIT else self.test_status
        self.index = self.route.passed_index(ego.location, self.index, self.WINDOW)
        if float(self.route.cumulative_length[self.index]) - self._current_dist > self._checkpoint_dist:
            self._set_event()
            self._current_dist = float(self.route.cumulative_length[self.index])
            self._mean_speed = 0.0
            self._actor_speed = 0.0
            self._speed_points = 0
        background = [a for a in snapshot.actors.values()
                      if a.kind is ActorKind.VEHICLE and a.role_name == "background"]  # fmt: skip
        if background:
            self._mean_speed += sum(planar_speed(a) for a in background) / len(background)
            self._actor_speed += planar_speed(ego)
            self._speed_points += 1

    def _set_event(self) -> None:
        value: float | int
        if self._speed_points > 0 and self._mean_speed:
            mean_speed = self._mean_speed / self._speed_points
            actor_speed = self._actor_speed / self._speed_points
            value = round(actor_speed / (self.RATIO * mean_speed) * 100, 2)
        else:
            value = 100
        self.test_status = FAILURE
        self.events.append(Infraction(lb.MIN_SPEED_INFRACTIONS, lb.min_speed_message(value), self._frame,
                                      percentage=float(value)))
        self.checkpoint_values.append(value)

    def terminate(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Record the last checkpoint when the ego got past 95 % of the route."""
        self._frame = snapshot.frame
        total = self.route.total_length
        if total > 0 and float(self.route.cumulative_length[self.index]) / total > 0.95:
            self._set_event()
        super().terminate(snapshot, ego)


class RouteTimeout:
    """The leaderboard's route timeout: 300 s plus, per metre of progress, 1 / (10 % of the lane speed limit)."""

    MIN_TIMEOUT = 300.0  # s
    TIMEOUT_ROUTE_PERC = 10.0  # %
    WINDOW = 3

    def __init__(self, route: DenseRoute) -> None:
        self.route = route
        self.index = 0
        self.timeout_value = self.MIN_TIMEOUT
        self.timed_out = False
        self._start_time: float | None = None

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Extend the allowance by the new progress and check the elapsed game time."""
        if self._start_time is None:
            self._start_time = snapshot.timestamp
        new_index = self.route.passed_index(ego.location, self.index, self.WINDOW)
        if new_index > self.index:
            dist = float(self.route.cumulative_length[new_index] - self.route.cumulative_length[self.index])
            # The leaderboard reads the ego's current speed limit; the dense route holds it per point.
            timeout_speed = self.route.speed_limit_ms(new_index) * self.TIMEOUT_ROUTE_PERC / 100.0
            self.timeout_value += dist / timeout_speed if timeout_speed > 0 else math.inf
            self.index = new_index
        if snapshot.timestamp - self._start_time > self.timeout_value:
            if not self.timed_out:
                log.info("route timeout after %.2f s (allowed %.2f s)", snapshot.timestamp - self._start_time,
                         self.timeout_value)
            self.timed_out = True

