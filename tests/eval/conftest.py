"""A synthetic evaluation run, small enough to work out every figure by hand.

Eight routes (ids 101–108) in a route XML, seven records spread over two per-process files (route 107
never ran), min-speed messages for efficiency and metric_info.json files for smoothness. The expected
values are derived in the tests that use them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pytest

from b2d_data.eval.abilities import MAP_MISSING, JunctionLookup, JunctionUnavailable
from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.scenarios.route_xml import Route, ScenarioConfig, write_routes

#: route id → (scenario type, town)
ROUTES: dict[str, tuple[str, str]] = {
    "101": ("Accident", "Town01"),  # Overtaking
    "102": ("ParkingCutIn", "Town01"),  # Emergency_Brake
    "103": ("SignalizedJunctionLeftTurn", "Town01"),  # Merging + Traffic_Signs
    "104": ("T_Junction", "Town02"),  # Traffic_Signs
    "105": ("VanillaSignalizedTurnEncounterRedLight", "Town02"),  # Traffic_Signs
    "106": ("YieldToEmergencyVehicle", "Town02"),  # Give_Way
    "107": ("InvadingTurn", "Town03"),  # Give_Way, never ran
    "108": ("BlockedIntersection", "Town99"),  # Emergency_Brake + Traffic_Signs, no map anywhere
}


def _route(route_id: str) -> Route:
    scenario, town = ROUTES[route_id]
    x0 = float(route_id)
    trigger = Transform(Location(x0, 0.0, 0.0), Rotation(yaw=90.0))
    return Route(
        id=route_id,
        town=town,
        waypoints=(Location(x0, 0.0, 0.0), Location(x0, 2.0, 0.0), Location(x0, 4.0, 0.0)),
        scenarios=(ScenarioConfig(f"{scenario}_1", scenario, trigger, {"direction": {"value": "left"}}),),
    )


def _record(
    route_id: str,
    status: str,
    score_route: float,
    infractions: dict[str, list[str]] | None = None,
    index: int = 0,
) -> lb.RouteRecord:
    scenario, town = ROUTES[route_id]
    record = lb.RouteRecord(
        route_id=lb.record_route_id(route_id),
        scenario_name=f"{scenario}_1",
        weather_id="1",
        save_name=f"{lb.record_route_id(route_id)}_{town}_{scenario}_1_1_01_02_03_04_05",
        town_name=town,
        index=index,
    )
    penalty_events = []
    for key, messages in (infractions or {}).items():
        for message in messages:
            record.add_infraction(key, message)
            penalty_events.append((key, None))
    record.status = status
    record.scores = lb.Scores.compose(score_route, lb.score_penalty(penalty_events))
    record.meta = lb.RouteMeta(route_length=100.0, duration_game=20.0, duration_system=60.0)
    return record


def _speed(*values: float | int) -> dict[str, list[str]]:
    return {lb.MIN_SPEED_INFRACTIONS: [lb.min_speed_message(v) for v in values]}


def synthetic_records() -> dict[str, lb.RouteRecord]:
    """The seven records, keyed by route id (see the test modules for what each one exercises)."""
    at = Location(1.0, 2.0, 0.0)
    return {
        "101": _record("101", "Completed", 100, _speed(80.0, 120.0)),
        "102": _record("102", "Completed", 100, _speed(50.0, 1500.0)),
        "103": _record("103", "Failed - Agent got blocked", 60, {lb.VEHICLE_BLOCKED: [lb.blocked_message(at)]}),
        "104": _record("104", "Failed - TickRuntime", 20),
        "105": _record("105", "Completed", 100, {lb.RED_LIGHT: [lb.red_light_message(7, at)]}),
        "106": _record("106", "Completed", 100, _speed(100)),
        "108": _record("108", "Failed - TickRuntime", 50),
    }


def write_checkpoint(path: Path, records: list[lb.RouteRecord], total: int) -> Path:
    """A per-process checkpoint file as the leaderboard leaves it at the end of its routes."""
    for i, record in enumerate(records):
        record.index = i
    results = lb.LeaderboardResults(records=records, progress=[len(records), total], sensors=["carla_camera"])
    lb.finalize(results, total)
    lb.write_results(results, path)
    return path


# Motion of one step: (acceleration x, angular velocity z in deg/s); forward is +x, right is +y.
def _steps(n: int, acc_x: float | list[float], yaw_rate_deg: float = 0.0) -> list[tuple[float, float]]:
    accs = acc_x if isinstance(acc_x, list) else [acc_x] * n
    return [(a, yaw_rate_deg) for a in accs]


def metric_steps() -> dict[str, list[tuple[float, float]]]:
    """Per route id, the steps written to its metric_info.json."""
    return {
        # 45 steps: chunk [0, 20) calm, chunk [20, 40) too strong a forward acceleration, 5 dropped wild steps.
        "101": _steps(20, 1.0) + _steps(20, 3.0) + _steps(5, 50.0, 500.0),
        # 40 steps: chunk [0, 20) a ramp from −4.0 by 0.21 per step, chunk [20, 40) a 0.5 deg/s turn.
        "102": _steps(20, [-4.0 + 0.21 * k for k in range(20)]) + _steps(20, 0.5, 0.5),
        # 15 steps (a single whole-episode chunk): a steady 30 deg/s turn.
        "106": _steps(15, 0.5, 30.0),
    }


def write_metric_info(path: Path, steps: list[tuple[float, float]]) -> None:
    """One metric_info.json in the Zoo agents' layout (object keyed by step)."""
    data = {
        str(i): {
            "acceleration": [acc, 0.0, 0.0],
            "angular_velocity": [0.0, 0.0, yaw],
            "forward_vector": [1.0, 0.0, 0.0],
            "right_vector": [0.0, 1.0, 0.0],
            "location": [0.1 * i, 0.0, 0.0],
            "rotation": [0.0, 0.0, 0.0],
        }
        for i, (acc, yaw) in enumerate(steps)
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=4))


