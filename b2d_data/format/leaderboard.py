"""Leaderboard 2.0 checkpoint JSON as Bench2Drive writes and reads it (format.md §8.2–8.4).

One module holds the whole contract: the record dataclasses with their exact key order, the penalty
factors, the infraction message formats, the success rule of ``merge_route_json.py`` and the
``global_record`` of ``statistics_manager.py``. The scenario criteria use it to *write* per-route
records; ``b2d_data.eval`` uses it to *read* them. Two layouts are accepted: the per-process checkpoint
file (``_checkpoint`` with ``global_record``/``progress``/``records`` plus ``entry_status``, ``eligible``,
``sensors``, ``values``, ``labels``) and the ``merged.json`` of ``tools/merge_route_json.py`` (only
``_checkpoint.records`` without ``index``, plus ``"driving score"``, ``"success rate"``, ``"eval num"``).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.transform import Location

#: Rounding of meta values and standard deviations (statistics_manager ``ROUND_DIGITS``).
ROUND_DIGITS = 3
#: Rounding of scores (statistics_manager ``ROUND_DIGITS_SCORE``).
ROUND_DIGITS_SCORE = 6

COLLISIONS_LAYOUT = "collisions_layout"
COLLISIONS_PEDESTRIAN = "collisions_pedestrian"
COLLISIONS_VEHICLE = "collisions_vehicle"
RED_LIGHT = "red_light"
STOP_INFRACTION = "stop_infraction"
OUTSIDE_ROUTE_LANES = "outside_route_lanes"
MIN_SPEED_INFRACTIONS = "min_speed_infractions"
YIELD_EMERGENCY_VEHICLE = "yield_emergency_vehicle_infractions"
SCENARIO_TIMEOUTS = "scenario_timeouts"
ROUTE_DEV = "route_dev"
VEHICLE_BLOCKED = "vehicle_blocked"
ROUTE_TIMEOUT = "route_timeout"

#: Keys of a record's ``infractions`` object, in the order the leaderboard writes them.
INFRACTION_KEYS: tuple[str, ...] = (
    COLLISIONS_LAYOUT,
    COLLISIONS_PEDESTRIAN,
    COLLISIONS_VEHICLE,
    RED_LIGHT,
    STOP_INFRACTION,
    OUTSIDE_ROUTE_LANES,
    MIN_SPEED_INFRACTIONS,
    YIELD_EMERGENCY_VEHICLE,
    SCENARIO_TIMEOUTS,
    ROUTE_DEV,
    VEHICLE_BLOCKED,
    ROUTE_TIMEOUT,
)

#: Events that multiply the penalty by a fixed factor, once per event (``PENALTY_VALUE_DICT``).
PENALTY_FACTORS: dict[str, float] = {
    COLLISIONS_PEDESTRIAN: 0.5,
    COLLISIONS_VEHICLE: 0.6,
    COLLISIONS_LAYOUT: 0.65,
    RED_LIGHT: 0.7,
    STOP_INFRACTION: 0.8,
    SCENARIO_TIMEOUTS: 0.7,
    YIELD_EMERGENCY_VEHICLE: 0.7,
}

#: Percentage-valued events: (per-unit value, kind). Bench2Drive marks min speed 'unused' (no penalty) and
#: gives outside-route-lanes the value 0 of kind 'increases', i.e. a factor (1 − pct/100).
PERCENTAGE_PENALTIES: dict[str, tuple[float, str]] = {
    OUTSIDE_ROUTE_LANES: (0.0, "increases"),
    MIN_SPEED_INFRACTIONS: (0.7, "unused"),
}

STATUS_STARTED = "Started"
STATUS_PERFECT = "Perfect"
STATUS_COMPLETED = "Completed"
STATUS_FAILED = "Failed"
#: Statuses that count as reaching the end of the route.
FINISHED_STATUSES: tuple[str, ...] = (STATUS_COMPLETED, STATUS_PERFECT)

#: Reasons appended to "Failed - " by the leaderboard and the statistics manager.
FAILURE_REASONS: tuple[str, ...] = (
    "Agent timed out",
    "Agent deviated from the route",
    "Agent got blocked",
    "TickRuntime",
    "Simulation crashed",
    "Agent's sensors were invalid",
    "Agent couldn't be set up",
    "Agent crashed",
)

ENTRY_STATUS_VALUES: tuple[str, ...] = ("Started", "Finished", "Rejected", "Crashed", "Invalid")
ELIGIBLE_VALUES: dict[str, bool] = {
    "Started": False,
    "Finished": True,
    "Rejected": False,
    "Crashed": False,
    "Invalid": False,
}

#: The 15 ``labels`` of a checkpoint file; ``values`` follow the same order.
LABELS: tuple[str, ...] = (
    "Avg. driving score",
    "Avg. route completion",
    "Avg. infraction penalty",
    "Collisions with pedestrians",
    "Collisions with vehicles",
    "Collisions with layout",
    "Red lights infractions",
    "Stop sign infractions",
    "Off-road infractions",
    "Route deviations",
    "Route timeouts",
    "Agent blocked",
    "Yield emergency vehicles infractions",
    "Scenario timeouts",
    "Min speed infractions",
)

#: Global-record infraction key behind each label after the first three.
_LABEL_KEYS: tuple[str, ...] = (
    COLLISIONS_PEDESTRIAN,
    COLLISIONS_VEHICLE,
    COLLISIONS_LAYOUT,
    RED_LIGHT,
    STOP_INFRACTION,
    OUTSIDE_ROUTE_LANES,
    ROUTE_DEV,
    ROUTE_TIMEOUT,
    VEHICLE_BLOCKED,
    YIELD_EMERGENCY_VEHICLE,
    SCENARIO_TIMEOUTS,
    MIN_SPEED_INFRACTIONS,
)

#: Top-level keys of ``merged.json`` written by tools/merge_route_json.py.
MERGED_KEYS: tuple[str, ...] = ("driving score", "success rate", "eval num")


class LeaderboardFormatError(B2DFormatError):
    """A file that is not Leaderboard checkpoint JSON (or merged.json); the message names the file."""


# ---------------------------------------------------------------------------------------------------------------
# penalties, status, success


def penalty_factor(key: str, percentage: float | None = None) -> float:
    """Factor one event of infraction ``key`` multiplies the route penalty by (1.0 for keys without penalty)."""
    if key in PENALTY_FACTORS:
        return PENALTY_FACTORS[key]
    if key in PERCENTAGE_PENALTIES:
        value, kind = PERCENTAGE_PENALTIES[key]
        if kind == "unused":
            return 1.0
        if percentage is None:
            raise ValueError(f"infraction {key!r} needs its percentage to compute a penalty factor")
        if kind == "increases":
            return 1.0 - (1.0 - value) * percentage / 100.0
        return 1.0 - (1.0 - value) * (1.0 - percentage / 100.0)
    if key in INFRACTION_KEYS:
        return 1.0
    raise KeyError(f"unknown infraction key {key!r}; known keys: {', '.join(INFRACTION_KEYS)}")


def score_penalty(events: Iterable[tuple[str, float | None]]) -> float:
    """Product of the penalty factors of ``(infraction key, percentage or None)`` events, in event order."""
    penalty = 1.0
    for key, percentage in events:
        penalty *= penalty_factor(key, percentage)
    return penalty


def route_status(target_reached: bool, num_infractions: int, failure_message: str = "") -> str:
    """Record status the statistics manager assigns ('Perfect', 'Completed', 'Failed' or 'Failed - <msg>')."""
    if target_reached:
        return STATUS_COMPLETED if num_infractions > 0 else STATUS_PERFECT
    return f"{STATUS_FAILED} - {failure_message}" if failure_message else STATUS_FAILED


def is_success(status: str, infractions: Mapping[str, Sequence[str]]) -> bool:
    """Bench2Drive success: finished and no infraction other than min-speed messages (merge_route_json.py)."""
    if status not in FINISHED_STATUSES:
        return False
    return all(len(messages) == 0 for key, messages in infractions.items() if key != MIN_SPEED_INFRACTIONS)


# ---------------------------------------------------------------------------------------------------------------
# infraction messages (scenario_runner atomic_criteria.py formats; locations rounded to 3 decimals)


def _at(location: Location | Sequence[float]) -> str:
    x, y, z = (location.x, location.y, location.z) if isinstance(location, Location) else tuple(location)
    return f"(x={round(float(x), 3)}, y={round(float(y), 3)}, z={round(float(z), 3)})"


def collision_message(type_id: str, actor_id: int, location: Location | Sequence[float]) -> str:
    """Message of a collision event; ``location`` is the ego's location at impact."""
    return f"Agent collided against object with type={type_id} and id={actor_id} at {_at(location)}"


