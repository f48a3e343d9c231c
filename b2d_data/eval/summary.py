"""Every Bench2Drive figure of one or several result sets, and the JSON that holds them.

``evaluate`` turns a ``ResultSet`` into a ``SetSummary`` (driving score, success rate, completion,
penalty, infractions per km, efficiency, smoothness in both modes, abilities with the Traffic_Signs
credit, per-route rows and warnings); ``summary_json`` gathers several summaries into one JSON object.
All scores are percentages (0–100) except the per-km infraction rates of ``global_record``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from b2d_data.eval.abilities import (
    ABILITIES,
    MAP_MISSING,
    MAP_UNUSABLE,
    AbilityResult,
    JunctionProvider,
    TrafficSignCheck,
    compute_abilities,
)
from b2d_data.eval.driving_score import DrivingScores, driving_scores
from b2d_data.eval.efficiency import Efficiency, driving_efficiency, route_efficiency
from b2d_data.eval.results import EvalInputError, ResultSet
from b2d_data.eval.route_count import CollectionLookup, RouteCount, route_count
from b2d_data.eval.smoothness import Smoothness, driving_smoothness
from b2d_data.format.leaderboard import GlobalRecord, compute_global_record
from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

SUMMARY_FORMAT = "b2d-eval-summary"
SUMMARY_VERSION = 1


@dataclass(frozen=True)
class EvalSettings:
    """What to compute and against what."""

    #: Denominator of driving score and success rate; None → the route XML's count, else the collection's (records
    #: of b2d-collect), else 220 (``route_count.py``).
    num_routes: int | None = None
    #: Where ``num_routes`` comes from, for the user (default: the ``--num-routes`` option).
    num_routes_reason: str | None = None
    routes: Sequence[Route] | None = None
    routes_file: Path | None = None
    #: Per result set, the folder holding ``<save_name>/metric_info.json`` (None → no smoothness).
    metric_dir: Path | None = None
    corrected_smoothness: bool = False
    junctions: JunctionProvider | None = None
    maps_dir: Path | None = None
    strict: bool = False
    #: Finds the b2d-collect corpus of a record file (None: b2d-collect records count one route each).
    collections: CollectionLookup | None = None


@dataclass
class SetSummary:
    """All figures of one result set."""

    result_set: ResultSet
    scores: DrivingScores
    global_record: GlobalRecord
    efficiency: Efficiency
    smoothness: Smoothness | None = None
    smoothness_corrected: Smoothness | None = None
    abilities: AbilityResult | None = None
    missing_routes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: The denominator of driving score and success rate and where it comes from.
    route_count: RouteCount | None = None

    @property
    def name(self) -> str:
        """Column label."""
        return self.result_set.name


def _check_against_routes(result_set: ResultSet, routes: Sequence[Route], routes_file: Path | None) -> list[str]:
    """Route ids of the XML without a record; raise when records name routes the XML lacks."""
    xml_ids = {r.id for r in routes}
    unknown = [r.route_id for r in result_set.records if r.route_number not in xml_ids]
    if unknown:
        shown = ", ".join(unknown[:5]) + (" ..." if len(unknown) > 5 else "")
        where = routes_file if routes_file is not None else Path("<routes>")
        raise EvalInputError(
            where,
            f"{len(unknown)} record(s) of '{result_set.name}' name routes this file does not hold ({shown}); "
            "pass the route XML the agent was evaluated on",
        )
    have = {r.route_number for r in result_set.records}
    return [r.id for r in routes if r.id not in have]


def _unchecked_warnings(abilities: AbilityResult) -> list[str]:
    """One line per reason why failed Traffic_Signs routes could not get the credit check."""
    by_kind: dict[str, list[TrafficSignCheck]] = {}
    for check in abilities.unchecked:
        by_kind.setdefault(check.unchecked_kind or MAP_UNUSABLE, []).append(check)
    lines = []
    for kind, checks in by_kind.items():
        towns = sorted({c.town for c in checks})
        detail = "" if kind == MAP_MISSING else f": {checks[0].reason}"
        lines.append(
            f"Traffic_Signs credit not checked for {len(checks)} failed route(s), {kind} "
            f"({', '.join(towns)}){detail}; Traffic_Signs may be under-estimated"
        )
    return lines


def evaluate(result_set: ResultSet, settings: EvalSettings, metric_dir: Path | None = None) -> SetSummary:
    """Compute every figure of one result set (``metric_dir`` overrides ``settings.metric_dir``)."""
    warnings: list[str] = []
    count = route_count(result_set, settings)
    num_routes = count.value
    records = result_set.records
    missing_routes: list[str] = []
    routes = settings.routes
    if routes is not None:
        missing_routes = _check_against_routes(result_set, routes, settings.routes_file)
        if count.collections:
            # A collection's route file also lists the attempts it never needed: they are neither missing nor
            # crashed, so only the routes that ran are used (for the abilities).
            ran = {r.route_number for r in records}
            routes, missing_routes = [r for r in routes if r.id in ran], []

    for path, reason in result_set.skipped_files:
        warnings.append(f"skipped {path}: {reason}")
    if result_set.duplicates:
        kept = "; ".join(f"route {d.route}: kept {d.kept}" for d in result_set.duplicates[:3])
        warnings.append(
            f"{len(result_set.duplicates)} route(s) had several records, the last one by file order was kept ({kept})"
        )
    if len(records) != num_routes:
        message = f"{len(records)} records for {num_routes} expected routes"
        if len(records) < num_routes:
            message += f"; the {num_routes - len(records)} missing route(s) count 0 in driving score and success rate"
        else:
            message += "; more records than routes (check --num-routes)"
        if settings.strict:
            raise EvalInputError(result_set.sources[0], f"{result_set.name}: {message} (strict mode)")
        log.warning("%s: %s", result_set.name, message)
        warnings.append(message)

    scores = driving_scores(records, num_routes)
    efficiency = driving_efficiency(records)
    if efficiency.all_outliers:
        warnings.append(
            f"efficiency: {len(efficiency.all_outliers)} route(s) have only min-speed values above 1000% and are "
            f"left out ({', '.join(efficiency.all_outliers[:3])})"
        )

    metric_dir = metric_dir if metric_dir is not None else settings.metric_dir
    smoothness = smoothness_corrected = None
    if metric_dir is not None:
        smoothness = driving_smoothness(records, metric_dir)
        if settings.corrected_smoothness:
            smoothness_corrected = driving_smoothness(records, metric_dir, corrected=True)
        if smoothness.missing_files:
            warnings.append(
                f"smoothness: {len(smoothness.missing_files)} record(s) have no metric_info.json "
                f"(e.g. {smoothness.missing_files[0]}) and are left out"
            )
        if smoothness.too_short:
            warnings.append(f"smoothness: {len(smoothness.too_short)} route(s) have fewer than 3 steps, left out")

    abilities = None
    if routes is not None:
        abilities = compute_abilities(records, routes, settings.junctions)
        warnings.extend(_unchecked_warnings(abilities))
    return SetSummary(
        result_set=result_set,
        scores=scores,
        global_record=compute_global_record(records, num_routes),
        efficiency=efficiency,
        smoothness=smoothness,
        smoothness_corrected=smoothness_corrected,
        abilities=abilities,
        missing_routes=missing_routes,
        warnings=warnings,
        route_count=count,
    )


# ---------------------------------------------------------------------------------------------------------------
# JSON


def _smoothness_json(s: Smoothness | None) -> dict[str, Any] | None:
    if s is None:
        return None
    return {
        "value": s.value,
        "mode": s.mode,
        "time_step_s": s.time_step,
        "routes": len(s.per_route),
        "missing_metric_files": list(s.missing_files),
        "too_short": list(s.too_short),
    }


def _abilities_json(a: AbilityResult | None) -> dict[str, Any] | None:
    if a is None:
        return None
    out: dict[str, Any] = {}
    for ability in ABILITIES:
        s = a.scores[ability]
        out[ability.value] = {
            "value": s.value,
            "successes": s.successes,
            "routes": s.routes,
            "routes_in_xml": s.routes_in_xml,
            "traffic_sign_credit": s.credited,
        }
    out["mean"] = a.mean
    out["crashed"] = [[scenario, route_id] for scenario, route_id in a.crashed]
    out["traffic_sign_checks"] = [
        {
            "route_id": c.route_id,
            "scenario_type": c.scenario_type,
            "town": c.town,
            "score_route": c.score_route,
            "checked": c.checked,
            "unchecked_kind": c.unchecked_kind,
            "credited": c.credited,
            "first_junction": c.first_junction,
            "num_waypoints": c.num_waypoints,
            "threshold": c.threshold,
            "reason": c.reason,
        }
        for c in a.traffic_sign_checks
    ]
    out["unchecked_routes"] = [
        {"route_id": c.route_id, "town": c.town, "kind": c.unchecked_kind, "reason": c.reason}
        for c in a.traffic_sign_checks
        if not c.checked
    ]
    return out


def _per_route(summary: SetSummary, routes: Sequence[Route] | None) -> list[dict[str, Any]]:
    xml = {r.id: r for r in routes} if routes is not None else {}
    smooth = summary.smoothness.per_route if summary.smoothness else {}
    smooth_c = summary.smoothness_corrected.per_route if summary.smoothness_corrected else {}
    rows = []
    for record, origin in zip(summary.result_set.records, summary.result_set.origins):
        route = xml.get(record.route_number)
        scenario_type = route.scenario_type if route is not None else (record.scenario_name or "").rsplit("_", 1)[0]
        rows.append(
            {
                "route_id": record.route_id,
                "route": record.route_number,
                "scenario_type": scenario_type,
                "town": record.town_name,
                "status": record.status,
                "success": record.success,
                "score_route": record.scores.score_route,
                "score_penalty": record.scores.score_penalty,
                "score_composed": record.scores.score_composed,
                "infractions": record.infraction_counts(),
                "efficiency": route_efficiency(record),
                "smoothness": smooth.get(record.route_id),
                "smoothness_corrected": smooth_c.get(record.route_id),
                "source": origin,
            }
        )
    return rows


def set_summary_json(summary: SetSummary, settings: EvalSettings) -> dict[str, Any]:
    """One result set's figures as a JSON object."""
    rs, sc = summary.result_set, summary.scores
    return {
        "name": rs.name,
        "sources": [str(p) for p in rs.sources],
        "records_read": rs.records_read,
        "records": sc.num_records,
        "expected_routes": sc.num_routes,
        "expected_routes_reason": summary.route_count.reason if summary.route_count is not None else None,
        "missing_routes": summary.missing_routes,
        "duplicates": [
            {"route": d.route, "occurrences": list(d.occurrences), "kept": d.kept} for d in rs.duplicates
        ],
        "driving_score": sc.driving_score,
        "success_rate": sc.success_rate,
        "successes": sc.num_success,
        "route_completion": sc.route_completion,
        "infraction_penalty": sc.infraction_penalty,
        "efficiency": {
            "value": summary.efficiency.value,
            "routes": summary.efficiency.routes,
            "all_outlier_routes": list(summary.efficiency.all_outliers),
        },
        "smoothness": _smoothness_json(summary.smoothness),
        "smoothness_corrected": _smoothness_json(summary.smoothness_corrected),
        "abilities": _abilities_json(summary.abilities),
        "global_record": summary.global_record.to_dict(),
        "warnings": list(summary.warnings),
        "per_route": _per_route(summary, settings.routes),
    }


