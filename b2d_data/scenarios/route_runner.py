"""RouteRunner: one leaderboard route, run closed loop on any :class:`~b2d_data.sim.api.Simulator`.

What Bench2Drive's ``leaderboard_evaluator`` + ``ScenarioManager`` + ``RouteScenario`` do for one route, without
CARLA: set the route's weather, spawn the ego (``vehicle.lincoln.mkz_2020``, role ``hero``) 0.5 m above the first
route point facing along the route, start the background traffic along the dense route, build the scenario
manager, then tick at 20 Hz: scenario manager, route criteria, agent, control, optional frame callback. The run
stops one tick after route completion (the behaviour tree's own lag), when a terminating criterion fails (route
deviation, blocked), on route timeout, or when the tick count exceeds 4000 ("Failed - TickRuntime"). An agent
that raises ends the route as "Failed - Agent crashed"; a simulator or scenario error as "Failed - Simulation
crashed" — the route always gets a record. Everything is deterministic for a given simulator seed and ``seed``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from b2d_data.format import leaderboard as lb
from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform
from b2d_data.scenarios import statistics
from b2d_data.scenarios.criteria import CriteriaResult, Infraction, RouteCriteria
from b2d_data.scenarios.framework import ScenarioError
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import FIXED_DELTA_SECONDS, ActorSpec, ScenarioHint, Simulator, Snapshot, VehicleControl

if TYPE_CHECKING:
    from b2d_data.maps import Map
    from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

#: Bench2Drive's hard tick limit (v0.0.2 and later).
MAX_TICKS = 4000
#: The ego spawns this far above the first route point.
SPAWN_HEIGHT = 0.5
#: Look-ahead window of the route index handed to the scenario manager (the leaderboard's ScenarioTriggerer).
ROUTE_INDEX_WINDOW = 5


class RouteFailure(Exception):
    """Raised by an agent (or the ``on_start`` hook) to end the route with a Leaderboard failure message.

    ``failure`` is the text after ``"Failed - "`` in the record's status (``Agent couldn't be set up``, ``Agent's
    sensors were invalid``, ``Agent crashed``, ...); ``detail`` says what happened, for logs and run logs.
    """

    def __init__(self, failure: str, detail: str = "") -> None:
        super().__init__(f"{failure}: {detail}" if detail else failure)
        self.failure = failure
        self.detail = detail


class Agent(Protocol):
    """What drives the ego: the privileged expert, or any policy."""

    def run_step(self, snapshot: Snapshot, hints: Sequence[ScenarioHint]) -> VehicleControl:
        """The ego's control for this tick."""
        ...


class ScenarioManagerLike(Protocol):
    """The part of ``b2d_data.scenarios.framework.ScenarioManager`` the runner uses.

    Optional extra: ``pop_switches() -> list[tuple[str, bool]]`` returning the criteria switch requests
    (``criteria.SWITCH_WRONG_DIRECTION`` / ``SWITCH_ACTOR_BLOCKED``) made since the last call; and
    ``adjust_control(control) -> control``, the ego's control as running scenarios perturb it (ControlLoss).
    """

    @property
    def events(self) -> Sequence[Any]:
        """Scenario criteria events (scenario timeout, yield to emergency vehicle) so far."""
        ...

    def tick(self, snapshot: Snapshot, route_index: int) -> None:
        """Build, trigger, update and end scenarios for this tick."""
        ...

    def hints(self) -> Sequence[ScenarioHint]:
        """What the running scenarios tell the expert."""
        ...

    def cleanup(self, snapshot: Snapshot | None = None) -> None:
        """End every scenario (terminating their criteria on ``snapshot``) and destroy their actors."""
        ...


@dataclass(frozen=True)
class ScenarioSetup:
    """Everything a scenario-manager factory gets: the world, the route, the ego and a seeded generator."""

    sim: Simulator
    map: Map
    route: Route
    dense_route: DenseRoute
    ego_id: int
    rng: np.random.Generator
    #: Leaderboard semantics: a scenario whose actors cannot be spawned is skipped and the route goes on.
    skip_failed_builds: bool = False


ScenarioManagerFactory = Callable[[ScenarioSetup], ScenarioManagerLike]


class NoScenarios:
    """A scenario manager with nothing to run (routes without scenarios, or no scenario framework)."""

    events: list[Any]

    def __init__(self) -> None:
        self.events = []
        self.active: list[Any] = []

    def tick(self, snapshot: Snapshot, route_index: int) -> None:
        """Nothing to do."""

    def hints(self) -> list[ScenarioHint]:
        """No hints."""
        return []

    def cleanup(self, snapshot: Snapshot | None = None) -> None:
        """Nothing to clean."""


