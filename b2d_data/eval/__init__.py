"""Metrics over Leaderboard result JSON, exactly as Bench2Drive computes them (format.md §8).

Driving score and success rate (``driving_score``), the five abilities with the Traffic_Signs credit
(``abilities``, ``junctions``), driving efficiency (``efficiency``), smoothness (``smoothness``), result
sets read from per-process or merged files (``results``), the combined summary JSON (``summary``) and the
table and bar chart (``report``). The ``b2d-eval`` console script lives in ``b2d_data.cli.eval``.
"""

from b2d_data.eval.abilities import (
    ABILITIES,
    AbilityResult,
    AbilityScore,
    JunctionLookup,
    JunctionProvider,
    JunctionUnavailable,
    TrafficSignCheck,
    compute_abilities,
    first_junction_lookup,
)
from b2d_data.eval.driving_score import BENCH2DRIVE_ROUTES, DrivingScores, driving_scores
from b2d_data.eval.efficiency import Efficiency, driving_efficiency, route_efficiency
from b2d_data.eval.junctions import MapJunctionProvider, find_town_map
from b2d_data.eval.results import EvalInputError, ResultSet, load_result_argument, load_result_set
from b2d_data.eval.smoothness import Smoothness, driving_smoothness, read_metric_info, route_smoothness
from b2d_data.eval.summary import EvalSettings, SetSummary, evaluate, summary_json

__all__ = [
    "ABILITIES", "AbilityResult", "AbilityScore", "BENCH2DRIVE_ROUTES", "DrivingScores", "Efficiency",
    "EvalInputError", "EvalSettings", "JunctionLookup", "JunctionProvider", "JunctionUnavailable",
    "MapJunctionProvider", "ResultSet", "SetSummary", "Smoothness", "TrafficSignCheck", "compute_abilities",
    "driving_efficiency", "driving_scores", "driving_smoothness", "evaluate", "find_town_map",
    "first_junction_lookup", "load_result_argument", "load_result_set", "read_metric_info", "route_efficiency",
    "route_smoothness", "summary_json",
]  # fmt: skip