def collision_key(type_id: str) -> str | None:
    """Infraction list a collision with ``type_id`` goes to, or None when the leaderboard ignores it."""
    if ("static" in type_id or "traffic" in type_id) and "sidewalk" not in type_id:
        return COLLISIONS_LAYOUT
    if "vehicle" in type_id:
        return COLLISIONS_VEHICLE
    if "walker" in type_id:
        return COLLISIONS_PEDESTRIAN
    return None


def red_light_message(light_id: int, location: Location | Sequence[float]) -> str:
    """Message of a red-light infraction; ``location`` is the traffic light actor's location."""
    return f"Agent ran a red light {light_id} at {_at(location)}"


def stop_message(stop_id: int, location: Location | Sequence[float]) -> str:
    """Message of a stop-sign infraction; ``location`` is the stop sign actor's location."""
    return f"Agent ran a stop with id={stop_id} at {_at(location)}"


def outside_lanes_message(distance_m: float, percentage: float) -> str:
    """Message of the outside-route-lanes event (distance rounded to 3, percentage to 2 decimals)."""
    return (
        f"Agent went outside its route lanes for about {round(float(distance_m), 3)} meters "
        f"({round(float(percentage), 2)}% of the completed route)"
    )


def route_deviation_message(location: Location | Sequence[float]) -> str:
    """Message of a route deviation (ends the route)."""
    return f"Agent deviated from the route at {_at(location)}"


