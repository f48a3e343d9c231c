"""EnterActorFlow's place per parameter set, and the merge sink it tells the expert on an on-ramp.

routes_training.xml holds 36 EnterActorFlow routes, all on Town12, all joining its highway by on-ramps: route 17's
trigger (2707.9, 3155.3) heads -10.2 deg toward the flow's road 38 m to its side (y = 3117), whose flow runs 310 m
from (2745.2, 3117.1) to (3054.9, 3116.6) at 20 m/s, 15-35 m apart. bench2drive220's 5 routes include urban turns
(27506 on Town05 turns right into a 12 m/s flow). So under the training ranges the type is placed on an on-ramp whose
lane runs on beside the highway (the layout EnterActorFlowV2 uses), under bench2drive220's on an unsignalised urban
junction turned right into the flow's road, as before.
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.enter_flow import EnterActorFlow
from b2d_data.scenarios.catalog.layout import LAYOUTS, PARAM_LAYOUTS, layout_of, register_param_layouts
from b2d_data.scenarios.catalog.road_geometry import same_direction_driving_neighbour, same_lane
from b2d_data.scenarios.framework import ScenarioContext, ScenarioManager
from b2d_data.scenarios.placement import find_candidates, make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.triggers import trigger_route_index
from b2d_data.sim.api import ActorSpec
from b2d_data.sim.builtin.world import BuiltinSimulator

TYPE = "EnterActorFlow"


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def _xml_wp(town, spot: dict):
    return town.get_waypoint(Location(*(float(spot[a]) for a in "xyz")))


def test_the_layout_depends_on_the_parameter_set():
    assert layout_of(TYPE, "training").name == "highway_ramps"
    assert layout_of(TYPE, "bench2drive220") is LAYOUTS[TYPE]
    assert LAYOUTS[TYPE].name == "unsignalized_junction"
    # a type without an override keeps its one layout under every set
    assert layout_of("Accident", "training") is LAYOUTS["Accident"] is layout_of("Accident", "bench2drive220")
    with pytest.raises(ValueError, match="registered already"):
        register_param_layouts("training", {TYPE: LAYOUTS[TYPE]})
    assert PARAM_LAYOUTS[("training", TYPE)].name == "highway_ramps"  # the failed call changed nothing


def test_training_routes_join_a_highway_from_an_on_ramp_and_bench2drive220_routes_turn_into_an_urban_road(town):
    training = find_candidates(town, TYPE, "training")
    urban = find_candidates(town, TYPE, "bench2drive220")
    assert training and urban
    assert {c.layout for c in training} == {"highway_ramps"} and {c.layout for c in urban} == {"unsignalized_junction"}
    for route in make_routes(town, TYPE, 3, seed=5, params="training"):
        (config,) = route.scenarios
        source = _xml_wp(town, config.other_parameters["start_actor_flow"])
        sink = _xml_wp(town, config.other_parameters["end_actor_flow"])
        dense = DenseRoute.from_route(town, route)
        lanes = [(wp.road_id, wp.lane_id) for wp in dense.waypoints]
        # the flow runs on a highway (>= 80 km/h); the route starts off the flow's lane and reaches its sink lane
        assert town.speed_limit(source) >= 80.0
        assert lanes[0] != (source.road_id, source.lane_id) and (sink.road_id, sink.lane_id) in lanes
    for route in make_routes(town, TYPE, 3, seed=5, params="bench2drive220"):
        (config,) = route.scenarios
        # bench2drive220's ranges: flow_speed 12-14 (our generated sub-range)
        assert 12 <= int(config.other_parameters["flow_speed"]["value"]) <= 14


def _scenario(town, sim, route) -> tuple[EnterActorFlow, ScenarioManager]:
    dense = DenseRoute.from_route(town, route)
    (config,) = route.scenarios
    index = trigger_route_index(dense, config.trigger_point)
    wp = dense.waypoints[index]
    loc = wp.transform.location
    ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"),
                          Transform(Location(loc.x, loc.y, loc.z + 0.5), wp.transform.rotation))  # fmt: skip
    manager = ScenarioManager(lambda cfg: ScenarioContext(sim, town, dense, cfg, np.random.default_rng(1), ego),
                              route.scenarios)  # fmt: skip
    (scenario,) = manager.scenarios
    manager.tick(sim.tick(), index)  # build + trigger + start
    assert isinstance(scenario, EnterActorFlow)
    return scenario, manager


def test_on_a_ramp_the_hint_carries_the_sink_of_the_flow_lane_left_of_the_ego_exit(town):
    route = make_routes(town, TYPE, 1, seed=5, params="training")[0]
    with BuiltinSimulator(town, seed=0) as sim:
        scenario, _ = _scenario(town, sim, route)
        hint = scenario.hint()
    assert scenario.ego_exit is not None
    left = same_direction_driving_neighbour(scenario.ego_exit, "left")
    (path,) = [p for p in scenario.paths if any(same_lane(wp, left) for wp in p)]
    sink = path[-1].transform.location
    assert hint is not None and hint.scenario_type == TYPE
    assert (hint.extra["sink_x"], hint.extra["sink_y"]) == (sink.x, sink.y)
    # the ego's own exit lane carries no flow: every flow runs on the highway's lanes
    assert not any(same_lane(wp, scenario.ego_exit) for p in scenario.paths for wp in p)
    assert hint.paths  # the flows' cars' paths ahead, as on any flow type


def test_in_an_urban_turn_the_ego_turns_into_a_flow_lane_and_the_hint_has_no_sink(town):
    route = make_routes(town, TYPE, 1, seed=5, params="bench2drive220")[0]
    with BuiltinSimulator(town, seed=0) as sim:
        scenario, _ = _scenario(town, sim, route)
        hint = scenario.hint()
    assert scenario.merge_sink is None
    assert any(same_lane(wp, scenario.ego_exit) for p in scenario.paths for wp in p)
    assert hint is not None and "sink_x" not in hint.extra
