"""The scenario manager's life cycle, the scenario criteria and the registry, with a recording test scenario."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.road_geometry import heading_change, lane_walk
from b2d_data.scenarios.criteria import SWITCH_ACTOR_BLOCKED, SWITCH_WRONG_DIRECTION, RouteCriteria
from b2d_data.scenarios.framework import (
    SCENARIO_CLASSES,
    Scenario,
    ScenarioContext,
    ScenarioManager,
    ScenarioSetupError,
    ScenarioStatus,
    UnknownScenarioError,
    YieldToEmergencyVehicleTest,
    scenario_class,
)
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import ScenarioConfig
from b2d_data.sim.api import ActorKind, ActorState, ScenarioHint, Snapshot

EGO = 1


def vehicle(actor_id: int, x: float, y: float, yaw: float = 0.0) -> ActorState:
    return ActorState(
        id=actor_id, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
        transform=Transform(Location(x, y, 0.0), Rotation(yaw=yaw)), velocity=Vector3D(),
        angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.45, 1.06, 0.75)), semantic_tags=(14,),
        role_name="hero" if actor_id == EGO else "scenario",
    )  # fmt: skip


def snap(t: float, *actors: ActorState) -> Snapshot:
    return Snapshot(frame=round(t / 0.05), timestamp=t, actors={a.id: a for a in actors}, traffic_lights={},
                    traffic_signs={}, collisions=(), weather=ROUTE_DEFAULT)  # fmt: skip


@pytest.fixture(scope="module")
def route(tmp_path_factory) -> DenseRoute:
    """A straight 120 m junction-free stretch of the generated town as a dense route."""
    town = load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))
    for wp in town.generate_waypoints(20.0):
        lane = lane_walk(wp, 120.0)
        if len(lane) > 120 and not any(w.is_junction for w in lane) and heading_change(lane) < 1.0:
            return DenseRoute.from_pairs([(w, RoadOption.LANEFOLLOW) for w in lane], town)
    pytest.fail("no straight 120 m lane in the generated town")


class Recorder(Scenario):
    """Records the calls it gets; ends when told to."""

    xml_type = "RecorderForTests"

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.calls: list[str] = []
        self.finish = False

    def build(self) -> None:
        self.calls.append("build")

    def start(self, snapshot: Snapshot) -> None:
        self.calls.append("start")
        self.request_switch(SWITCH_WRONG_DIRECTION, False)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        self.calls.append("update")
        return ScenarioStatus.SUCCESS if self.finish else ScenarioStatus.RUNNING

    def hint(self) -> ScenarioHint | None:
        return ScenarioHint(self.xml_type, 7, 8)

    def on_end(self) -> None:
        self.calls.append("end")


def config_at(route: DenseRoute, index: int, yaw_offset: float = 0.0, lateral: float = 0.0) -> ScenarioConfig:
    t = route.waypoints[index].transform
    loc = Location(t.location.x, t.location.y + lateral, t.location.z)
    return ScenarioConfig(
        "RecorderForTests_1", "RecorderForTests", Transform(loc, Rotation(yaw=t.rotation.yaw + yaw_offset))
    )


def make_manager(route: DenseRoute, config: ScenarioConfig, monkeypatch) -> tuple[ScenarioManager, Recorder]:
    monkeypatch.setitem(SCENARIO_CLASSES, "RecorderForTests", Recorder)
    made: list[Recorder] = []

    def factory(cfg: ScenarioConfig) -> ScenarioContext:
        return ScenarioContext(sim=None, map=route.waypoints[0].map, route=route, config=cfg,  # type: ignore[arg-type]
                               rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip

    manager = ScenarioManager(factory, [config])
    made.extend(s for s in manager.scenarios if isinstance(s, Recorder))
    return manager, made[0]


def ego_at(route: DenseRoute, index: int, t: float) -> Snapshot:
    x, y, _ = route.locations[index]
    return snap(t, vehicle(EGO, float(x), float(y), route.waypoints[index].transform.rotation.yaw))


def test_life_cycle_build_trigger_update_end(route, monkeypatch):
    trigger = 60
    manager, scenario = make_manager(route, config_at(route, trigger), monkeypatch)
    far = snap(0.0, vehicle(EGO, route.locations[0, 0] + 600.0, route.locations[0, 1]))
    manager.tick(far, 0)
    assert scenario.calls == [] and manager.hints() == []  # more than 500 m away: not built
    manager.tick(ego_at(route, 0, 0.05), 0)
    assert scenario.calls == ["build"] and manager.hints() == [ScenarioHint("RecorderForTests", 7, 8)]
    s = route.cumulative_length
    before = int(np.searchsorted(s, s[trigger] - 2.5, side="right")) - 1  # more than 2.5 m before the trigger
    manager.tick(ego_at(route, before, 0.10), before)
    assert scenario.calls == ["build"] and manager.active == []
    at = int(np.searchsorted(s, s[trigger] - 1.5))
    manager.tick(ego_at(route, at, 0.15), at)
    assert scenario.calls == ["build", "start", "update"] and manager.active == [scenario]
    # a scenario with a ScenarioTimeout switches the agent-blocked test off at its trigger (LB2.0's
    # ScenarioTimeout.initialise), before its own start hooks run
    assert manager.pop_switches() == [(SWITCH_ACTOR_BLOCKED, False), (SWITCH_WRONG_DIRECTION, False)]
    assert manager.pop_switches() == []
    scenario.finish = True
    manager.tick(ego_at(route, trigger, 0.20), trigger)
    assert scenario.calls[-2:] == ["update", "end"]
    assert manager.pop_switches() == [(SWITCH_ACTOR_BLOCKED, True)]  # ScenarioTimeout.terminate
    assert manager.statuses == {"RecorderForTests_1": ScenarioStatus.SUCCESS}
    assert manager.active == [] and manager.hints() == [] and manager.events == []
    manager.tick(ego_at(route, trigger + 5, 0.25), trigger + 5)
    assert scenario.calls.count("update") == 2  # a finished scenario is not updated again


def test_scenario_timeout_ends_the_scenario_with_an_infraction(route, monkeypatch):
    manager, scenario = make_manager(route, config_at(route, 10), monkeypatch)
    manager.tick(ego_at(route, 10, 1.0), 10)  # built and triggered at t = 1 s
    manager.tick(ego_at(route, 10, 240.95), 10)
    assert manager.active == [scenario]
    manager.tick(ego_at(route, 10, 241.0), 10)  # 240 s after the trigger
    assert manager.statuses["RecorderForTests_1"] is ScenarioStatus.FAILURE
    events = manager.events
    assert [(e.key, e.message) for e in events] == [(lb.SCENARIO_TIMEOUTS, "Agent timed out a scenario")]
    assert lb.PENALTY_FACTORS[events[0].key] == 0.7
    assert scenario.calls[-1] == "end"


def test_cleanup_ends_running_scenarios_without_timeout_event(route, monkeypatch):
    manager, scenario = make_manager(route, config_at(route, 10), monkeypatch)
    manager.tick(ego_at(route, 10, 1.0), 10)
    manager.cleanup(ego_at(route, 12, 2.0))
    assert scenario.calls[-1] == "end" and manager.events == [] and manager.active == []


def test_trigger_point_must_lie_on_the_route(route, monkeypatch):
    with pytest.raises(ScenarioSetupError, match="not within 2 m and 10 degrees"):
        make_manager(route, config_at(route, 30, lateral=2.5), monkeypatch)
    with pytest.raises(ScenarioSetupError):
        make_manager(route, config_at(route, 30, yaw_offset=15.0), monkeypatch)
    make_manager(route, config_at(route, 30, lateral=1.5, yaw_offset=8.0), monkeypatch)


def test_unknown_type_lists_the_known_ones():
    with pytest.raises(UnknownScenarioError) as info:
        scenario_class("NoSuchScenario")
    assert "Accident" in str(info.value) and "ParkingExit" in str(info.value)
    from b2d_data.format.scenario_types import LB2_ONLY_TYPES, SCENARIO_TYPES

    benchmark = {t.xml_type for t in SCENARIO_TYPES}
    missing = sorted(benchmark - set(SCENARIO_CLASSES))
    if missing:  # a Bench2Drive type not implemented yet is named as such
        with pytest.raises(UnknownScenarioError, match="without an implementation"):
            scenario_class(missing[0])
    # every registered type is a Bench2Drive one or one of LB2.0's training types Bench2Drive drops (issue 23), at
    # least those of issues 4, 12 and 14
    registered = {t for t in SCENARIO_CLASSES if not t.endswith("ForTests")}
    assert registered <= benchmark | {t.xml_type for t in LB2_ONLY_TYPES} and len(registered) >= 30
    issue_12 = {
        "NonSignalizedJunctionLeftTurn", "SignalizedJunctionRightTurn", "SignalizedJunctionLeftTurnEnterFlow",
        "NonSignalizedJunctionLeftTurnEnterFlow", "EnterActorFlow", "CrossingBicycleFlow",
    }  # fmt: skip
    assert issue_12 <= registered


def test_yield_to_emergency_vehicle_test_judges_the_last_state_seen():
    test = YieldToEmergencyVehicleTest(ev_id=2)
    ego_ahead = snap(1.0, vehicle(EGO, 10.0, 0.0), vehicle(2, 0.0, 0.0))
    test.update(ego_ahead, ego_ahead.actors[EGO])
    ev_ahead = snap(2.0, vehicle(EGO, 10.0, 0.0), vehicle(2, 20.0, 0.0))
    test.update(ev_ahead, ev_ahead.actors[EGO])
    test.terminate(ev_ahead, ev_ahead.actors[EGO])
    assert test.events == []
    failing = YieldToEmergencyVehicleTest(ev_id=2)
    failing.update(ego_ahead, ego_ahead.actors[EGO])
    gone = snap(3.0, vehicle(EGO, 12.0, 0.0))  # the vehicle was removed: the last state decides
    failing.update(gone, gone.actors[EGO])
    failing.terminate(gone, gone.actors[EGO])
    failing.terminate(gone, gone.actors[EGO])
    assert [(e.key, e.message) for e in failing.events] == [
        (lb.YIELD_EMERGENCY_VEHICLE, "Agent failed to yield to an emergency vehicle")
    ]


# --------------------------------------------------------------------------- the agent-blocked test (issue 23, X1)


class Untimed(Recorder):
    """A scenario type without a ScenarioTimeout (DynamicObjectCrossing, ControlLoss, ...)."""

    xml_type = "UntimedForTests"
    scenario_timeout = None
    timeout_test = False


def stand_still(route: DenseRoute, configs: list[ScenarioConfig], monkeypatch, until: float, dt: float = 0.25,
                finish: dict[str, float] | None = None) -> tuple[RouteCriteria, ScenarioManager, float | None]:
    """The ego stands at the first trigger point from t = 0; the route criteria get the manager's switches each
    tick as ``route_runner`` passes them. ``finish`` ends named scenarios at given times. Returns the criteria, the
    manager and the time at which the route stopped as blocked (None if it did not)."""
    monkeypatch.setitem(SCENARIO_CLASSES, "RecorderForTests", Recorder)
    monkeypatch.setitem(SCENARIO_CLASSES, "UntimedForTests", Untimed)

    def factory(cfg: ScenarioConfig) -> ScenarioContext:
        return ScenarioContext(sim=None, map=route.waypoints[0].map, route=route, config=cfg,  # type: ignore[arg-type]
                               rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip

    manager = ScenarioManager(factory, configs)
    criteria = RouteCriteria(route.waypoints[0].map, route, EGO)
    index = manager.scenarios[0].trigger_index
    for k in range(round(until / dt) + 1):
        t = k * dt
        for scenario in manager.scenarios:
            if isinstance(scenario, Recorder) and (finish or {}).get(scenario.name, math.inf) <= t:
                scenario.finish = True
        snapshot = ego_at(route, index, t)
        manager.tick(snapshot, index)
        for name, active in manager.pop_switches():
            criteria.switch(name, active)
        criteria.update(snapshot, snapshot.actors[EGO], index)
        if criteria.stop_reason == "Agent got blocked":
            return criteria, manager, t
    return criteria, manager, None


def recorder_config(route: DenseRoute, index: int, n: int = 1, xml_type: str = "RecorderForTests") -> ScenarioConfig:
    t = route.waypoints[index].transform
    return ScenarioConfig(f"{xml_type}_{n}", xml_type, Transform(t.location, Rotation(yaw=t.rotation.yaw)))


def test_a_scenario_timeout_pauses_the_agent_blocked_test(route, monkeypatch):
    # LB2.0: ScenarioTimeout.initialise sets AC_SwitchActorBlockedTest False, terminate sets it True again, and
    # ActorBlockedTest restarts its clock whenever the key is read. An ego that stands from t = 0 at a trigger reached
    # at t = 0 is therefore not blocked at 60 s; the scenario times out at t = 240 s (ScenarioTimeoutTest, x0.7),
    # the test comes back on with its clock at 240 s, and the route ends as blocked at the first tick past 300 s.
    criteria, manager, blocked_at = stand_still(route, [recorder_config(route, 30)], monkeypatch, until=320.0)
    assert blocked_at == pytest.approx(300.25)
    assert [e.key for e in manager.events] == [lb.SCENARIO_TIMEOUTS]
    assert [e.key for e in criteria.blocked.events] == [lb.VEHICLE_BLOCKED]


def test_without_a_scenario_timeout_the_agent_blocked_test_stays_on(route, monkeypatch):
    # the same standing ego at a scenario without a ScenarioTimeout: blocked at the first tick past 60 s
    _, manager, blocked_at = stand_still(route, [recorder_config(route, 30, xml_type="UntimedForTests")],
                                         monkeypatch, until=100.0)  # fmt: skip
    assert blocked_at == pytest.approx(60.25) and manager.events == []


def test_overlapping_scenario_timeouts_the_last_writer_wins(route, monkeypatch):
    # two timed scenarios triggered together at t = 0; the first ends at t = 100 s and writes True while the second
    # still runs: LB2.0's blackboard key holds the last value written, so the test is on again from 100 s and the
    # standing ego is blocked at the first tick past 160 s, long before the second scenario's timeout at 240 s
    configs = [recorder_config(route, 30, 1), recorder_config(route, 30, 2)]
    _, manager, blocked_at = stand_still(route, configs, monkeypatch, until=200.0,
                                         finish={"RecorderForTests_1": 100.0})  # fmt: skip
    assert blocked_at == pytest.approx(160.25)
    assert manager.statuses["RecorderForTests_1"] is ScenarioStatus.SUCCESS
    assert manager.statuses["RecorderForTests_2"] is None  # still running when the route ended


def test_a_scenario_actor_takes_its_place_from_background_traffic_not_from_other_scenario_actors(route):
    from b2d_data.scenarios.framework import ScenarioSetupError
    from b2d_data.sim.api import ActorSpec
    from b2d_data.sim.builtin.world import BuiltinSimulator

    car = "vehicle.lincoln.mkz_2020"
    place = route.waypoints[40].transform
    at = Transform(Location(place.location.x, place.location.y, place.location.z + 0.2), place.rotation)
    with BuiltinSimulator(route.waypoints[0].map, seed=0) as sim:
        ctx = ScenarioContext(sim=sim, map=route.waypoints[0].map, route=route, config=config_at(route, 40),
                              rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
        scenario = Recorder(ctx)
        background = sim.spawn_actor(ActorSpec(car, role_name="background"), at)
        sim.tick()  # the place is taken in the world the scenario sees
        actor = scenario.spawn(car, at)  # the background car 0 m away is removed, the place is ours
        assert background not in sim.actor_ids() and actor in sim.actor_ids() and actor in scenario.actors
        with pytest.raises(ScenarioSetupError, match="place taken"):
            scenario.spawn(car, at)  # a scenario actor stands there now: never removed
        assert actor in sim.actor_ids()