def blocked_message(location: Location | Sequence[float]) -> str:
    """Message of the agent-blocked event (ends the route)."""
    return f"Agent got blocked at {_at(location)}"


def yield_emergency_message() -> str:
    """Message of a failure to yield to an emergency vehicle."""
    return "Agent failed to yield to an emergency vehicle"


def scenario_timeout_message() -> str:
    """Message of a scenario timeout."""
    return "Agent timed out a scenario"


def route_timeout_message() -> str:
    """Message of a route timeout."""
    return "Route timeout."


def min_speed_message(percentage: float | int) -> str:
    """Message of one min-speed checkpoint; pass ``round(value, 2)``, or the int 100 when no traffic was around."""
    return f"Average speed is {percentage}% of the surrounding traffic's one"


# Bench2Drive's efficiency tool takes the first "<number>%" of each message with this pattern.
_PERCENT = re.compile(r"\b\d+\.?\d*%")
_OUTSIDE = re.compile(r"for about ([-+\d.eE]+) meters \(([-+\d.eE]+)% of the completed route\)")


def parse_min_speed_percentage(message: str) -> float | None:
    """The percentage of a min-speed message, read as tools/efficiency_smoothness_benchmark.py does."""
    match = _PERCENT.search(message)
    return float(match.group().rstrip("%")) if match else None


def parse_outside_lanes(message: str) -> tuple[float, float] | None:
    """``(metres, percentage)`` of an outside-route-lanes message, or None when it does not match."""
    match = _OUTSIDE.search(message)
    return (float(match.group(1)), float(match.group(2))) if match else None


def record_route_id(route_id: str | int, repetition: int = 0) -> str:
    """``RouteScenario_<id>_rep<k>``: the record name of an XML route."""
    return f"RouteScenario_{route_id}_rep{repetition}"


def make_save_name(
    route_id: str, town: str, scenario_name: str, weather_id: str | int | None, when: datetime
) -> str:
    """``{route_id}_{town}_{scenario_name}_{weather_id}_{MM_DD_HH_MM_SS}`` as Bench2Drive names a route's folder."""
    return f"{route_id}_{town}_{scenario_name}_{weather_id}_{when.strftime('%m_%d_%H_%M_%S')}"


# ---------------------------------------------------------------------------------------------------------------
# records


