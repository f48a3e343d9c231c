"""Route-point planners that fill the near/far command and target fields of an annotation.

The released Bench2Drive collector does not ship this code (format.md, open question 2), so b2d-data follows
the TCP-style planners that the baselines train on: a *sparse* route (points where the RoadOption changes, and
at most every 50 m) consumed by planners that drop the points the ego has come close to. Three planners run
side by side, each over its own copy of the sparse route:

- ``near`` (TCP's waypoint planner): pops points within 4 m, looking at most 50 m along the route;
- ``far`` (TCP's command planner): pops points within 7.5 m, looking at most 25 m along the route;
- ``target`` (PDM-Lite's target planner): pops points within 7.5 m, looking at most 50 m along the route.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from b2d_data.format.road_option import RoadOption


@dataclass(frozen=True)
class RoutePoint:
    """A route point in CARLA world metres with the command that applies from it on."""

    x: float
    y: float
    command: RoadOption


def downsample_route(
    points: Sequence[tuple[float, float]], commands: Sequence[RoadOption], max_gap: float = 50.0
) -> list[int]:
    """Indices of the sparse route: the first and last point, each RoadOption change, and one every ``max_gap`` m."""
    if not points:
        return []
    keep = [0]
    travelled = 0.0
    for i in range(1, len(points)):
        travelled += math.dist(points[i], points[i - 1])
        changed = commands[i] != commands[i - 1]
        # A change keeps the last point of the old command too, so lane changes keep their start.
        if changed and keep[-1] != i - 1:
            keep.append(i - 1)
            travelled = math.dist(points[i], points[i - 1])
        if changed or travelled >= max_gap:
            keep.append(i)
            travelled = 0.0
    if keep[-1] != len(points) - 1:
        keep.append(len(points) - 1)
    return keep


class RoutePointPlanner:
    """Pops route points the ego came within ``min_distance`` of, looking ``max_distance`` m along the route."""

    def __init__(self, route: Sequence[RoutePoint], min_distance: float, max_distance: float) -> None:
        if not route:
            raise ValueError("a route planner needs at least one route point")
        self.min_distance = min_distance
        self.max_distance = max_distance
        self._route: deque[RoutePoint] = deque(route)

    def run_step(self, x: float, y: float) -> RoutePoint:
        """Advance past reached points and return the next one to head for."""
        route = self._route
        pop = 0
        farthest = -math.inf
        along = 0.0
        for i in range(1, len(route)):
            if along > self.max_distance:
                break
            along += math.hypot(route[i].x - route[i - 1].x, route[i].y - route[i - 1].y)
            distance = math.hypot(route[i].x - x, route[i].y - y)
            if distance <= self.min_distance and distance > farthest:
                farthest = distance
                pop = i
        for _ in range(pop):
            if len(route) > 2:
                route.popleft()
        return route[1] if len(route) > 1 else route[0]


@dataclass(frozen=True)
class CommandPoints:
    """The three planner outputs of one frame."""

    near: RoutePoint
    far: RoutePoint
    target: RoutePoint


class CommandPlanners:
    """The near / far / target planners over one sparse route."""

    def __init__(self, sparse_route: Sequence[RoutePoint]) -> None:
        self.near = RoutePointPlanner(sparse_route, 4.0, 50.0)
        self.far = RoutePointPlanner(sparse_route, 7.5, 25.0)
        self.target = RoutePointPlanner(sparse_route, 7.5, 50.0)

    @classmethod
    def from_dense_route(cls, points: Sequence[tuple[float, float]], commands: Sequence[RoadOption]) -> CommandPlanners:
        """Build the planners from the leaderboard's dense 1 m route."""
        keep = downsample_route(points, commands)
        sparse = [RoutePoint(float(points[i][0]), float(points[i][1]), RoadOption(commands[i])) for i in keep]
        return cls(sparse)

    def run_step(self, x: float, y: float) -> CommandPoints:
        """Advance all three planners from the ego position (the GNSS ``x, y`` of the annotation)."""
        return CommandPoints(self.near.run_step(x, y), self.far.run_step(x, y), self.target.run_step(x, y))
