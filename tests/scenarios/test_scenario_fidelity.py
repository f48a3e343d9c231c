"""Issue 23, first step: scoring rules and defaults of single scenario types as Leaderboard 2.0 has them.

Each expected value is worked out from scenario_runner's ``leaderboard-2.0`` branch as Bench2Drive bundles it; the
comment above each assertion names the reference file. The scenarios are built on the generated town without a
simulator (their constructors and criteria need only the map and the route).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location, Vector3D
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios import statistics
from b2d_data.scenarios.catalog.highway import HighwayCutIn
from b2d_data.scenarios.criteria import CollisionTest, RouteCriteria
from b2d_data.scenarios.framework import SCENARIO_TIMEOUT, ScenarioContext, scenario_class
from b2d_data.scenarios.placement import make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import CollisionEvent, Snapshot

EGO = 1


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def build(town, scenario_type: str, drop: tuple[str, ...] = ()):
    """The first generated route of ``scenario_type`` and its scenario object, XML parameters ``drop`` removed."""
    route = make_routes(town, scenario_type, 1, seed=0)[0]
    config = route.scenarios[0]
    config = replace(config, other_parameters={k: v for k, v in config.other_parameters.items() if k not in drop})
    route = replace(route, scenarios=(config,))
    dense = DenseRoute.from_route(town, route)
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
    return route, dense, scenario_class(scenario_type)(ctx)


# ------------------------------------------------------------------------------------------------ scoring


def test_highway_cut_in_has_no_scenario_timeout_and_no_criteria():
    # highway_cut_in.py: the behaviour has no ScenarioTimeout, _create_test_criteria returns [] in route mode. So no
    # 240 s end, no ScenarioTimeoutTest and no pause of the agent-blocked test (which follows scenario_timeout).
    assert HighwayCutIn.scenario_timeout is None and HighwayCutIn.timeout_test is False
    # the other obstacle and flow types keep theirs
    assert scenario_class("Accident").scenario_timeout == SCENARIO_TIMEOUT == 240.0


def _walker_hit(frame: int, t: float) -> Snapshot:
    from b2d_data.format.transform import BoundingBox, Rotation, Transform
    from b2d_data.format.weather import ROUTE_DEFAULT
    from b2d_data.sim.api import ActorKind, ActorState

    ego = ActorState(
        id=EGO, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
        transform=Transform(Location(0.0, 0.0, 0.0), Rotation()), velocity=Vector3D(5.0, 0.0, 0.0),
        angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.45, 1.06, 0.75)), semantic_tags=(14,),
        role_name="hero",
    )  # fmt: skip
    hit = CollisionEvent(frame, EGO, 42, "walker.pedestrian.0001", Location(1.0, 0.0, 0.0))
    return Snapshot(frame=frame, timestamp=t, actors={EGO: ego}, traffic_lights={}, traffic_signs={},
                    collisions=(hit,), weather=ROUTE_DEFAULT)  # fmt: skip


def test_a_collision_during_vehicle_turning_route_pedestrian_counts_twice(town):
    # object_crash_intersection.py: VehicleTurningRoutePedestrian._create_test_criteria returns
    # [CollisionTest(ego)] whatever the mode; VehicleTurningRoute returns [] ("the route already has a collision
    # criteria"). The route adds scenario criteria to its own (route_scenario.py) and the statistics multiply the
    # factor of every event of every criterion, so one walker hit while the scenario runs costs 0.5 x 0.5 = 0.25.
    route, dense, scenario = build(town, "VehicleTurningRoutePedestrian")
    scenario_criteria = scenario.criteria()
    assert [type(c) for c in scenario_criteria] == [CollisionTest]
    assert build(town, "VehicleTurningRoute")[2].criteria() == []

    criteria = RouteCriteria(town, dense, EGO)
    snapshot = _walker_hit(100, 5.0)
    criteria.collision.update(snapshot, snapshot.actors[EGO])
    for criterion in scenario_criteria:  # the scenario manager updates them from trigger to end
        criterion.update(snapshot, snapshot.actors[EGO])
    criteria.add_scenario_events([e for c in scenario_criteria for e in c.events])
    record = statistics.route_record(route, criteria.result(), dense.total_length, 10.0, 1.0)
    assert len(record.infractions[lb.COLLISIONS_PEDESTRIAN]) == 2
    assert record.scores.score_penalty == pytest.approx(0.25)


# ------------------------------------------------------------------------------------------------ defaults


def test_vehicle_opens_door_default_distance_is_50_m(town):
    # vehicle_opens_door.py: get_value_parameter(config, 'distance', float, 50); the car stands 50 m on
    _, dense, scenario = build(town, "VehicleOpensDoorTwoWays", drop=("distance",))
    assert scenario.distance == 50.0
    s = dense.cumulative_length
    at = dense.closest_index(scenario.obstacle_waypoint.transform.location)
    assert float(s[at] - s[scenario.trigger_index]) == pytest.approx(50.0, abs=1.0)


@pytest.mark.parametrize("scenario_type", ("ConstructionObstacle", "ConstructionObstacleTwoWays"))
def test_construction_default_distance_is_100_m(town, scenario_type):
    # construction_crash_vehicle.py: get_value_parameter(config, 'distance', float, 100), inherited by TwoWays;
    # the construction site stands 100 m after the trigger point
    _, dense, scenario = build(town, scenario_type, drop=("distance",))
    assert scenario.distance == 100.0
    s = dense.cumulative_length
    at = dense.closest_index(scenario.obstacle_waypoint.transform.location)
    assert float(s[at] - s[scenario.trigger_index]) == pytest.approx(100.0, abs=1.0)


def test_enter_actor_flow_defaults(town):
    # actor_flow.py EnterActorFlow: flow_speed 10 m/s, source_dist_interval [20, 50]
    _, _, scenario = build(town, "EnterActorFlow", drop=("flow_speed", "source_dist_interval"))
    assert scenario.flow_speed == 10.0 and scenario.interval == (20.0, 50.0)


def test_crossing_bicycle_flow_default_interval(town):
    # cross_bicycle_flow.py: source_dist_interval [20, 50] (flow_speed 10)
    _, _, scenario = build(town, "CrossingBicycleFlow", drop=("flow_speed", "source_dist_interval"))
    assert scenario.flow_speed == 10.0 and scenario.interval == (20.0, 50.0)


def test_dynamic_object_crossing_default_blocker_is_the_vending_machine(town):
    # object_crash_vehicle.py DynamicObjectCrossing: blocker_model 'static.prop.vendingmachine'
    _, _, scenario = build(town, "DynamicObjectCrossing", drop=("blocker_model",))
    assert scenario.blocker_model == "static.prop.vendingmachine"


# ------------------------------------------------------------------------------------------------ actor placement


def _scenarios(town, scenario_type: str, n: int):
    for route in make_routes(town, scenario_type, n, seed=0):
        dense = DenseRoute.from_route(town, route)
        ctx = ScenarioContext(sim=None, map=town, route=dense, config=route.scenarios[0],  # type: ignore[arg-type]
                              rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
        yield scenario_class(scenario_type)(ctx)


def test_the_turning_route_pedestrian_starts_on_the_side_away_from_the_turn(town):
    # object_crash_intersection.py VehicleTurningRoutePedestrian: spawn at right_wp if (entry x exit).z < 0 (a left
    # turn, scenario_helper.py) else at left_wp: a right turn puts the walker left of the exit lane (our lateral
    # offsets are + right, so < 0), a left turn right of it (> 0)
    turns = set()
    for scenario in _scenarios(town, "VehicleTurningRoutePedestrian", 6):
        turns.add(scenario.ego_turn)
        if scenario.ego_turn == "right":
            assert scenario.start_lateral < 0.0
        else:
            assert scenario.start_lateral > 0.0
    assert turns == {"left", "right"}


def test_pedestrian_crossing_walkers_stand_past_the_last_lane_point(town):
    # pedestrian_crossing.py: each walker's spawn point is the sidewalk point moved forward by 0.4, 1.0 and 1.6 m,
    # toward the junction, not back from it
    (scenario,) = _scenarios(town, "PedestrianCrossing", 1)
    origin = scenario.collision_waypoint.transform
    f = origin.get_forward_vector()
    along = [
        (w.transform.location.x - origin.location.x) * f.x + (w.transform.location.y - origin.location.y) * f.y
        for w in scenario.walkers
    ]
    assert along == pytest.approx([0.4, 1.0, 1.6], abs=1e-6)