@dataclass
class Scores:
    """A record's ``scores``: route completion (0–100), penalty (0–1) and their product."""

    score_route: float = 0
    score_penalty: float = 0
    score_composed: float = 0

    @classmethod
    def compose(cls, score_route: float, penalty: float) -> Scores:
        """Scores rounded as the statistics manager rounds them."""
        return cls(
            round(score_route, ROUND_DIGITS_SCORE),
            round(penalty, ROUND_DIGITS_SCORE),
            round(max(score_route * penalty, 0.0), ROUND_DIGITS_SCORE),
        )

    def to_dict(self) -> dict[str, float]:
        """The JSON object, in key order."""
        return {
            "score_route": self.score_route,
            "score_penalty": self.score_penalty,
            "score_composed": self.score_composed,
        }


@dataclass
class RouteMeta:
    """A record's ``meta``: route length in metres, game and wall-clock durations in seconds."""

    route_length: float = 0
    duration_game: float = 0
    duration_system: float = 0

    def to_dict(self) -> dict[str, float]:
        """The JSON object, in key order."""
        return {
            "route_length": self.route_length,
            "duration_game": self.duration_game,
            "duration_system": self.duration_system,
        }


def empty_infractions() -> dict[str, list[str]]:
    """All twelve infraction lists, empty, in key order."""
    return {key: [] for key in INFRACTION_KEYS}


@dataclass
class RouteRecord:
    """One route's result (``_checkpoint.records[i]``). ``index`` is None in merged files, which drop it."""

    route_id: str
    scenario_name: str | None = None
    weather_id: str | None = None
    save_name: str | None = None
    status: str = STATUS_STARTED
    num_infractions: int = 0
    infractions: dict[str, list[str]] = field(default_factory=empty_infractions)
    scores: Scores = field(default_factory=Scores)
    meta: RouteMeta = field(default_factory=RouteMeta)
    town_name: str | None = None
    index: int | None = -1
    #: Keys the file holds beyond the Bench2Drive schema (kept so that a read/write round trip is lossless).
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def route_number(self) -> str:
        """The XML route id inside ``RouteScenario_<id>_rep<k>`` (how ability_benchmark.py matches routes)."""
        parts = self.route_id.split("_")
        return parts[1] if len(parts) > 1 else self.route_id

    @property
    def repetition(self) -> int:
        """The ``k`` of ``_rep<k>`` (0 when absent)."""
        tail = self.route_id.rsplit("_rep", 1)
        return int(tail[1]) if len(tail) == 2 and tail[1].isdigit() else 0

    @property
    def success(self) -> bool:
        """Bench2Drive success (finished, no infraction but min-speed)."""
        return is_success(self.status, self.infractions)

    def infraction_counts(self) -> dict[str, int]:
        """Number of messages per infraction key, in key order."""
        keys = list(INFRACTION_KEYS) + [k for k in self.infractions if k not in INFRACTION_KEYS]
        return {key: len(self.infractions.get(key, [])) for key in keys}

    def add_infraction(self, key: str, message: str) -> None:
        """Append a message to an infraction list and keep ``num_infractions`` in step."""
        if key not in INFRACTION_KEYS:
            raise KeyError(f"unknown infraction key {key!r}; known keys: {', '.join(INFRACTION_KEYS)}")
        self.infractions.setdefault(key, []).append(message)
        self.num_infractions = sum(len(messages) for messages in self.infractions.values())

    def to_dict(self) -> dict[str, Any]:
        """The JSON object in the leaderboard's key order (``index`` omitted when None, as in merged files)."""
        out: dict[str, Any] = {}
        if self.index is not None:
            out["index"] = self.index
        out.update(
            {
                "route_id": self.route_id,
                "scenario_name": self.scenario_name,
                "weather_id": self.weather_id,
                "save_name": self.save_name,
                "status": self.status,
                "num_infractions": self.num_infractions,
                "infractions": {key: list(messages) for key, messages in self.infractions.items()},
                "scores": self.scores.to_dict(),
                "meta": self.meta.to_dict(),
            }
        )
        # A record of a route still running has no town yet in the leaderboard; keep the key only when set.
        if self.town_name is not None:
            out["town_name"] = self.town_name
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, data: Any, path: str | Path, position: int) -> RouteRecord:
        """Parse one record; ``path`` and ``position`` only serve the error messages."""
        where = f"record {position}"
        if not isinstance(data, dict):
            raise LeaderboardFormatError(path, f"{where} is a {type(data).__name__}, not an object")
        route_id = data.get("route_id")
        if not isinstance(route_id, str):
            raise LeaderboardFormatError(path, f"{where} has no string 'route_id' (e.g. 'RouteScenario_1711_rep0')")
        where = f"record {position} ({route_id})"
        for key in ("status", "infractions", "scores"):
            if key not in data:
                raise LeaderboardFormatError(path, f"{where} lacks '{key}'")
        infractions = data["infractions"]
        if not isinstance(infractions, dict) or not all(isinstance(v, list) for v in infractions.values()):
            raise LeaderboardFormatError(path, f"{where}: 'infractions' must map names to lists of messages")
        scores = data["scores"]
        if not isinstance(scores, dict):
            raise LeaderboardFormatError(path, f"{where}: 'scores' must be an object")
        for key in ("score_route", "score_penalty", "score_composed"):
            if not isinstance(scores.get(key), (int, float)) or isinstance(scores.get(key), bool):
                raise LeaderboardFormatError(path, f"{where}: 'scores.{key}' is missing or not a number")
        meta = data.get("meta", {})
        if not isinstance(meta, dict):
            raise LeaderboardFormatError(path, f"{where}: 'meta' must be an object")
        known = {
            "index", "route_id", "scenario_name", "weather_id", "save_name", "status", "num_infractions",
            "infractions", "scores", "meta", "town_name",
        }  # fmt: skip
        num = data.get("num_infractions")
        return cls(
            route_id=route_id,
            scenario_name=data.get("scenario_name"),
            weather_id=data.get("weather_id"),
            save_name=data.get("save_name"),
            status=str(data["status"]),
            num_infractions=int(num) if isinstance(num, (int, float)) else sum(len(v) for v in infractions.values()),
            infractions={str(k): [str(m) for m in v] for k, v in infractions.items()},
            scores=Scores(scores["score_route"], scores["score_penalty"], scores["score_composed"]),
            meta=RouteMeta(meta.get("route_length", 0), meta.get("duration_game", 0), meta.get("duration_system", 0)),
            town_name=data.get("town_name"),
            index=data.get("index") if "index" in data else None,
            extra={k: v for k, v in data.items() if k not in known},
        )