def default_scenario_manager(setup: ScenarioSetup) -> ScenarioManagerLike:
    """The scenario framework's ``ScenarioManager`` for the route's scenarios (``NoScenarios`` without any).

    Like the leaderboard, scenarios whose trigger point is not within 2 m and 10° of the route are dropped with
    a warning, and so are scenarios that fail to set up (unknown type, missing road layout): the route is driven
    without them.
    """
    if not setup.route.scenarios:
        return NoScenarios()
    try:
        from b2d_data.scenarios.framework import ScenarioContext, ScenarioError, ScenarioManager, scenario_class
        from b2d_data.scenarios.triggers import trigger_route_index
    except ImportError as exc:
        log.warning("route %s: scenario framework unavailable (%s); running without its %d scenario(s)",
                    setup.route.id, exc, len(setup.route.scenarios))
        return NoScenarios()
    # One generator per scenario, seeded by its XML position, so draws depend neither on timing nor on which
    # other scenarios were dropped.
    seeds = np.random.SeedSequence(int(setup.rng.integers(2**63))).spawn(len(setup.route.scenarios))
    seed_of = {id(config): seed for config, seed in zip(setup.route.scenarios, seeds)}

    def context(config: Any) -> Any:
        return ScenarioContext(sim=setup.sim, map=setup.map, route=setup.dense_route, config=config,
                               rng=np.random.default_rng(seed_of[id(config)]), ego_id=setup.ego_id)

    configs = []
    # Dropped scenarios go into the manager's ``skipped`` like those whose build fails, so the record says why.
    dropped: list[tuple[str, str]] = []
    for config in setup.route.scenarios:
        if trigger_route_index(setup.dense_route, config.trigger_point) is None:
            log.warning("route %s: ignoring scenario %r, its trigger point is too far from the route",
                        setup.route.id, config.name)
            dropped.append((config.name, "its trigger point is not within 2 m and 10 degrees of the route"))
            continue
        try:
            scenario_class(config.type)(context(config))  # set-up check only; the manager makes its own
        except ScenarioError as exc:
            log.warning("route %s: skipping scenario %r due to a setup error: %s", setup.route.id, config.name, exc)
            dropped.append((config.name, str(exc)))
            continue
        configs.append(config)
    manager = ScenarioManager(context, configs, skip_failed_builds=setup.skip_failed_builds)
    manager.skipped.extend(dropped)
    return manager


@dataclass(frozen=True)
class TickInfo:
    """What the frame callback gets besides the snapshot."""

    #: Ticks since the route started (1 for the first).
    tick: int
    #: Index of this recorded frame (0 for the first).
    frame_index: int
    ego_id: int
    #: The ego's closest dense-route point.
    route_index: int
    #: The control the agent returned for this tick.
    control: VehicleControl
    hints: tuple[ScenarioHint, ...]
    #: Route completion so far (percent).
    score_route: float
    #: Infraction events so far (route criteria only; scenario events arrive at the end).
    num_events: int


@dataclass
class RouteResult:
    """A finished route: its Leaderboard record, Bench2Drive success, ticks run, frames recorded, game time."""

    record: lb.RouteRecord
    success: bool
    ticks: int
    frames: int
    duration_game: float
    criteria: CriteriaResult | None = None
    #: Why the loop ended: ``completed``, a failure message (``TickRuntime``, ``Agent crashed``, ...).
    stop_reason: str = ""
    events: tuple[Infraction, ...] = field(default_factory=tuple)
    #: What went wrong when a scenario could not be set up (empty otherwise).
    detail: str = ""
    #: ``(scenario name, reason)`` of scenarios skipped because they could not be built (``skip_failed_scenarios``).
    skipped_scenarios: tuple[tuple[str, str], ...] = ()


