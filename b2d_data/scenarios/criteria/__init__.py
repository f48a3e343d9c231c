"""Route criteria with Bench2Drive's semantics (expert-and-scenarios.md §4, format.md §8.1–8.2).

:class:`RouteCriteria` runs all of them for one route; the single tests are importable for focused use.
They read only the :class:`~b2d_data.sim.api.Snapshot`, the :class:`~b2d_data.maps.Map` and the
:class:`~b2d_data.scenarios.route.DenseRoute`.
"""

from b2d_data.scenarios.criteria.base import Criterion, Infraction, planar_speed, segments_intersect
from b2d_data.scenarios.criteria.blocked import ActorBlockedTest
from b2d_data.scenarios.criteria.collision import CollisionTest
from b2d_data.scenarios.criteria.lanes import OutsideRouteLanesTest
from b2d_data.scenarios.criteria.route_criteria import (
    BLOCKED_MAX_TIME,
    MIN_SPEED_CHECKPOINTS,
    SWITCH_ACTOR_BLOCKED,
    SWITCH_WRONG_DIRECTION,
    CriteriaResult,
    RouteCriteria,
    as_infraction,
)
from b2d_data.scenarios.criteria.route_progress import (
    InRouteTest,
    MinimumSpeedRouteTest,
    RouteCompletionTest,
    RouteTimeout,
)
from b2d_data.scenarios.criteria.traffic_rules import RunningRedLightTest, RunningStopTest, stop_line_waypoints

__all__ = [
    "BLOCKED_MAX_TIME", "MIN_SPEED_CHECKPOINTS", "SWITCH_ACTOR_BLOCKED", "SWITCH_WRONG_DIRECTION",
    "ActorBlockedTest", "CollisionTest", "CriteriaResult", "Criterion", "InRouteTest", "Infraction",
    "MinimumSpeedRouteTest", "OutsideRouteLanesTest", "RouteCompletionTest", "RouteCriteria", "RouteTimeout",
    "RunningRedLightTest", "RunningStopTest", "as_infraction", "planar_speed", "segments_intersect",
    "stop_line_waypoints",
]  # fmt: skip