@dataclass
class GlobalRecord:
    """``_checkpoint.global_record``: means over the expected routes, infractions per km, totals."""

    status: str = STATUS_PERFECT
    infractions: dict[str, float] = field(default_factory=lambda: {key: 0 for key in INFRACTION_KEYS})
    scores_mean: dict[str, float] = field(
        default_factory=lambda: {"score_composed": 0, "score_route": 0, "score_penalty": 0}
    )
    scores_std_dev: dict[str, float] = field(
        default_factory=lambda: {"score_composed": 0, "score_route": 0, "score_penalty": 0}
    )
    total_length: float = 0
    duration_game: float = 0
    duration_system: float = 0
    #: ``[route_id, index, status]`` of every failed route.
    exceptions: list[list[Any]] = field(default_factory=list)
    index: int = -1
    route_id: int | str = -1

    def to_dict(self) -> dict[str, Any]:
        """The JSON object in the leaderboard's key order."""
        return {
            "index": self.index,
            "route_id": self.route_id,
            "status": self.status,
            "infractions": dict(self.infractions),
            "scores_mean": dict(self.scores_mean),
            "scores_std_dev": dict(self.scores_std_dev),
            "meta": {
                "total_length": self.total_length,
                "duration_game": self.duration_game,
                "duration_system": self.duration_system,
                "exceptions": [list(e) for e in self.exceptions],
            },
        }

    @classmethod
    def from_dict(cls, data: Any, path: str | Path) -> GlobalRecord:
        """Parse a ``global_record`` object."""
        if not isinstance(data, dict):
            raise LeaderboardFormatError(path, "'_checkpoint.global_record' must be an object")
        meta = data.get("meta", {}) if isinstance(data.get("meta", {}), dict) else {}
        return cls(
            status=data.get("status", STATUS_PERFECT),
            infractions=dict(data.get("infractions", {})),
            scores_mean=dict(data.get("scores_mean", {})),
            scores_std_dev=dict(data.get("scores_std_dev", {})),
            total_length=meta.get("total_length", 0),
            duration_game=meta.get("duration_game", 0),
            duration_system=meta.get("duration_system", 0),
            exceptions=[list(e) for e in meta.get("exceptions", [])],
            index=data.get("index", -1),
            route_id=data.get("route_id", -1),
        )