class RouteRunner:
    """Runs one route of a route XML file on a simulator with an agent and scores it as Bench2Drive does."""

    def __init__(
        self,
        sim: Simulator,
        route: Route,
        agent: Agent,
        seed: int = 0,
        record_every: int = 2,
        on_frame: Callable[[Snapshot, TickInfo], None] | None = None,
        scenario_manager_factory: ScenarioManagerFactory | None = None,
        max_ticks: int = MAX_TICKS,
        dense_route: DenseRoute | None = None,
        index: int = 0,
        repetition: int = 0,
        on_start: Callable[[int], None] | None = None,
        skip_failed_scenarios: bool = False,
    ) -> None:
        if record_every < 1:
            raise ValueError(f"record_every must be at least 1, got {record_every}")
        self.sim = sim
        self.route = route
        self.agent = agent
        self.seed = int(seed)
        self.record_every = record_every
        self.on_frame = on_frame
        self.scenario_manager_factory = scenario_manager_factory or default_scenario_manager
        self.max_ticks = max_ticks
        self.index = index
        self.repetition = repetition
        self.on_start = on_start
        self.skip_failed_scenarios = skip_failed_scenarios
        self.dense_route = dense_route if dense_route is not None else DenseRoute.from_route(sim.map, route)

    # ------------------------------------------------------------------------------------------------ set-up

    def spawn_transform(self) -> Transform:
        """The ego's spawn pose: the first route point's transform, 0.5 m higher."""
        first = self.dense_route.waypoints[0].transform
        loc = first.location
        return Transform(Location(loc.x, loc.y, loc.z + SPAWN_HEIGHT), first.rotation)

    def _spawn_ego(self) -> int:
        return self.sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), self.spawn_transform())

    def _update_weather(self, route_index: int, last: float) -> float:
        """Route weathers with several entries change with the route percentage (RouteWeatherBehavior)."""
        if len(self.route.weathers) < 2:
            return last
        percentage = self.dense_route.percentage(route_index)
        if percentage != last:
            self.sim.set_weather(self.route.weather_at(percentage))
        return percentage

    # ------------------------------------------------------------------------------------------------ the run

    def run(self) -> RouteResult:
        """Run the route to its end and build its record."""
        wall_start = time.monotonic()
        sim, dense = self.sim, self.dense_route
        sim.set_weather(self.route.weather_at(0.0))
        try:
            ego_id = self._spawn_ego()
        except Exception:
            # The leaderboard records a route whose ego cannot be spawned as a simulation crash.
            log.exception("route %s: the ego could not be spawned", self.route.id)
            record = statistics.route_record(
                self.route, CriteriaResult(0.0, ()), dense.total_length, 0.0, time.monotonic() - wall_start,
                failure_message=statistics.SIMULATION_CRASHED_FAILURE, index=self.index, repetition=self.repetition,
            )
            return RouteResult(record=record, success=False, ticks=0, frames=0, duration_game=0.0,
                               stop_reason=statistics.SIMULATION_CRASHED_FAILURE)
        log.info("route %s on %s: %d route points, %.1f m, ego %d", self.route.id, self.route.town, len(dense),
                 dense.total_length, ego_id)
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, self.repetition]))
        criteria = RouteCriteria(sim.map, dense, ego_id)
        manager: ScenarioManagerLike = NoScenarios()
        background_started = False
        ticks = frames = 0
        failure = ""
        stop_reason = ""
        detail = ""
        snapshot: Snapshot | None = None
        try:
            if self.on_start is not None:
                # The caller's own hook (mounting the rig, setting up an agent): its errors propagate, except a
                # RouteFailure, which ends the route with that failure (an agent that cannot be set up).
                try:
                    self.on_start(ego_id)
                except RouteFailure as exc:
                    log.error("route %s: %s", self.route.id, exc)
                    failure = stop_reason = exc.failure
                    detail = exc.detail
            if not failure:
                try:
                    sim.background.start(ego_id, list(dense.waypoints))
                    background_started = True
                    manager = self.scenario_manager_factory(
                        ScenarioSetup(sim, sim.map, self.route, dense, ego_id, rng, self.skip_failed_scenarios)
                    )
                    # Build (and trigger) what is due at the start before the first tick, so that the agent's
                    # first step already sees it (ParkingExit moves the ego into the parking lane at the start).
                    manager.tick(sim.snapshot(), 0)
                except Exception:
                    log.exception("route %s: starting background traffic or scenarios failed", self.route.id)
                    failure = stop_reason = statistics.SIMULATION_CRASHED_FAILURE
            route_index = 0
            weather_percentage = 0.0
            while not failure:
                try:
                    snapshot = sim.tick()
                except Exception:
                    log.exception("route %s: the simulator failed at tick %d", self.route.id, ticks + 1)
                    failure = stop_reason = statistics.SIMULATION_CRASHED_FAILURE
                    break
                ticks += 1
                if ticks > self.max_ticks:
                    log.info("route %s: tick limit %d exceeded", self.route.id, self.max_ticks)
                    failure = stop_reason = statistics.TICK_RUNTIME_FAILURE
                    break
                ego = snapshot.actors.get(ego_id)
                if ego is None:
                    log.error("route %s: the ego (actor %d) vanished at tick %d", self.route.id, ego_id, ticks)
                    failure = stop_reason = statistics.SIMULATION_CRASHED_FAILURE
                    break
                route_index = dense.closest_index(ego.location, route_index, ROUTE_INDEX_WINDOW, planar=False)
                weather_percentage = self._update_weather(route_index, weather_percentage)
                try:
                    manager.tick(snapshot, route_index)
                    pop_switches = getattr(manager, "pop_switches", None)
                    for name, active in (pop_switches() if pop_switches is not None else ()):
                        criteria.switch(name, active)
                    hints = tuple(manager.hints())
                except ScenarioError as exc:
                    # the route's layout does not suit its scenario: a reason for the run log, not a traceback
                    log.error("route %s: scenario set-up failed at tick %d: %s", self.route.id, ticks, exc)
                    detail = str(exc)
                    failure = stop_reason = statistics.SIMULATION_CRASHED_FAILURE
                    break
                except Exception:
                    log.exception("route %s: the scenario manager failed at tick %d", self.route.id, ticks)
                    failure = stop_reason = statistics.SIMULATION_CRASHED_FAILURE
                    break
                criteria.update(snapshot, ego, route_index)
                try:
                    control = self.agent.run_step(snapshot, hints)
                except RouteFailure as exc:
                    log.error("route %s: tick %d: %s", self.route.id, ticks, exc)
                    failure = stop_reason = exc.failure
                    detail = exc.detail
                    break
                except Exception:
                    log.exception("route %s: the agent crashed at tick %d", self.route.id, ticks)
                    failure = stop_reason = statistics.AGENT_CRASHED_FAILURE
                    break
                # scenarios may perturb what the ego executes (ControlLoss); the recorded action stays the agent's
                adjust = getattr(manager, "adjust_control", None)
                sim.apply_control(ego_id, adjust(control) if adjust is not None else control)
                if self.on_frame is not None and (ticks - 1) % self.record_every == 0:
                    info = TickInfo(ticks, frames, ego_id, route_index, control, hints, criteria.score_route,
                                    len(criteria.events))
                    self.on_frame(snapshot, info)
                    frames += 1
                reason = criteria.stop_reason
                if reason is not None:
                    stop_reason = reason
                    break
        finally:
            if snapshot is not None:
                criteria.terminate(snapshot)
            scenario_events = self._cleanup(manager, snapshot, ego_id, background_started)
        criteria.add_scenario_events(scenario_events, snapshot.frame if snapshot is not None else 0)
        result = criteria.result()
        duration_game = ticks * FIXED_DELTA_SECONDS
        record = statistics.route_record(
            self.route, result, dense.total_length, duration_game, time.monotonic() - wall_start,
            failure_message=failure, index=self.index, repetition=self.repetition,
        )
        return RouteResult(record=record, success=record.success, ticks=ticks, frames=frames,
                           duration_game=round(duration_game, lb.ROUND_DIGITS), criteria=result,
                           stop_reason=stop_reason, events=result.events, detail=detail,
                           skipped_scenarios=tuple(getattr(manager, "skipped", ())))  # fmt: skip

    def _cleanup(self, manager: ScenarioManagerLike, snapshot: Snapshot | None, ego_id: int,
                 background_started: bool) -> list[Any]:
        """End the scenarios (their criteria report now), stop the background, remove the ego; never raises."""
        try:
            manager.cleanup(snapshot)
        except Exception:
            log.exception("route %s: scenario cleanup failed", self.route.id)
        events: list[Any] = []
        try:
            events = list(manager.events)
        except Exception:
            log.exception("route %s: cannot read the scenario criteria events", self.route.id)
        if background_started:
            try:
                self.sim.background.stop()
            except Exception:
                log.exception("route %s: stopping the background traffic failed", self.route.id)
        try:
            self.sim.destroy_actor(ego_id)
        except Exception:
            log.exception("route %s: destroying the ego failed", self.route.id)
        return events


def run_route(sim: Simulator, route: Route, agent: Agent, **kwargs: Any) -> RouteResult:
    """Shortcut: ``RouteRunner(sim, route, agent, **kwargs).run()``."""
    return RouteRunner(sim, route, agent, **kwargs).run()

