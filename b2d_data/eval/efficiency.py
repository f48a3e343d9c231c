"""Driving efficiency from the min-speed messages (tools/efficiency_smoothness_benchmark.py, format.md §8.6).

Each min-speed checkpoint message says how fast the ego drove relative to the surrounding background
traffic, in percent. A route's efficiency is the mean of its checkpoint values that are ≤ 1000 %; routes
without any message are left out; the result set's efficiency is the mean over the routes that have one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from b2d_data.format.leaderboard import MIN_SPEED_INFRACTIONS, RouteRecord, parse_min_speed_percentage

#: Checkpoint values above this are outliers Bench2Drive drops.
MAX_PERCENTAGE = 1000.0


def route_efficiency(record: RouteRecord) -> float | None:
    """Mean of a route's min-speed percentages ≤ 1000, or None when it has none."""
    values = []
    for message in record.infractions.get(MIN_SPEED_INFRACTIONS, []):
        value = parse_min_speed_percentage(message)
        if value is not None and value <= MAX_PERCENTAGE:
            values.append(value)
    return sum(values) / len(values) if values else None


@dataclass(frozen=True)
class Efficiency:
    """Driving efficiency of a result set and which routes it is averaged over."""

    value: float | None
    routes: int
    #: Routes with messages whose every value exceeded 1000 % (Bench2Drive's tool divides by zero there).
    all_outliers: tuple[str, ...] = field(default=())


def driving_efficiency(records: Sequence[RouteRecord]) -> Efficiency:
    """Mean route efficiency over the routes that have min-speed messages."""
    per_route: list[float] = []
    outliers: list[str] = []
    for record in records:
        if not record.infractions.get(MIN_SPEED_INFRACTIONS):
            continue
        value = route_efficiency(record)
        if value is None:
            outliers.append(record.route_id)
        else:
            per_route.append(value)
    value = sum(per_route) / len(per_route) if per_route else None
    return Efficiency(value=value, routes=len(per_route), all_outliers=tuple(outliers))
