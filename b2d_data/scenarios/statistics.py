"""Per-route statistics: criteria results → a Leaderboard ``RouteRecord``, as Bench2Drive's statistics manager.

``statistics_manager.compute_route_statistics`` (Bench2Drive fork): the route timeout adds ``"Route timeout."``
and the failure "Agent timed out"; then every criterion event, in criteria order, either multiplies the penalty
(fixed factors; outside route lanes by (1 − pct/100); min speed not at all) or names the failure (route
deviation, blocked — the later one wins); route completion gives ``score_route``, and ``score_route >= 100``
means the target was reached. ``num_infractions`` counts every message, min speed included, so a finished
Bench2Drive route is practically always "Completed", never "Perfect".
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from datetime import datetime

from b2d_data.format import leaderboard as lb
from b2d_data.scenarios.criteria import CriteriaResult
from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

#: Failure messages the criteria set, in the order the statistics manager lets them override each other.
ROUTE_TIMEOUT_FAILURE = "Agent timed out"
ROUTE_DEVIATION_FAILURE = "Agent deviated from the route"
BLOCKED_FAILURE = "Agent got blocked"
TICK_RUNTIME_FAILURE = "TickRuntime"
AGENT_CRASHED_FAILURE = "Agent crashed"
SIMULATION_CRASHED_FAILURE = "Simulation crashed"


def scenario_name_of(route: Route) -> str | None:
    """The record's ``scenario_name``: the XML ``name`` of the route's first scenario (None without one)."""
    return route.scenarios[0].name if route.scenarios else None


def weather_id_of_route(route: Route) -> str | None:
    """The record's ``weather_id``: the weather.xml id of the route's first weather, as a string, or None."""
    weather_id = route.weather_id
    return None if weather_id is None else str(weather_id)


def route_record(
    route: Route,
    result: CriteriaResult,
    route_length: float,
    duration_game: float,
    duration_system: float,
    failure_message: str = "",
    index: int = 0,
    repetition: int = 0,
    town_name: str | None = None,
    when: datetime | None = None,
) -> lb.RouteRecord:
    """The checkpoint record of one finished route.

    ``failure_message`` is what stopped the run from outside the criteria (``TickRuntime``, ``Agent crashed``,
    ``Simulation crashed``); the criteria's own failures override it, as in the leaderboard. ``when`` fixes the
    time stamp of ``save_name`` (now by default).
    """
    record_id = lb.record_route_id(route.id, repetition)
    scenario_name = scenario_name_of(route)
    weather_id = weather_id_of_route(route)
    town = town_name if town_name is not None else route.town
    save_name = lb.make_save_name(record_id, town, str(scenario_name), weather_id, when or datetime.now())

    infractions = lb.empty_infractions()
    penalties: list[tuple[str, float | None]] = []
    failure = failure_message
    if result.route_timeout:
        infractions[lb.ROUTE_TIMEOUT].append(lb.route_timeout_message())
        failure = ROUTE_TIMEOUT_FAILURE
    for event in result.events:
        key = event.key
        if key in lb.PENALTY_FACTORS:
            penalties.append((key, None))
        elif key in lb.PERCENTAGE_PENALTIES:
            if event.percentage is None:
                raise ValueError(f"{key} event without its percentage: {event.message!r}")
            penalties.append((key, event.percentage))
        elif key == lb.ROUTE_DEV:
            failure = ROUTE_DEVIATION_FAILURE
        elif key == lb.VEHICLE_BLOCKED:
            failure = BLOCKED_FAILURE
        elif key != lb.ROUTE_TIMEOUT:
            raise ValueError(f"unknown infraction key {key!r} in route {route.id}")
        infractions[key].append(event.message)

    penalty = lb.score_penalty(penalties)
    num_infractions = sum(len(messages) for messages in infractions.values())
    status = lb.route_status(result.target_reached, num_infractions, failure)
    record = lb.RouteRecord(
        route_id=record_id,
        scenario_name=scenario_name,
        weather_id=weather_id,
        save_name=save_name,
        status=status,
        num_infractions=num_infractions,
        infractions=infractions,
        scores=lb.Scores.compose(result.score_route, penalty),
        meta=lb.RouteMeta(
            round(route_length, lb.ROUND_DIGITS),
            round(duration_game, lb.ROUND_DIGITS),
            round(duration_system, lb.ROUND_DIGITS),
        ),
        town_name=town,
        index=index,
    )
    log.info("%s: %s, route %.2f %%, penalty %.4f, %d infraction messages", record_id, status,
             record.scores.score_route, record.scores.score_penalty, num_infractions)
    return record


def checkpoint_results(
    records: Sequence[lb.RouteRecord], total_routes: int | None = None, sensors: Sequence[str] = ()
) -> lb.LeaderboardResults:
    """A checkpoint file's content for finished records: progress, global record, values, labels, entry status."""
    total = len(records) if total_routes is None else total_routes
    results = lb.LeaderboardResults(records=list(records), progress=[len(records), total], sensors=list(sensors))
    lb.finalize(results, max(total, 1))
    return results