@dataclass
class LeaderboardResults:
    """A whole result file: a per-process checkpoint (``merged=False``) or a merged.json (``merged=True``)."""

    records: list[RouteRecord] = field(default_factory=list)
    global_record: GlobalRecord | None = None
    progress: list[int] = field(default_factory=list)
    entry_status: str = "Started"
    eligible: bool = False
    sensors: list[str] = field(default_factory=list)
    values: list[str] = field(default_factory=list)
    labels: list[str] = field(default_factory=list)
    merged: bool = False
    #: Other top-level keys (merged.json's "driving score", "success rate", "eval num", ...), in file order.
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object in the leaderboard's key order (merged files keep only records and their extra keys)."""
        records = [r.to_dict() for r in self.records]
        if self.merged:
            return {"_checkpoint": {"records": records}, **self.extra}
        out: dict[str, Any] = {
            "_checkpoint": {
                "global_record": self.global_record.to_dict() if self.global_record else {},
                "progress": list(self.progress),
                # The leaderboard leaves out the record of a route still in progress (index -1).
                "records": [d for d, r in zip(records, self.records) if r.index != -1],
            },
            "entry_status": self.entry_status,
            "eligible": self.eligible,
            "sensors": list(self.sensors),
            "values": list(self.values),
            "labels": list(self.labels),
        }
        out.update(self.extra)
        return out


def parse_results(data: Any, path: str | Path = "<memory>") -> LeaderboardResults:
    """Interpret decoded JSON as a Leaderboard result; raise ``LeaderboardFormatError`` naming ``path``."""
    hint = "expected Leaderboard checkpoint JSON with '_checkpoint.records' (or a merged.json)"
    if not isinstance(data, dict):
        raise LeaderboardFormatError(path, f"top level is a {type(data).__name__}; {hint}")
    checkpoint = data.get("_checkpoint")
    if not isinstance(checkpoint, dict):
        found = ", ".join(list(data)[:5]) or "nothing"
        raise LeaderboardFormatError(path, f"no '_checkpoint' object (top-level keys: {found}); {hint}")
    raw_records = checkpoint.get("records")
    if not isinstance(raw_records, list):
        raise LeaderboardFormatError(path, f"'_checkpoint.records' is missing or not a list; {hint}")
    records = [RouteRecord.from_dict(r, path, i) for i, r in enumerate(raw_records)]
    merged = "entry_status" not in data and "global_record" not in checkpoint
    known = {"_checkpoint", "entry_status", "eligible", "sensors", "values", "labels"}
    raw_global = checkpoint.get("global_record")
    progress = checkpoint.get("progress", [])
    if not isinstance(progress, list):
        raise LeaderboardFormatError(path, "'_checkpoint.progress' must be a list [done, total]")
    return LeaderboardResults(
        records=records,
        global_record=GlobalRecord.from_dict(raw_global, path) if raw_global else None,
        progress=[int(p) for p in progress],
        entry_status=data.get("entry_status", "Started"),
        eligible=bool(data.get("eligible", False)),
        sensors=list(data.get("sensors", [])),
        values=list(data.get("values", [])),
        labels=list(data.get("labels", [])),
        merged=merged,
        extra={k: v for k, v in data.items() if k not in known},
    )


