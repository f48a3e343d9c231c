"""VanillaSignalizedTurnEncounterGreenLight as Bench2Drive's ``vanilla_turn.py`` runs it, placed as bench2drive220.

Bench2Drive: a TrafficLightFreezer sequence (ego green, others red, 5 s; then all red, 5 s) in parallel with the
end condition; the sequence ending ends the scenario, and the freezer then restores each light's state from before
it froze them, i.e. the state at the trigger. bench2drive220's GreenLight routes on Town07 start ~10 m before the
junction with the trigger ~3 m before it.
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.junctions import lights_of_lane
from b2d_data.scenarios.catalog.vanilla_turns import VanillaSignalizedTurnEncounterGreenLight
from b2d_data.scenarios.framework import ScenarioContext, ScenarioManager, ScenarioStatus
from b2d_data.scenarios.placement import make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.triggers import trigger_route_index
from b2d_data.sim.api import ActorSpec, TrafficLightState
from b2d_data.sim.builtin.world import BuiltinSimulator

GREEN_LIGHT = "VanillaSignalizedTurnEncounterGreenLight"
RED, GREEN = TrafficLightState.RED, TrafficLightState.GREEN


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def test_green_then_all_red_for_5_s_each_then_the_states_at_the_trigger_and_the_end(town):
    route = make_routes(town, GREEN_LIGHT, 1, seed=0, params="bench2drive220")[0]
    dense = DenseRoute.from_route(town, route)
    index = trigger_route_index(dense, route.scenarios[0].trigger_point)
    with BuiltinSimulator(town, seed=0) as sim:
        # the ego stands at the trigger point (no control) and never reaches the junction's end condition
        loc = dense.waypoints[index].transform.location
        ego = sim.spawn_actor(
            ActorSpec(EGO_TYPE_ID, role_name="hero"),
            Transform(Location(loc.x, loc.y, loc.z + 0.5), dense.waypoints[index].transform.rotation),
        )
        manager = ScenarioManager(lambda cfg: ScenarioContext(sim, town, dense, cfg, np.random.default_rng(1), ego),
                                  route.scenarios)  # fmt: skip
        (scenario,) = manager.scenarios
        assert isinstance(scenario, VanillaSignalizedTurnEncounterGreenLight)
        snap = sim.tick()
        lights = scenario.junction_lights(snap)
        ego_lights = {info.id for info in lights_of_lane(lights, scenario.ego_entry)}
        at_trigger = {info.id: info.state for info in lights}
        t0 = snap.timestamp
        seen: list[tuple[float, dict[int, TrafficLightState], ScenarioStatus | None]] = []
        for _ in range(260):
            manager.tick(snap, index)
            status = manager.statuses[scenario.name]
            snap = sim.tick()
            seen.append((round(snap.timestamp - t0, 2), {i: snap.traffic_lights[i].state for i in at_trigger}, status))
            if status is not None:
                break
    assert ego_lights and len(at_trigger) > len(ego_lights)
    # the junction's cycle had a pole green at the trigger, so "restored" differs from "left all red"
    assert GREEN in at_trigger.values()
    forced_green = {i: (GREEN if i in ego_lights else RED) for i in at_trigger}
    all_red = dict.fromkeys(at_trigger, RED)
    # the trigger is the first tick (t0); a state set at a tick shows in the next snapshot (t0 + 0.05)
    assert [t for t, states, _ in seen if states == forced_green] == [round(0.05 * k, 2) for k in range(1, 101)]
    assert [t for t, states, _ in seen if states == all_red] == [round(0.05 * k, 2) for k in range(101, 201)]
    # at t0 + 10 s the sequence is over: the scenario ends and every light is back in its state at the trigger
    end_t, end_states, end_status = seen[-1]
    assert end_status is ScenarioStatus.SUCCESS and end_t == 10.05
    assert [status for _, _, status in seen[:-1]] == [None] * 200
    assert end_states == at_trigger


def test_green_light_routes_start_10_m_before_the_junction_and_trigger_2_or_4_m_before_it(town):
    routes = make_routes(town, GREEN_LIGHT, 6, seed=0, params="bench2drive220")
    gaps = []
    for route in routes:
        dense = DenseRoute.from_route(town, route)
        s = dense.cumulative_length
        trigger = trigger_route_index(dense, route.scenarios[0].trigger_point)
        entry = next(k for k, wp in enumerate(dense.waypoints) if wp.is_junction)
        # 5 lane steps of 2 m back from the junction's entry waypoint; the dense route (1 m apart) reaches the first
        # point inside the junction up to 1 m after that entry
        assert 10.0 - 0.05 <= s[entry] <= 11.0 + 0.05, route.id
        # the trigger is the keypoint 3 or 4 steps from the start: 4 or 2 m before the entry (+ the same ≤ 1 m)
        gap = s[entry] - s[trigger]
        assert any(k - 0.05 <= gap <= k + 1.05 for k in (2.0, 4.0)), (route.id, gap)
        gaps.append(gap)
    # both keypoints occur (uniform trigger offset 6–8 m, rounded to the 2 m keypoints)
    assert min(gaps) < 3.1 and max(gaps) > 3.9


#: Bench2Drive v0.0.4 validation route 27870's keypoints (a subset, same roads): south into Town04 junction 621,
#: turning left.
ROUTE_27870 = ((313.9, -100.2), (313.9, -104.2), (329.3, -117.7), (335.3, -117.6), (351.4, -132.5))


def test_non_signalized_turn_sets_up_at_a_signalised_junction():
    # Bench2Drive vanilla_turn.py VanillaNonSignalizedTurn: _initialize_actors (VanillaJunctionTurn's) only walks
    # next(1.0)[0] to the first junction; unlike the signalised siblings it never calls
    # get_traffic_lights_in_junction, and _create_behavior is the end condition alone. So it sets up at junction 621,
    # which has lights, and forces none. (We refused: "junction 621 has traffic lights".)
    from b2d_data.collection.towns import load_map, shipped_town
    from b2d_data.format.transform import Rotation
    from b2d_data.scenarios.catalog.vanilla_turns import VanillaNonSignalizedTurn
    from b2d_data.scenarios.route_xml import ScenarioConfig

    town04 = load_map(shipped_town("Town04"))
    dense = DenseRoute.from_keypoints(town04, [Location(x, y, 0.0) for x, y in ROUTE_27870])
    sim = BuiltinSimulator(town04, seed=0)
    start = dense.waypoints[0].transform
    ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), Transform(start.location, start.rotation))
    config = ScenarioConfig("VanillaNonSignalizedTurn_1", "VanillaNonSignalizedTurn",
                            Transform(Location(313.9, -107.2, 0.0), Rotation(yaw=270.5)), {})
    scenario = VanillaNonSignalizedTurn(ScenarioContext(sim, town04, dense, config, np.random.default_rng(0), ego))
    scenario.build()
    snapshot = sim.snapshot()
    assert scenario.junction.id == 621 and scenario.junction_lights(snapshot)
    scenario.start(snapshot)
    assert sim.snapshot().traffic_lights == snapshot.traffic_lights  # nothing forced
