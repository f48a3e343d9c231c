"""PriorityAtJunction as LB2.0's ``green_traffic_light.py`` runs it, on a generated town.

Reference (Bench2Drive's copy of the file, identical to scenario_runner leaderboard-2.0): the ego's light GREEN and
every other light of the junction RED (:74-77), frozen by a ``TrafficLightFreezer`` without a duration in parallel
with ``WaitEndIntersection(ego, junction)`` (:83-85): the lights stay so however long the ego takes, the scenario ends
when the ego has left the junction and the freezer's ``terminate`` gives every light back its state from before. No
criteria (:93), no ScenarioTimeout, no background request.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.junctions import lights_of_lane
from b2d_data.scenarios.catalog.priority_at_junction import PriorityAtJunction
from b2d_data.scenarios.catalog.road_geometry import junction_lights
from b2d_data.scenarios.framework import ScenarioContext, ScenarioManager, ScenarioSetupError, ScenarioStatus
from b2d_data.scenarios.junction_signals import junctions_needing_lights
from b2d_data.scenarios.placement import find_candidates, make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.triggers import trigger_route_index
from b2d_data.sim.api import ActorSpec, TrafficLightState
from b2d_data.sim.builtin.world import BuiltinSimulator

RED, GREEN = TrafficLightState.RED, TrafficLightState.GREEN
TYPE = "PriorityAtJunction"


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def _at(wp) -> Transform:
    loc = wp.transform.location
    return Transform(Location(loc.x, loc.y, loc.z + 0.5), wp.transform.rotation)


def test_ego_green_others_red_until_the_ego_has_left_the_junction_then_the_states_at_the_trigger(town, monkeypatch):
    route = make_routes(town, TYPE, 1, seed=0)[0]
    dense = DenseRoute.from_route(town, route)
    index = trigger_route_index(dense, route.scenarios[0].trigger_point)
    requests: list[str] = []
    with BuiltinSimulator(town, seed=0) as sim:
        for hook in ("handle_junction_scenario", "switch_route_sources", "change_opposite_behavior"):
            monkeypatch.setattr(sim.background, hook, lambda *a, _h=hook, **k: requests.append(_h))
        ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), _at(dense.waypoints[index]))
        manager = ScenarioManager(lambda cfg: ScenarioContext(sim, town, dense, cfg, np.random.default_rng(1), ego),
                                  route.scenarios)  # fmt: skip
        (scenario,) = manager.scenarios
        assert isinstance(scenario, PriorityAtJunction)
        # no criteria at all: not even a ScenarioTimeoutTest (green_traffic_light.py :93), and no 240 s timeout
        assert scenario.criteria() == [] and scenario.scenario_timeout is None
        snap = sim.tick()
        lights = scenario.junction_lights(snap)
        ego_lights = {info.id for info in lights_of_lane(lights, scenario.ego_entry)}
        at_trigger = {info.id: info.state for info in lights}
        forced = {i: (GREEN if i in ego_lights else RED) for i in at_trigger}
        # 30 s standing at the trigger: longer than a whole cycle, so an unfrozen light would have changed
        states = []
        for _ in range(600):
            manager.tick(snap, index)
            snap = sim.tick()
            states.append({i: snap.traffic_lights[i].state for i in at_trigger})
            assert manager.statuses[scenario.name] is None
        # the ego drives into the junction: still running; out of it: SUCCESS at once, lights given back
        inside = next(k for k in range(index, len(dense.waypoints)) if dense.waypoints[k].is_junction)
        sim.set_transform(ego, _at(dense.waypoints[inside + 2]))
        snap = sim.tick()
        manager.tick(snap, inside + 2)
        assert manager.statuses[scenario.name] is None
        after = next(k for k in range(inside, len(dense.waypoints)) if not dense.waypoints[k].is_junction) + 3
        sim.set_transform(ego, _at(dense.waypoints[after]))
        snap = sim.tick()
        manager.tick(snap, after)
        status = manager.statuses[scenario.name]
        snap = sim.tick()
        released = {i: snap.traffic_lights[i].state for i in at_trigger}
    # one light of the ego's lane, and the junction has others
    assert len(ego_lights) == 1 and len(at_trigger) > 1
    assert states == [forced] * 600
    assert status is ScenarioStatus.SUCCESS
    assert released == at_trigger
    assert requests == []  # no HandleJunctionScenario, no source switch


def test_placement_finds_signalised_junctions_the_route_drives_through(town):
    assert len(find_candidates(town, TYPE)) >= 10
    lit = {s.junction_id for s in town.traffic_lights()}
    for route in make_routes(town, TYPE, 4, seed=3):
        (config,) = route.scenarios
        assert config.other_parameters == {}  # routes_training.xml gives it no parameter
        dense = DenseRoute.from_route(town, route)
        index = trigger_route_index(dense, config.trigger_point)
        junctions = [wp.junction_id for wp in dense.waypoints[index:] if wp.is_junction]
        # the route goes through a signalised junction after its trigger and comes out of it
        assert junctions and junctions[0] in lit and not dense.waypoints[-1].is_junction


def test_a_junction_without_lights_gets_none_generated_and_the_scenario_is_not_built(town):
    # green_traffic_light.py :70-75: no light in the junction raises ValueError, and the ego's light is read from the
    # OpenDRIVE landmarks ([0] of an empty list raises too), so LB2.0 never runs it at a junction without lights in
    # the file; generating lights there (as for the signalised types) would make it run
    base = make_routes(town, "VanillaNonSignalizedTurn", 1, seed=0, params="bench2drive220")[0]
    (config,) = base.scenarios
    route = replace(base, scenarios=(replace(config, name=f"{TYPE}_1", type=TYPE),))
    dense = DenseRoute.from_route(town, route)
    assert junctions_needing_lights(town, route, dense) == []
    with BuiltinSimulator(town, seed=0) as sim:
        ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), _at(dense.waypoints[0]))
        scenario = PriorityAtJunction(
            ScenarioContext(sim, town, dense, route.scenarios[0], np.random.default_rng(1), ego)
        )
        with pytest.raises(ScenarioSetupError, match="no traffic lights"):
            scenario.build()


def test_expert_drives_through_on_its_held_green(town):
    from b2d_data import expert
    from b2d_data.scenarios.route_runner import RouteRunner

    route = make_routes(town, TYPE, 1, seed=5)[0]
    dense = DenseRoute.from_route(town, route)
    index = trigger_route_index(dense, route.scenarios[0].trigger_point)
    entry = dense.waypoints[next(k for k in range(index, len(dense.waypoints)) if dense.waypoints[k].is_junction) - 1]
    junction_id = next(wp.junction_id for wp in dense.waypoints[index:] if wp.is_junction)
    seen: list[dict[int, TrafficLightState]] = []
    ego_light: set[int] = set()

    def on_frame(snapshot, info) -> None:
        wp = town.get_waypoint(snapshot.actors[info.ego_id].location)
        if wp.is_junction and wp.junction_id == junction_id:
            lights = junction_lights(snapshot.traffic_lights, town, town.junctions[junction_id])
            ego_light.update(info.id for info in lights_of_lane(lights, entry))
            seen.append({info.id: info.state for info in lights})

    with BuiltinSimulator(town, seed=0) as sim:
        result = RouteRunner(sim, route, expert.Expert(town, list(dense), seed=0), seed=0, dense_route=dense,
                             on_frame=on_frame, record_every=1, max_ticks=3000).run()  # fmt: skip
    infractions = {k: v for k, v in result.record.infractions.items() if v and k != "min_speed_infractions"}
    assert result.success, infractions
    # every tick the ego spent in the junction, its light was green and the junction's others red
    assert (
        seen
        and len(ego_light) == 1
        and all(states[i] == (GREEN if i in ego_light else RED) for states in seen for i in states)
    )
