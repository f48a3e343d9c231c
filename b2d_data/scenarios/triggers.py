"""Trigger and end conditions of scenarios (scenario_runner's ``atomic_trigger_conditions``), tick by tick.

Each condition is a small object fed one :class:`~b2d_data.sim.api.Snapshot` per tick; ``check`` returns True
once the condition holds (and keeps returning True afterwards where scenario_runner's atomics succeed once).
Distances are horizontal, as CARLA's ``Location.distance`` on road-level points practically is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.format.transform import Location, Transform
from b2d_data.sim.api import ActorState, Snapshot

if TYPE_CHECKING:
    from b2d_data.maps import Map
    from b2d_data.scenarios.route import DenseRoute

#: A scenario is built once the ego is this close to its trigger point (m).
BUILD_DISTANCE = 500.0
#: The ego triggers a scenario when its route point is within this distance of the trigger point (m).
TRIGGER_DISTANCE = 2.0
#: A trigger point further than this from every route point (or turned more than TRIGGER_MAX_YAW) is dropped.
TRIGGER_MAX_OFFSET = 2.0
TRIGGER_MAX_YAW = 10.0


def horizontal_distance(a: Location, b: Location) -> float:
    """Distance between two locations ignoring z."""
    return math.hypot(a.x - b.x, a.y - b.y)


def trigger_route_index(route: DenseRoute, trigger: Transform) -> int | None:
    """Index of the route point matching a trigger point (within 2 m and 10°, the leaderboard's check), or None."""
    loc = trigger.location
    d = np.hypot(route.locations[:, 0] - loc.x, route.locations[:, 1] - loc.y)
    order = np.argsort(d, kind="stable")
    for i in order:
        if d[i] > TRIGGER_MAX_OFFSET:
            return None
        yaw = route.waypoints[int(i)].transform.rotation.yaw
        if abs((trigger.rotation.yaw - yaw + 180.0) % 360.0 - 180.0) <= TRIGGER_MAX_YAW:
            return int(i)
    return None


def route_point_reached(
    route: DenseRoute, route_index: int, target_index: int, distance: float = TRIGGER_DISTANCE
) -> bool:
    """Whether the ego's route point is within ``distance`` metres (along the route) of a target point, or past it."""
    s = route.cumulative_length
    route_index = min(max(int(route_index), 0), len(s) - 1)
    return float(s[route_index]) >= float(s[target_index]) - distance


def is_in_front(actor: ActorState | Transform, reference: ActorState | Transform) -> bool:
    """Whether ``actor`` is ahead of ``reference`` along the reference's heading (``WaitUntilInFront``)."""
    a = actor.transform if isinstance(actor, ActorState) else actor
    r = reference.transform if isinstance(reference, ActorState) else reference
    fwd = r.get_forward_vector()
    dx, dy = a.location.x - r.location.x, a.location.y - r.location.y
    return fwd.x * dx + fwd.y * dy > 0.0


@dataclass
class TimeToArrivalTrigger:
    """Reactive trigger "TTA (t, d)": the ego's time to arrival at a location below ``time`` or within ``distance``.

    Time to arrival is the horizontal distance over the ego's current speed (infinite when standing).
    """

    location: Location
    time: float
    distance: float
    fired: bool = False

    def check(self, ego: ActorState) -> bool:
        """Evaluate on the ego's current state; stays True once fired."""
        if self.fired:
            return True
        d = horizontal_distance(ego.location, self.location)
        speed = ego.speed()
        tta = d / speed if speed > 1e-3 else math.inf
        self.fired = d < self.distance or tta < self.time
        return self.fired


@dataclass
class DistanceTrigger:
    """``InTriggerDistanceToLocation`` / ``ToVehicle``: an actor within ``distance`` of a location."""

    distance: float
    fired: bool = False

    def check(self, actor: ActorState, location: Location) -> bool:
        """True once the actor has been within the distance."""
        if not self.fired:
            self.fired = horizontal_distance(actor.location, location) < self.distance
        return self.fired


@dataclass
class DriveDistance:
    """``DriveDistance``: an actor has driven ``distance`` metres since the condition was created."""

    distance: float
    travelled: float = 0.0
    _last: Location | None = None

    def check(self, actor: ActorState | None) -> bool:
        """Accumulate the actor's motion since the last call; True once the distance is covered."""
        if actor is not None:
            loc = actor.location
            if self._last is not None:
                self.travelled += horizontal_distance(loc, self._last)
            self._last = loc
        return self.travelled >= self.distance


@dataclass
class Timer:
    """``Idle(duration)``: elapsed simulation time since it was started."""

    duration: float
    start: float | None = None

    def check(self, snapshot: Snapshot) -> bool:
        """Start on the first call; True once ``duration`` seconds of game time have passed."""
        if self.start is None:
            self.start = snapshot.timestamp
        return snapshot.timestamp - self.start >= self.duration - 1e-9


@dataclass
class WaitEndIntersection:
    """``WaitEndIntersection``: the ego has entered a junction and left it again.

    The ego's lane is looked up on the map each tick; ``junction_id`` restricts the test to one junction.
    """

    town: Map
    junction_id: int | None = None
    inside: bool = False
    done: bool = False

    def check(self, ego: ActorState) -> bool:
        """True once the ego was inside the junction and is now outside it."""
        if self.done:
            return True
        wp = self.town.get_waypoint(ego.location)
        in_junction = (
            wp is not None and wp.is_junction and (self.junction_id is None or wp.junction_id == self.junction_id)
        )
        if in_junction:
            self.inside = True
        elif self.inside:
            self.done = True
        return self.done


def wait_until_in_front(
    town: Map, actor: ActorState, other: ActorState, factor: float = 1.0, max_distance: float | None = 10.0
) -> bool:
    """``WaitUntilInFront(actor, other, factor, check_distance)``: ``actor`` is past the lane point ``factor`` × the
    two half-lengths ahead of ``other`` (and, unless ``max_distance`` is None, within that many metres of it)."""
    length = max(1e-6, factor) * (actor.bounding_box.extent.x + other.bounding_box.extent.x)
    wp = town.get_waypoint(other.location)
    ahead = wp.next(length) if wp is not None else []
    if not ahead:
        return False
    ref = ahead[0].transform
    fwd = ref.get_forward_vector()
    loc = actor.location
    dx, dy, dz = loc.x - ref.location.x, loc.y - ref.location.y, loc.z - ref.location.z
    if fwd.x * dx + fwd.y * dy + fwd.z * dz <= 0.0:
        return False
    return max_distance is None or math.sqrt(dx * dx + dy * dy + dz * dz) < max_distance
