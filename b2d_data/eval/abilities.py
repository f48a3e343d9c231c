"""The five Bench2Drive abilities (tools/ability_benchmark.py of v0.0.4, format.md §8.5).

Each route of the route XML is classified by the type of its first scenario; a scenario type may
belong to several abilities (``b2d_data.format.scenario_types``). A route counts once in the denominator
of each of its abilities and in the numerator when it succeeded. Routes without a record are listed as
``crashed`` and left out of every denominator (unlike driving score and success rate).

Traffic_Signs extra credit: a *failed* route of a Traffic_Signs type still earns a Traffic_Signs success
(numerator only) when it ran no red light and no stop sign and got past its first junction, i.e.
``score_route / 100 > (c + 8) / n`` where ``n`` is the number of waypoints of the route densified at 1 m
and ``c`` the 1-based index of the first junction waypoint. Finding ``c`` and ``n`` needs the town's map,
so it goes through a pluggable junction provider; routes it cannot serve are reported, not guessed.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from b2d_data.format.leaderboard import RED_LIGHT, STOP_INFRACTION, RouteRecord
from b2d_data.format.scenario_types import Ability, abilities_of
from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

#: Abilities in the order Bench2Drive reports them.
ABILITIES: tuple[Ability, ...] = (
    Ability.OVERTAKING,
    Ability.MERGING,
    Ability.EMERGENCY_BRAKE,
    Ability.GIVE_WAY,
    Ability.TRAFFIC_SIGNS,
)

#: Waypoints past the first junction waypoint the ego must have covered ("to pass the trigger volume").
JUNCTION_MARGIN = 8


@dataclass(frozen=True)
class JunctionLookup:
    """Where a route first enters a junction on its 1 m densified waypoint list."""

    #: 1-based index of the first junction waypoint, None when the route never enters a junction.
    first_junction: int | None
    #: Number of waypoints of the densified route.
    num_waypoints: int


#: Why a route's Traffic_Signs credit could not be checked (``TrafficSignCheck.unchecked_kind``).
NO_PROVIDER = "no junction provider"
MAP_MISSING = "town map missing"
MAP_UNUSABLE = "map could not be used"


class JunctionUnavailable(Exception):
    """A junction provider cannot serve a route; the message says why, ``kind`` groups the reasons."""

    def __init__(self, message: str, kind: str = MAP_UNUSABLE) -> None:
        super().__init__(message)
        self.kind = kind


#: Route → its junction lookup; may return None or raise ``JunctionUnavailable`` when it cannot tell.
JunctionProvider = Callable[[Route], "JunctionLookup | None"]


@dataclass(frozen=True)
class TrafficSignCheck:
    """The extra-credit check of one failed Traffic_Signs route."""

    route_id: str
    scenario_type: str
    town: str
    score_route: float
    credited: bool
    #: Why the route did or did not get the credit, or why it could not be checked.
    reason: str
    checked: bool = True
    #: For unchecked routes: NO_PROVIDER, MAP_MISSING or MAP_UNUSABLE.
    unchecked_kind: str | None = None
    first_junction: int | None = None
    num_waypoints: int | None = None

    @property
    def threshold(self) -> float | None:
        """Completion fraction the route had to exceed, ``(c + 8) / n``."""
        if self.first_junction is None or not self.num_waypoints:
            return None
        return (self.first_junction + JUNCTION_MARGIN) / self.num_waypoints


@dataclass(frozen=True)
class AbilityScore:
    """One ability: successes (Traffic_Signs credit included) over evaluated routes."""

    ability: Ability
    successes: int
    routes: int
    #: Traffic_Signs extra credits included in ``successes``.
    credited: int = 0
    #: Routes of this ability in the route XML (the denominator when every route has a record).
    routes_in_xml: int = 0

    @property
    def value(self) -> float | None:
        """Success percentage, None when no route of this ability was evaluated."""
        return 100.0 * self.successes / self.routes if self.routes else None


@dataclass
class AbilityResult:
    """The five abilities, their mean, and what the computation could not cover."""

    scores: dict[Ability, AbilityScore]
    #: (scenario type, route id) of routes without a record, in the order Bench2Drive lists them.
    crashed: list[tuple[str | None, str]] = field(default_factory=list)
    traffic_sign_checks: list[TrafficSignCheck] = field(default_factory=list)

    @property
    def mean(self) -> float | None:
        """Mean of the abilities that have routes (Bench2Drive divides by 5; with all 5 defined it is the same)."""
        values = [s.value for s in self.scores.values() if s.value is not None]
        return sum(values) / len(values) if values else None

    @property
    def unchecked(self) -> list[TrafficSignCheck]:
        """Failed Traffic_Signs routes whose credit could not be checked."""
        return [c for c in self.traffic_sign_checks if not c.checked]


def first_junction_lookup(is_junction: Sequence[bool]) -> JunctionLookup:
    """Lookup from the junction flags of a densified route (1-based index of the first True)."""
    for index, flag in enumerate(is_junction, start=1):
        if flag:
            return JunctionLookup(first_junction=index, num_waypoints=len(is_junction))
    return JunctionLookup(first_junction=None, num_waypoints=len(is_junction))


def _check_traffic_signs(
    route: Route, scenario: str, record: RouteRecord, junctions: JunctionProvider | None
) -> TrafficSignCheck:
    base = {
        "route_id": route.id,
        "scenario_type": scenario,
        "town": route.town,
        "score_route": record.scores.score_route,
    }
    if record.infractions.get(RED_LIGHT) or record.infractions.get(STOP_INFRACTION):
        # Decided without the map: a red-light or stop infraction rules the credit out.
        return TrafficSignCheck(**base, credited=False, reason="ran a red light or a stop sign")
    unchecked = {"credited": False, "checked": False}
    if junctions is None:
        reason = "no junction provider (no --maps-dir)"
        return TrafficSignCheck(**base, **unchecked, reason=reason, unchecked_kind=NO_PROVIDER)
    try:
        lookup = junctions(route)
    except JunctionUnavailable as exc:
        return TrafficSignCheck(**base, **unchecked, reason=str(exc), unchecked_kind=exc.kind)
    if lookup is None:
        reason = "junction provider has no data for this route"
        return TrafficSignCheck(**base, **unchecked, reason=reason, unchecked_kind=MAP_UNUSABLE)
    if lookup.first_junction is None or lookup.num_waypoints == 0:
        return TrafficSignCheck(
            **base, credited=False, reason="densified route has no junction waypoint",
            first_junction=None, num_waypoints=lookup.num_waypoints,
        )  # fmt: skip
    needed = (lookup.first_junction + JUNCTION_MARGIN) / lookup.num_waypoints
    credited = record.scores.score_route / 100.0 > needed
    reason = (
        f"completion {record.scores.score_route / 100.0:.4f} {'>' if credited else '<='} "
        f"({lookup.first_junction}+{JUNCTION_MARGIN})/{lookup.num_waypoints} = {needed:.4f}"
    )
    return TrafficSignCheck(
        **base, credited=credited, reason=reason,
        first_junction=lookup.first_junction, num_waypoints=lookup.num_waypoints,
    )  # fmt: skip


def compute_abilities(
    records: Sequence[RouteRecord], routes: Sequence[Route], junctions: JunctionProvider | None = None
) -> AbilityResult:
    """Ability success rates of ``records`` on ``routes`` (records are matched by XML route id; each repetition of
    a route counts as one run of it)."""
    by_id: dict[str, list[RouteRecord]] = {}
    for r in records:
        by_id.setdefault(r.route_number, []).append(r)
    successes = {a: 0 for a in ABILITIES}
    totals = {a: 0 for a in ABILITIES}
    in_xml = {a: 0 for a in ABILITIES}
    credited = 0
    crashed: list[tuple[str | None, str]] = []
    checks: list[TrafficSignCheck] = []
    # Bench2Drive walks the routes sorted by town (stable), which orders its crashed list.
    for route in sorted(routes, key=lambda r: r.town):
        scenario = route.scenario_type
        abilities = abilities_of(scenario) if scenario else ()
        for ability in abilities:
            in_xml[ability] += 1
        runs = by_id.get(route.id)
        if not runs:
            crashed.append((scenario, route.id))
            continue
        for record in runs:
            success = record.success
            for ability in abilities:
                totals[ability] += 1
                successes[ability] += int(success)
            if Ability.TRAFFIC_SIGNS in abilities and not success:
                check = _check_traffic_signs(route, scenario or "", record, junctions)
                checks.append(check)
                if check.credited:
                    successes[Ability.TRAFFIC_SIGNS] += 1
                    credited += 1
    scores = {
        a: AbilityScore(
            ability=a,
            successes=successes[a],
            routes=totals[a],
            credited=credited if a is Ability.TRAFFIC_SIGNS else 0,
            routes_in_xml=in_xml[a],
        )
        for a in ABILITIES
    }
    unchecked = [c for c in checks if not c.checked]
    if unchecked:
        log.warning("Traffic_Signs credit not checked for %d failed route(s): %s", len(unchecked), unchecked[0].reason)
    return AbilityResult(scores=scores, crashed=crashed, traffic_sign_checks=checks)
