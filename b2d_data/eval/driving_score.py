"""Driving score and success rate as tools/merge_route_json.py computes them (format.md §8.4)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from b2d_data.format.leaderboard import RouteRecord

#: The number of routes of the Bench2Drive evaluation set, the merge tool's fixed denominator.
BENCH2DRIVE_ROUTES = 220


@dataclass(frozen=True)
class DrivingScores:
    """Closed-loop scores of one result set; every figure is a percentage over ``num_routes``."""

    num_routes: int
    num_records: int
    num_success: int
    #: Σ score_composed / num_routes (missing routes count 0).
    driving_score: float
    #: 100 × successes / num_routes.
    success_rate: float
    #: Σ score_route / num_routes (the leaderboard's "Avg. route completion").
    route_completion: float
    #: 100 × Σ score_penalty / num_routes (the leaderboard's "Avg. infraction penalty" as a percentage).
    infraction_penalty: float

    @property
    def missing(self) -> int:
        """Expected routes without a record (negative when there are more records than routes)."""
        return self.num_routes - self.num_records


def driving_scores(records: Sequence[RouteRecord], num_routes: int = BENCH2DRIVE_ROUTES) -> DrivingScores:
    """Driving score, success rate, mean completion and penalty over ``num_routes`` routes."""
    if num_routes < 1:
        raise ValueError(f"the number of routes must be at least 1, got {num_routes}")
    successes = sum(1 for r in records if r.success)
    return DrivingScores(
        num_routes=num_routes,
        num_records=len(records),
        num_success=successes,
        driving_score=sum(r.scores.score_composed for r in records) / num_routes,
        success_rate=100.0 * successes / num_routes,
        route_completion=sum(r.scores.score_route for r in records) / num_routes,
        infraction_penalty=100.0 * sum(r.scores.score_penalty for r in records) / num_routes,
    )
