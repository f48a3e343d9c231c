"""What every route criterion shares: the infraction event, the criterion base class and small geometry helpers.

Criteria follow scenario_runner's ``atomic_criteria.py`` (leaderboard-2.0 branch, as bundled by Bench2Drive): each
one is updated once per tick with the new :class:`~b2d_data.sim.api.Snapshot` and the ego's state, appends
:class:`Infraction` events, and may ask the route to end (``terminate_on_failure`` / route completion).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from b2d_data.format.transform import Location
from b2d_data.sim.api import ActorState, Snapshot

#: Status values of a criterion (scenario_runner's ``test_status``).
INIT = "INIT"
RUNNING = "RUNNING"
SUCCESS = "SUCCESS"
FAILURE = "FAILURE"


@dataclass(frozen=True)
class Infraction:
    """One traffic event as the statistics manager sees it.

    ``key`` is the record's infraction list (``format.leaderboard`` constants, e.g. ``collisions_vehicle``);
    ``percentage`` is the unrounded value of percentage-valued events (outside route lanes, min speed), which the
    penalty uses; ``frame`` is the snapshot frame at which the event was (last) set.
    """

    key: str
    message: str
    frame: int
    percentage: float | None = None
    location: Location | None = None
    actor_id: int | None = None


class Criterion:
    """Base class: per-tick ``update``, end-of-route ``terminate``, accumulated ``events`` and a status."""

    #: Name used in logs.
    name = "Criterion"

    def __init__(self, terminate_on_failure: bool = False) -> None:
        self.terminate_on_failure = terminate_on_failure
        self.test_status = INIT
        self.events: list[Infraction] = []

    @property
    def failed(self) -> bool:
        """Whether the criterion has recorded a failure."""
        return self.test_status == FAILURE

    @property
    def stops_route(self) -> bool:
        """Whether this criterion ends the route now (a failure of a terminating criterion)."""
        return self.terminate_on_failure and self.failed

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Advance the criterion by one tick."""

    def terminate(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Close the criterion when the route ends (may add a last event)."""
        if self.test_status in (INIT, RUNNING):
            self.test_status = SUCCESS


def planar_speed(actor: ActorState) -> float:
    """Horizontal speed (m/s), as ``CarlaDataProvider.get_velocity`` computes it."""
    return math.hypot(actor.velocity.x, actor.velocity.y)


def rotate_2d(x: float, y: float, angle_deg: float) -> tuple[float, float]:
    """Rotate a horizontal vector by ``angle_deg`` (CARLA yaw convention)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    return c * x - s * y, s * x + c * y


def _orientation(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def _on_segment(ax: float, ay: float, bx: float, by: float, px: float, py: float) -> bool:
    return min(ax, bx) - 1e-12 <= px <= max(ax, bx) + 1e-12 and min(ay, by) - 1e-12 <= py <= max(ay, by) + 1e-12


def segments_intersect(
    p1: tuple[float, float], p2: tuple[float, float], q1: tuple[float, float], q2: tuple[float, float]
) -> bool:
    """Whether two closed 2-D segments share a point (what a non-empty shapely intersection means)."""
    d1 = _orientation(*q1, *q2, *p1)
    d2 = _orientation(*q1, *q2, *p2)
    d3 = _orientation(*p1, *p2, *q1)
    d4 = _orientation(*p1, *p2, *q2)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True
    # Touching or collinear cases: an end point lying on the other segment.
    return (
        (d1 == 0 and _on_segment(*q1, *q2, *p1))
        or (d2 == 0 and _on_segment(*q1, *q2, *p2))
        or (d3 == 0 and _on_segment(*p1, *p2, *q1))
        or (d4 == 0 and _on_segment(*p1, *p2, *q2))
    )
