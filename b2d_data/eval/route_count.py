"""How many routes a result set is scored over, and why.

Driving score and success rate are sums over the records divided by the routes the agent was meant to drive (a
missing route counts 0). That count comes, first match wins, from ``--num-routes``, from the route XML
(``--routes``), from the ``b2d-collect`` collection that wrote the records (its routes with a finished attempt in
``run_log.jsonl``; without a run log beside them, one route per record), else from Bench2Drive's evaluation set of
220 routes, the Leaderboard merge tool's fixed denominator.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from b2d_data.eval.driving_score import BENCH2DRIVE_ROUTES

if TYPE_CHECKING:
    from b2d_data.eval.results import ResultSet
    from b2d_data.eval.summary import EvalSettings

#: The ``extra`` key that ``b2d-collect`` puts in each route record it writes.
COLLECT_EXTRA = "b2d_collect"

#: Given a record file, the ``b2d-collect`` corpus that wrote it and that corpus's routes with a finished attempt,
#: or None (the CLI passes ``collection.corpus.collection_of``; eval itself does not read collections).
CollectionLookup = Callable[[Path], "tuple[Path, int] | None"]


@dataclass(frozen=True)
class RouteCount:
    """The denominator of driving score and success rate, with where it comes from (shown to the user)."""

    value: int
    reason: str


def route_count(result_set: ResultSet, settings: EvalSettings) -> RouteCount:
    """The number of routes ``result_set`` is scored over, and why (see the module docstring for the order)."""
    if settings.num_routes is not None:
        return RouteCount(settings.num_routes, settings.num_routes_reason or "--num-routes")
    if settings.routes is not None:
        where = settings.routes_file if settings.routes_file is not None else "the route XML"
        return RouteCount(len(settings.routes), f"the routes of {where}")
    records = result_set.records
    # One lookup per folder: a collection's results/ holds a file per route.
    corpora: dict[Path, tuple[Path, int] | None] = {}
    for path in result_set.sources:
        folder = Path(path).resolve().parent
        if folder not in corpora:
            corpora[folder] = settings.collections(path) if settings.collections is not None else None
    found = list(corpora.values())
    if found and None not in found:
        finished = dict(c for c in found if c is not None)
        total = sum(finished.values())
        return RouteCount(
            max(total, len(records)),
            f"b2d-collect collection {', '.join(str(r) for r in sorted(finished))}: {total} route(s) with a finished "
            "attempt in run_log.jsonl",
        )
    if records and all(isinstance(r.extra.get(COLLECT_EXTRA), dict) for r in records):
        return RouteCount(len(records), "b2d-collect records without their run_log.jsonl: one route per record")
    return RouteCount(
        BENCH2DRIVE_ROUTES,
        f"Bench2Drive's {BENCH2DRIVE_ROUTES} evaluation routes (bench2drive220); for other routes give --routes or "
        "--num-routes",
    )