def summary_json(summaries: Sequence[SetSummary], settings: EvalSettings) -> dict[str, Any]:
    """The whole evaluation: settings, units and one object per result set."""
    counts = {s.scores.num_routes for s in summaries}
    return {
        "format": SUMMARY_FORMAT,
        "version": SUMMARY_VERSION,
        "units": (
            "driving_score, success_rate, route_completion, infraction_penalty, efficiency, smoothness and "
            "abilities are percentages (0-100); global_record.infractions are events per km driven"
        ),
        # One count for every set, else None (each set's expected_routes then says its own).
        "num_routes": next(iter(counts)) if len(counts) == 1 else None,
        "routes_file": str(settings.routes_file) if settings.routes_file else None,
        "maps_dir": str(settings.maps_dir) if settings.maps_dir else None,
        "smoothness_modes": {
            "smoothness": "Bench2Drive tools/efficiency_smoothness_benchmark.py, quirks kept "
            "(deg/s against rad/s bounds, dt 0.1 s on 20 Hz samples, yaw rate checked as yaw acceleration)",
            "smoothness_corrected": "angular velocity in rad/s, dt 0.05 s, yaw acceleration = d(yaw rate)/dt; "
            "not comparable with published Bench2Drive numbers",
        },
        "result_sets": [set_summary_json(s, settings) for s in summaries],
    }
