"""How many routes a result set is scored over, and why.

Driving score and success rate are sums over the records divided by the routes the agent was meant to drive (a
missing route counts 0). That count comes, first match wins, from ``--num-routes``, from the ``b2d-collect``
collection that wrote the records (its routes with a finished attempt in ``run_log.jsonl``; a collection's route
files list every planned attempt, most of which never run, so ``--routes`` does not override it), from the route
XML (``--routes``), from b2d-collect records without their run log (one route per record), else from Bench2Drive's
evaluation set of 220 routes, the Leaderboard merge tool's fixed denominator.
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
    #: The b2d-collect collection folder(s) the count comes from (empty for any other source).
    collections: tuple[Path, ...] = ()


def route_count(result_set: ResultSet, settings: EvalSettings) -> RouteCount:
    """The number of routes ``result_set`` is scored over, and why (see the module docstring for the order)."""
    if settings.num_routes is not None:
        return RouteCount(settings.num_routes, settings.num_routes_reason or "--num-routes")
    records = result_set.records
    collected = _collection_count(result_set, settings)
    if collected is not None:
        if settings.routes is None:
            return collected
        where = settings.routes_file if settings.routes_file is not None else "the route XML"
        reason = (f"{collected.reason} (not the {len(settings.routes)} route(s) of {where}: a collection's route file "
                  "lists every planned attempt)")  # fmt: skip
        return RouteCount(collected.value, reason, collected.collections)
    if settings.routes is not None:
        where = settings.routes_file if settings.routes_file is not None else "the route XML"
        return RouteCount(len(settings.routes), f"the routes of {where}")
    if records and all(isinstance(r.extra.get(COLLECT_EXTRA), dict) for r in records):
        return RouteCount(len(records), "b2d-collect records without their run_log.jsonl: one route per record")
    return RouteCount(
        BENCH2DRIVE_ROUTES,
        f"Bench2Drive's {BENCH2DRIVE_ROUTES} evaluation routes (bench2drive220); for other routes give --routes or "
        "--num-routes",
    )


def _collection_count(result_set: ResultSet, settings: EvalSettings) -> RouteCount | None:
    """The count of the b2d-collect collection(s) every record file of ``result_set`` lies in, else None."""
    if settings.collections is None or not result_set.sources:
        return None
    # One lookup per folder: a collection's results/ holds a file per route.
    corpora: dict[Path, tuple[Path, int] | None] = {}
    for path in result_set.sources:
        folder = Path(path).resolve().parent
        if folder not in corpora:
            corpora[folder] = settings.collections(path)
    found = list(corpora.values())
    if None in found:
        return None
    finished = dict(c for c in found if c is not None)
    total = sum(finished.values())
    return RouteCount(
        max(total, len(result_set.records)),
        f"b2d-collect collection {', '.join(str(r) for r in sorted(finished))}: {total} route(s) with a finished "
        "attempt in run_log.jsonl",
        tuple(sorted(finished)),
    )