def read_results(path: str | Path) -> LeaderboardResults:
    """Read a checkpoint or merged JSON file; errors name the file and what is wrong."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise LeaderboardFormatError(path, "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LeaderboardFormatError(path, f"cannot be read as UTF-8 text: {exc}") from None
    if not text.strip():
        raise LeaderboardFormatError(path, "file is empty (a leaderboard run that crashed before its first save?)")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise LeaderboardFormatError(path, f"not JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}") from None
    return parse_results(data, path)


def write_results(results: LeaderboardResults, path: str | Path) -> None:
    """Write a result file as the leaderboard does (``json.dump`` with indent 4, keys in schema order)."""
    Path(path).write_text(json.dumps(results.to_dict(), indent=4), encoding="utf-8")


# ---------------------------------------------------------------------------------------------------------------
# global record (statistics_manager.compute_global_statistics)


def _outside_lanes_km(record: RouteRecord) -> float:
    messages = record.infractions.get(OUTSIDE_ROUTE_LANES, [])
    if not messages:
        return 0.0
    # The leaderboard reads the metres as the 9th space-separated token of the first message.
    return float(messages[0].split(" ")[8]) / 1000


def compute_global_record(records: Sequence[RouteRecord], total_routes: int) -> GlobalRecord:
    """``global_record`` of ``records`` with means over ``total_routes``, exactly as the statistics manager."""
    if total_routes < 1:
        raise ValueError(f"total_routes must be at least 1, got {total_routes}")
    g = GlobalRecord()
    result = STATUS_PERFECT
    for r in records:
        g.scores_mean["score_route"] += r.scores.score_route / total_routes
        g.scores_mean["score_penalty"] += r.scores.score_penalty / total_routes
        g.scores_mean["score_composed"] += r.scores.score_composed / total_routes
        g.total_length += r.meta.route_length
        g.duration_game += r.meta.duration_game
        g.duration_system += r.meta.duration_system
        route_result = STATUS_FAILED if STATUS_FAILED in r.status else r.status
        if route_result == STATUS_FAILED:
            g.exceptions.append([r.route_id, r.index, r.status])
            result = route_result
        elif result == STATUS_PERFECT and route_result != STATUS_PERFECT:
            result = route_result
    for key in g.scores_mean:
        g.scores_mean[key] = round(g.scores_mean[key], ROUND_DIGITS_SCORE)
    g.status = result

    if total_routes == 1:
        g.scores_std_dev = {key: 0 for key in g.scores_std_dev}
    else:
        # Deviations are taken from the already rounded means, as the leaderboard does.
        for r in records:
            values = r.scores.to_dict()
            for key in g.scores_std_dev:
                g.scores_std_dev[key] += math.pow(values[key] - g.scores_mean[key], 2)
        for key in g.scores_std_dev:
            g.scores_std_dev[key] = round(math.sqrt(g.scores_std_dev[key] / float(total_routes - 1)), ROUND_DIGITS)

    km_driven = 0.0
    for r in records:
        km_driven += r.meta.route_length / 1000 * r.scores.score_route / 100
        for key in g.infractions:
            if key == OUTSIDE_ROUTE_LANES:
                g.infractions[key] += _outside_lanes_km(r)
            else:
                g.infractions[key] += len(r.infractions.get(key, []))
    km_driven = max(km_driven, 0.001)
    for key in g.infractions:
        if key != OUTSIDE_ROUTE_LANES:
            g.infractions[key] /= km_driven
        g.infractions[key] = round(g.infractions[key], ROUND_DIGITS)
    return g


def global_values(g: GlobalRecord) -> list[str]:
    """The 15 ``values`` strings matching ``LABELS``."""
    head = [g.scores_mean["score_composed"], g.scores_mean["score_route"], g.scores_mean["score_penalty"]]
    return [str(v) for v in head] + [str(g.infractions[key]) for key in _LABEL_KEYS]


def entry_status_of(records: Iterable[RouteRecord]) -> str:
    """'Crashed' / 'Rejected' when a route says so, else 'Finished' (statistics manager rule)."""
    status = "Finished"
    for r in records:
        if "Simulation crashed" in r.status:
            status = "Crashed"
        elif "Agent's sensors were invalid" in r.status:
            status = "Rejected"
    return status


def finalize(results: LeaderboardResults, total_routes: int) -> None:
    """Fill ``global_record``, ``values``, ``labels``, ``entry_status`` and ``eligible`` from the records."""
    results.global_record = compute_global_record(results.records, total_routes)
    results.values = global_values(results.global_record)
    results.labels = list(LABELS)
    results.entry_status = entry_status_of(results.records)
    results.eligible = ELIGIBLE_VALUES[results.entry_status]
