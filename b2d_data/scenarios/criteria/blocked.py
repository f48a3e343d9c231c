"""ActorBlockedTest: the ego standing (< 0.1 m/s) for more than 60 s ends the route (Bench2Drive; LB2.0 uses 180 s)."""

from __future__ import annotations

from b2d_data.format import leaderboard as lb
from b2d_data.scenarios.criteria.base import FAILURE, RUNNING, Criterion, Infraction, planar_speed
from b2d_data.sim.api import ActorState, Snapshot


class ActorBlockedTest(Criterion):
    """Fails once the ego's speed has stayed below ``min_speed`` for more than ``max_time`` seconds.

    The clock starts at the first update (so an ego that never moves is blocked after 60 s too) and restarts at
    every tick with the ego at or above ``min_speed``. Scenarios can pause the test with :meth:`switch`, which
    also restarts the clock.
    """

    name = "AgentBlockedTest"

    def __init__(self, min_speed: float = 0.1, max_time: float = 60.0, terminate_on_failure: bool = True) -> None:
        super().__init__(terminate_on_failure)
        self.min_speed = min_speed
        self.max_time = max_time
        self.active = True
        self._time_last_valid_state: float | None = None
        self._pending_switch: bool | None = None

    def switch(self, active: bool) -> None:
        """(De)activate the test from the next update on (the ``AC_SwitchActorBlockedTest`` blackboard message)."""
        self._pending_switch = active

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Track the time since the ego last moved."""
        now = snapshot.timestamp
        if self._pending_switch is not None:
            self.active = self._pending_switch
            self._time_last_valid_state = now
            self._pending_switch = None
        if self.test_status == FAILURE:
            return  # a terminating criterion: the route ends with its first event
        self.test_status = RUNNING
        if not self.active:
            return
        if planar_speed(ego) < self.min_speed and self._time_last_valid_state is not None:
            if now - self._time_last_valid_state > self.max_time:
                self.test_status = FAILURE
                location = ego.location
                self.events.append(Infraction(lb.VEHICLE_BLOCKED, lb.blocked_message(location), snapshot.frame,
                                              location=location))
        else:
            self._time_last_valid_state = now