@dataclass
class SyntheticRun:
    """Paths of the synthetic run on disk."""

    routes_file: Path
    run_dir: Path
    files: list[Path]
    metric_dir: Path
    records: dict[str, lb.RouteRecord]


class HandJunctions:
    """A junction provider with hand-set answers: routes 103 and 104 enter a junction at waypoint 20 of 100."""

    def __init__(self) -> None:
        self.calls: list[str] = []

    def __call__(self, route: Route) -> JunctionLookup:
        self.calls.append(route.id)
        if route.id in ("103", "104"):
            return JunctionLookup(first_junction=20, num_waypoints=100)
        raise JunctionUnavailable(f"map of {route.town} missing", MAP_MISSING)


@pytest.fixture
def hand_junctions() -> HandJunctions:
    """The hand-set junction provider (records which routes it was asked about)."""
    return HandJunctions()


@pytest.fixture
def synthetic_run(tmp_path: Path) -> SyntheticRun:
    """Route XML, two per-process result files and a metric folder under ``tmp_path``."""
    routes_file = tmp_path / "routes8.xml"
    write_routes([_route(rid) for rid in ROUTES], routes_file)
    records = synthetic_records()
    run_dir = tmp_path / "agent_run"
    run_dir.mkdir()
    first = write_checkpoint(run_dir / "eval_0.json", [records[r] for r in ("101", "102", "103", "104")], 4)
    second = write_checkpoint(run_dir / "eval_1.json", [records[r] for r in ("105", "106", "108")], 4)
    metric_dir = tmp_path / "metrics"
    for route_id, steps in metric_steps().items():
        write_metric_info(metric_dir / str(records[route_id].save_name) / "metric_info.json", steps)
    return SyntheticRun(routes_file, run_dir, [first, second], metric_dir, records)


@pytest.fixture
def perfect_run(tmp_path: Path) -> Path:
    """A merged.json-style file where all eight routes succeed (a second column to compare with)."""
    records = []
    for route_id in ROUTES:
        record = _record(route_id, "Completed", 100, _speed(100.0))
        record.index = None
        records.append(record)
    path = tmp_path / "perfect" / "merged_perfect.json"
    path.parent.mkdir()
    results = lb.LeaderboardResults(records=records, merged=True, extra={"driving score": 100.0})
    lb.write_results(results, path)
    return path
