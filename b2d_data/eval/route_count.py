"""How many routes a result set is scored over, and why.

Driving score and success rate are sums over the records divided by the routes the agent was meant to drive (a
missing route counts 0). That count comes, first match wins, from ``--num-routes``, from the route XML
(``--routes``), from the ``b2d-collect`` collection that wrote the records (its routes with a finished attempt in
``run_log.jsonl``; without a run log beside them, one route per record), else from Bench2Drive's evaluation set of
220 routes, the Leaderboard merge tool's fixed denominator.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from b2d_data.eval.driving_score import BENCH2DRIVE_ROUTES

if TYPE_CHECKING:
    from b2d_data.eval.results import ResultSet
    from b2d_data.eval.summary import EvalSettings

#: The ``extra`` key that ``b2d-collect`` puts in each route record it writes.
COLLECT_EXTRA = "b2d_collect"


@dataclass(frozen=True)
class RouteCount:
    """The denominator of driving score and success rate, with where it comes from (shown to the user)."""

    value: int
    reason: str


def collection_root(path: Path) -> Path | None:
    """The ``b2d-collect`` corpus that a result file belongs to (``<root>/results/<file>`` beside a run log)."""
    from b2d_data.collection import run_log as rl
    from b2d_data.collection.job import RESULTS_DIR

    folder = Path(path).resolve().parent
    root = folder.parent
    if folder.name == RESULTS_DIR and (root / rl.LOG_FILE).is_file():
        return root
    return None


def collection_routes(root: Path) -> int:
    """Routes of a ``b2d-collect`` corpus with a finished attempt (each has one record in ``results/``)."""
    from b2d_data.collection import run_log as rl

    finals = rl.final_records(rl.read_run_log(root / rl.LOG_FILE))
    return len({str(r.get("route_id")) for r in finals})


def route_count(result_set: ResultSet, settings: EvalSettings) -> RouteCount:
    """The number of routes ``result_set`` is scored over, and why (see the module docstring for the order)."""
    if settings.num_routes is not None:
        return RouteCount(settings.num_routes, "--num-routes")
    if settings.routes is not None:
        where = settings.routes_file if settings.routes_file is not None else "the route XML"
        return RouteCount(len(settings.routes), f"the routes of {where}")
    records = result_set.records
    if records and all(isinstance(r.extra.get(COLLECT_EXTRA), dict) for r in records):
        roots = {collection_root(p) for p in result_set.sources}
        if None not in roots:
            known = sorted(r for r in roots if r is not None)
            finished = sum(collection_routes(r) for r in known)
            return RouteCount(
                max(finished, len(records)),
                f"b2d-collect collection {', '.join(str(r) for r in known)}: {finished} route(s) with a finished "
                "attempt in run_log.jsonl",
            )
        return RouteCount(len(records), "b2d-collect records without their run_log.jsonl: one route per record")
    return RouteCount(
        BENCH2DRIVE_ROUTES,
        f"Bench2Drive's {BENCH2DRIVE_ROUTES} evaluation routes (bench2drive220); for other routes give --routes or "
        "--num-routes",
    )
