"""RouteRunner end to end on the builtin simulator (Town01), plus its failure paths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import load_opendrive
from b2d_data.scenarios.criteria import SWITCH_WRONG_DIRECTION, Infraction
from b2d_data.scenarios.framework import ScenarioSetupError
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_runner import (
    NoScenarios,
    RouteRunner,
    ScenarioSetup,
    TickInfo,
    default_scenario_manager,
)
from b2d_data.scenarios.route_xml import Route, ScenarioConfig
from b2d_data.sim.api import ScenarioHint, Snapshot, TrafficLightState, VehicleControl
from b2d_data.sim.builtin.world import BuiltinSimulator


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town01.xodr")


@pytest.fixture(scope="module")
def straight_route(town01):
    """50 m on Town01 road 1 (straight, no junction), from spawn point 2."""
    start = town01.get_waypoint(town01.get_spawn_points()[2].location)
    route = Route(id="42", town="Town01", waypoints=(start.transform.location, start.next(50.0)[0].transform.location))
    return route, DenseRoute.from_route(town01, route)


class PurePursuit:
    """Follows the dense route at ``target`` m/s; brakes for any vehicle less than 10 m ahead in its path."""

    def __init__(self, dense: DenseRoute, target: float = 6.0) -> None:
        self.dense, self.target, self.index = dense, target, 0
        self.hints_seen: list[tuple[ScenarioHint, ...]] = []

    def run_step(self, snapshot: Snapshot, hints) -> VehicleControl:
        self.hints_seen.append(tuple(hints))
        ego = snapshot.hero()
        loc, yaw = ego.location, math.radians(ego.transform.rotation.yaw)
        self.index = self.dense.closest_index(loc, self.index, 10)
        tx, ty, _ = self.dense.locations[min(self.index + 4, len(self.dense) - 1)]
        dx, dy = tx - loc.x, ty - loc.y
        ahead, left = math.cos(yaw) * dx + math.sin(yaw) * dy, -math.sin(yaw) * dx + math.cos(yaw) * dy
        curvature = 2 * left / max(ahead * ahead + left * left, 1e-6)
        steer = max(-1.0, min(1.0, math.atan(2.9 * curvature) / math.radians(70)))
        blocked = False
        for other in snapshot.vehicles():
            if other.id == ego.id:
                continue
            ox, oy = other.location.x - loc.x, other.location.y - loc.y
            along, across = math.cos(yaw) * ox + math.sin(yaw) * oy, -math.sin(yaw) * ox + math.cos(yaw) * oy
            blocked |= 0 < along < 10 and abs(across) < 2
        speed = ego.speed()
        if blocked:
            return VehicleControl(brake=1.0, steer=steer)
        return VehicleControl(throttle=max(0.0, min(1.0, 0.5 * (self.target - speed))), steer=steer)


def green_world(town01, seed: int = 0) -> BuiltinSimulator:
    sim = BuiltinSimulator(town01, seed=seed)
    for light_id in sim.snapshot().traffic_lights:
        sim.set_traffic_light_state(light_id, TrafficLightState.GREEN, freeze=True)
    return sim


def test_route_completed_end_to_end(town01, straight_route, tmp_path):
    route, dense = straight_route
    frames: list[tuple[int, TickInfo]] = []
    sim = green_world(town01)
    runner = RouteRunner(sim, route, PurePursuit(dense), seed=0,
                         on_frame=lambda snap, info: frames.append((snap.frame, info)))
    result = runner.run()
    record = result.record

    assert result.stop_reason == "completed"
    assert record.status == "Completed"  # every Bench2Drive route has min-speed messages
    assert record.scores.score_route == 100.0 and record.scores.score_penalty == 1.0
    assert result.success and record.success
    assert all(not msgs for key, msgs in record.infractions.items() if key != lb.MIN_SPEED_INFRACTIONS)
    assert record.infractions[lb.MIN_SPEED_INFRACTIONS]
    assert record.num_infractions == len(record.infractions[lb.MIN_SPEED_INFRACTIONS])
    assert record.route_id == "RouteScenario_42_rep0" and record.town_name == "Town01"
    assert record.meta.route_length == round(dense.total_length, 3)
    assert record.meta.duration_game == pytest.approx(result.ticks * 0.05)
    # A frame every second tick, starting with the first.
    assert result.frames == len(frames) == (result.ticks + 1) // 2
    assert [info.tick for _, info in frames[:3]] == [1, 3, 5]
    assert [info.frame_index for _, info in frames] == list(range(len(frames)))
    # The ego was removed at the end (and the background stopped).
    assert frames[0][1].ego_id not in sim.actor_ids()

    path = tmp_path / "eval_route.json"
    from b2d_data.scenarios.statistics import checkpoint_results

    lb.write_results(checkpoint_results([record]), path)
    back = lb.read_results(path).records
    assert [r.to_dict() for r in back] == [record.to_dict()]
    assert back[0].status == "Completed" and back[0].scores.score_route == 100.0


def test_runs_are_deterministic(town01, straight_route):
    route, dense = straight_route
    a = RouteRunner(green_world(town01, seed=3), route, PurePursuit(dense), seed=3).run()
    b = RouteRunner(green_world(town01, seed=3), route, PurePursuit(dense), seed=3).run()
    assert a.ticks == b.ticks and a.events == b.events
    da, db = a.record.to_dict(), b.record.to_dict()
    for d in (da, db):
        d.pop("save_name"), d["meta"].pop("duration_system")
    assert da == db


def test_the_ego_spawns_half_a_metre_above_the_first_route_point(town01, straight_route):
    route, dense = straight_route
    runner = RouteRunner(BuiltinSimulator(town01), route, PurePursuit(dense), dense_route=dense)
    pose = runner.spawn_transform()
    first = dense.waypoints[0].transform
    assert pose.location.z == pytest.approx(first.location.z + 0.5)
    assert (pose.location.x, pose.location.y, pose.rotation.yaw) == (first.location.x, first.location.y,
                                                                    first.rotation.yaw)


class Crashing:
    def __init__(self, at_tick: int) -> None:
        self.at_tick, self.calls = at_tick, 0

    def run_step(self, snapshot, hints) -> VehicleControl:
        self.calls += 1
        if self.calls == self.at_tick:
            raise RuntimeError("planner exploded")
        return VehicleControl(throttle=0.5)


def test_an_agent_that_raises_fails_the_route_but_keeps_the_record(town01, straight_route, caplog):
    route, dense = straight_route
    result = RouteRunner(BuiltinSimulator(town01), route, Crashing(at_tick=3), dense_route=dense).run()
    assert result.record.status == "Failed - Agent crashed" and not result.success
    assert result.ticks == 3 and result.stop_reason == "Agent crashed"
    assert "planner exploded" in caplog.text


class StubManager:
    """A scenario manager stand-in: one hint, a switch request, a scenario timeout reported at cleanup."""

    def __init__(self, setup: ScenarioSetup) -> None:
        self.setup, self.ticks, self.route_indices = setup, 0, []
        self.cleaned_with: Snapshot | None = None
        self.events: list[Infraction] = []
        self._switches = [(SWITCH_WRONG_DIRECTION, False)]

    def tick(self, snapshot: Snapshot, route_index: int) -> None:
        self.ticks += 1
        self.route_indices.append(route_index)

    def pop_switches(self):
        out, self._switches = self._switches, []
        return out

    def hints(self):
        return [ScenarioHint("Accident", 7, 7)]

    def cleanup(self, snapshot: Snapshot | None = None) -> None:
        self.cleaned_with = snapshot
        self.events.append(Infraction(lb.SCENARIO_TIMEOUTS, lb.scenario_timeout_message(), snapshot.frame))


def test_tick_limit_and_scenario_manager_wiring(town01, straight_route):
    route, dense = straight_route
    managers: list[StubManager] = []

    def factory(setup: ScenarioSetup) -> StubManager:
        managers.append(StubManager(setup))
        return managers[-1]

    agent = PurePursuit(dense, target=2.0)
    result = RouteRunner(BuiltinSimulator(town01), route, agent, scenario_manager_factory=factory, max_ticks=40).run()
    (manager,) = managers
    # 41 world ticks: the 41st exceeds the limit before anything else runs (Bench2Drive's tick_count > 4000).
    assert result.ticks == 41 and result.duration_game == pytest.approx(2.05)
    assert result.record.status == "Failed - TickRuntime"
    # The manager also ticks once on the spawn snapshot (index 0) before the first world tick: 1 + 40 calls.
    assert manager.ticks == 41 and manager.route_indices == sorted(manager.route_indices)
    assert manager.route_indices[0] == 0
    assert agent.hints_seen[0] == (ScenarioHint("Accident", 7, 7),)
    assert manager.cleaned_with is not None and manager.cleaned_with.frame == manager.setup.sim.snapshot().frame
    # The scenario timeout reported at cleanup lands in the record with its 0.7 factor.
    assert result.record.infractions[lb.SCENARIO_TIMEOUTS] == ["Agent timed out a scenario"]
    assert result.record.scores.score_penalty == 0.7
    assert 0 < result.record.scores.score_route < 100


class UnbuildableManager(StubManager):
    """A manager whose scenario finds its layout missing when it is built (on the third tick)."""

    def tick(self, snapshot: Snapshot, route_index: int) -> None:
        super().tick(snapshot, route_index)
        if self.ticks == 3:
            raise ScenarioSetupError("Red_1: layout 'signalized junction' missing: junction 9 has no traffic lights")


def test_a_scenario_that_cannot_be_built_stops_the_route_with_its_reason(town01, straight_route, caplog):
    route, dense = straight_route
    agent = PurePursuit(dense)
    result = RouteRunner(BuiltinSimulator(town01), route, agent, scenario_manager_factory=UnbuildableManager).run()
    assert result.record.status == "Failed - Simulation crashed" and not result.success
    assert result.detail == "Red_1: layout 'signalized junction' missing: junction 9 has no traffic lights"
    # logged as one line for the user, not as a traceback
    assert "junction 9 has no traffic lights" in caplog.text and "Traceback" not in caplog.text


def test_default_manager_drops_scenarios_off_the_route(town01, straight_route):
    route, dense = straight_route
    far = Transform(Location(dense.locations[10][0], dense.locations[10][1] + 30.0, 0.0), Rotation(yaw=180.0))
    off = ScenarioConfig(name="Accident_1", type="Accident", trigger_point=far)
    setup = ScenarioSetup(BuiltinSimulator(town01), town01, Route("5", "Town01", route.waypoints, (off,)), dense, 1,
                          np.random.default_rng(0))
    manager = default_scenario_manager(setup)
    assert not isinstance(manager, NoScenarios) and manager.scenarios == []
    # On the route (route point 10, facing along it): an Accident needs a second lane this road lacks, so it
    # is skipped as a set-up error; a HardBreakRoute needs nothing and is kept.
    p10 = dense.waypoints[10].transform
    accident = ScenarioConfig(name="Accident_2", type="Accident", trigger_point=p10)
    hard_break = ScenarioConfig(name="HardBreakRoute_1", type="HardBreakRoute", trigger_point=p10)
    three = Route("5", "Town01", route.waypoints, (off, accident, hard_break))
    setup = ScenarioSetup(setup.sim, town01, three, dense, 1, np.random.default_rng(0))
    assert [s.name for s in default_scenario_manager(setup).scenarios] == ["HardBreakRoute_1"]
    no_scenarios = ScenarioSetup(setup.sim, town01, route, dense, 1, np.random.default_rng(0))
    assert isinstance(default_scenario_manager(no_scenarios), NoScenarios)
