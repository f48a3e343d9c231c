"""CollisionTest: the ego's collisions, typed layout / vehicle / pedestrian, with the leaderboard's de-duplication."""

from __future__ import annotations

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location
from b2d_data.scenarios.criteria.base import FAILURE, RUNNING, Criterion, Infraction, planar_speed
from b2d_data.sim.api import ActorState, CollisionEvent, Snapshot


class CollisionTest(Criterion):
    """Counts the ego's collisions from ``Snapshot.collisions``.

    A hit is ignored while the ego is slower than 0.1 m/s (not its fault), when it is with the same actor as the
    last counted one within 5 s, or when the ego is within 5 m of the last counted collision. Hits with actors
    whose type is neither layout, vehicle nor walker still arm these filters but give no event.
    """

    name = "CollisionTest"
    COLLISION_RADIUS = 5.0  # m: two collisions this close count as one
    MAX_ID_TIME = 5.0  # s: two collisions with the same actor this close in time count as one
    EPSILON = 0.1  # m/s: below this ego speed a collision is not the ego's fault

    def __init__(self, ego_id: int) -> None:
        super().__init__()
        self.ego_id = ego_id
        self.actual_value = 0
        self._collision_id: int | None = None
        self._collision_time: float | None = None
        self._collision_location: Location | None = None

    def update(self, snapshot: Snapshot, ego: ActorState | None) -> None:
        """Count this tick's hits, then let the filters expire (sensor callbacks run before the tree tick)."""
        if ego is None:
            return  # no ego in this snapshot (a scenario criterion updated while the ego is gone): nothing to count
        if self.test_status != FAILURE:
            self.test_status = RUNNING
        for event in snapshot.collisions:
            if event.actor_id == self.ego_id:
                self._count(event, snapshot, ego)
        location = ego.location
        last = self._collision_location
        if last is not None and (location - last).length() > self.COLLISION_RADIUS:
            self._collision_location = None
        if self._collision_id is not None and self._collision_time is not None:
            if snapshot.timestamp - self._collision_time > self.MAX_ID_TIME:
                self._collision_id = None

    def _count(self, event: CollisionEvent, snapshot: Snapshot, ego: ActorState) -> None:
        location = ego.location
        if self._collision_id is not None and self._collision_id == event.other_id:
            return
        last = self._collision_location
        if last is not None and (location - last).length() <= self.COLLISION_RADIUS:
            return
        if planar_speed(ego) < self.EPSILON:
            return
        self.test_status = FAILURE
        self.actual_value += 1
        self._collision_time = snapshot.timestamp
        self._collision_location = location
        if event.other_id != 0:  # id 0 is CARLA's static world: never remembered as "the same actor"
            self._collision_id = event.other_id
        key = lb.collision_key(event.other_type_id)
        if key is None:
            return
        message = lb.collision_message(event.other_type_id, event.other_id, location)
        self.events.append(Infraction(key, message, snapshot.frame, location=location, actor_id=event.other_id))
