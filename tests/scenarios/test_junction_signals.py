"""Signalised scenarios at a junction whose OpenDRIVE file has no lights (bench2drive220 route 26944 on Town04).

CARLA places Town04's lights at junction 1452 from its Unreal level; ``with_scenario_lights`` gives such a junction
CARLA-style lights before the world is built, so the scenario sets up instead of being skipped.
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.data import bench2drive_file
from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.scenarios.catalog.red_light_runner import OppositeVehicleRunningRedLight
from b2d_data.scenarios.framework import ScenarioContext, ScenarioSetupError
from b2d_data.scenarios.junction_signals import is_signalized, junctions_needing_lights, with_scenario_lights
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import Route, ScenarioConfig, read_routes
from b2d_data.sim.api import ActorSpec
from b2d_data.sim.builtin.world import BuiltinSimulator

#: The grid's eastbound lane along y = -120 (CARLA frame): right of the centre line by half a 3.49 m lane.
LANE_Y = -120.0 + 3.49 / 2


def red_light_route(trigger_x: float = 70.0) -> Route:
    """Eastbound straight through the grid's centre junction, OppositeVehicleRunningRedLight from the right."""
    config = ScenarioConfig(
        "OppositeVehicleRunningRedLight_1", "OppositeVehicleRunningRedLight",
        Transform(Location(trigger_x, LANE_Y, 0.0), Rotation(yaw=0.0)), {"direction": {"value": "right"}},
    )  # fmt: skip
    return Route("1", "Town199", (Location(30.0, LANE_Y, 0.0), Location(210.0, LANE_Y, 0.0)), (config,))


@pytest.fixture(scope="module")
def grid(light_less_grid):
    return light_less_grid


def centre_junction(town) -> int:
    """The grid's 4-way junction, centred at (120, -120)."""
    centre = Location(120.0, -120.0, 0.0)
    return next(j.id for j in town.junctions.values() if j.bounding_box.location.distance_2d(centre) < 1.0)


def build_scenario(town, route: Route) -> OppositeVehicleRunningRedLight:
    """The route's scenario built (constructor and ``build``) in a world on ``town`` with the ego at the start."""
    dense = DenseRoute.from_route(town, route)
    sim = BuiltinSimulator(town, seed=0)
    start = dense.waypoints[0].transform
    ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), Transform(start.location, start.rotation))
    ctx = ScenarioContext(sim, town, dense, route.scenarios[0], np.random.default_rng(0), ego)
    scenario = OppositeVehicleRunningRedLight(ctx)
    scenario.build()
    return scenario


def test_signalised_types_are_those_that_need_lights():
    assert is_signalized("OppositeVehicleRunningRedLight")
    assert is_signalized("SignalizedJunctionLeftTurn") and is_signalized("VanillaSignalizedTurnEncounterRedLight")
    assert not is_signalized("OppositeVehicleTakingPriority")  # the unsignalised twin refuses lights
    assert not is_signalized("NonSignalizedJunctionLeftTurn") and not is_signalized("Accident")


def test_the_scenario_junction_gets_lights_and_the_scenario_builds(grid):
    route = red_light_route()
    junction = centre_junction(grid)
    # the trigger at x = 70 lies 50 m before the junction (box from about x = 110): within the 100 m search
    assert junctions_needing_lights(grid, route) == [junction]
    with pytest.raises(ScenarioSetupError, match="has no traffic lights"):
        build_scenario(grid, route)  # what the Leaderboard-style evaluator skipped before
    lit = with_scenario_lights(grid, route)
    scenario = build_scenario(lit, route)
    lights = scenario.junction_lights(scenario.ctx.sim.snapshot())
    assert scenario.junction.id == junction and len(lights) == 4  # one head per incoming road
    assert with_scenario_lights(lit, route) is lit  # lights there now: nothing more to add


def test_routes_without_signalised_scenarios_keep_the_town(grid):
    route = red_light_route()
    plain = Route(route.id, route.town, route.waypoints, ())
    assert with_scenario_lights(grid, plain) is grid
    priority = ScenarioConfig("OppositeVehicleTakingPriority_1", "OppositeVehicleTakingPriority",
                              route.scenarios[0].trigger_point, {"direction": {"value": "right"}})  # fmt: skip
    assert with_scenario_lights(grid, Route(route.id, route.town, route.waypoints, (priority,))) is grid


def test_route_26944_on_town04_sets_up_its_scenario():
    """Town04.xodr has no signal at junction 1452; CARLA has lights there: four roads enter it, four heads."""
    from b2d_data.collection.towns import load_map, shipped_town

    route = next(r for r in read_routes(bench2drive_file("bench2drive220.xml")) if r.id == "26944")
    town = load_map(shipped_town("Town04"))
    assert junctions_needing_lights(town, route) == [1452]
    lit = with_scenario_lights(town, route)
    scenario = build_scenario(lit, route)
    assert scenario.junction.id == 1452
    assert len(scenario.junction_lights(scenario.ctx.sim.snapshot())) == 4
