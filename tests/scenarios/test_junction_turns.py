"""The junction turns through a flow (``catalog/junction_turns.py``) on routes of Bench2Drive's own route files, as
scenario_runner's ``leaderboard-2.0`` branch (Bench2Drive ``da12001``) sets them up.

Built without a simulator (the constructors need only the map and the route): on the shipped Town07 with the
keypoints of Bench2Drive v0.0.4's validation route 24948, and on a small generated town whose junction has an entry
without a straight branch (the junction flows' entry rule, row 20 of docs/scenario-deviations.md), also triggered
~150 m before that junction (LB2.0's junction search has no distance limit).
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import load_opendrive
from b2d_data.scenarios.catalog.junction_turns import SignalizedJunctionRightTurn
from b2d_data.scenarios.framework import ScenarioContext
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import ScenarioConfig

#: Route 24948's keypoints (a subset, same roads): north on road 44, right at junction 68 onto road 0, heading west.
ROUTE_24948 = ((-102.8, 15.2), (-102.9, 25.2), (-103.0, 37.2), (-116.7, 49.1), (-126.7, 49.0), (-142.7, 48.9))


@pytest.fixture(scope="module")
def town07(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town07.xodr")


def test_right_turn_flow_sink_walks_on_into_the_next_junction(town07):
    # signalized_junction_right_turn.py JunctionRightTurn._initialize_actors: the source is the left entry's rightmost
    # driving lane walked back in 5 m steps (5 x flow_speed = 65 m at most, stopping before a junction); the sink is
    # sink_exit_wp.next(3 x flow_speed)[0] with sink_exit_wp = generate_target_waypoint(source, 0), the first lane
    # point after the junction on the straightest way through it. CARLA's next() walks on through junctions, and
    # the only refusal is an empty list (a dead end). Here the left entry (road 55 lane 1) goes straight through
    # junction 68 onto road 0 lane -1, which enters junction 123 36 m later: the sink lies 39 m after the exit,
    # inside junction 123. (We refused: "no left entry of junction 68 goes straight on for 39 m".)
    dense = DenseRoute.from_keypoints(town07, [Location(x, y, 0.0) for x, y in ROUTE_24948])
    config = ScenarioConfig("SignalizedJunctionRightTurn_1", "SignalizedJunctionRightTurn",
                            Transform(Location(-102.9, 22.2, 0.0), Rotation(yaw=90.3)),
                            {"flow_speed": {"value": "13"}, "source_dist_interval": {"from": "21", "to": "34"}})
    ctx = ScenarioContext(sim=None, map=town07, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=1)  # fmt: skip
    scenario = SignalizedJunctionRightTurn(ctx)
    assert scenario.junction.id == 68
    assert (scenario.source_entry.road_id, scenario.source_entry.lane_id) == (55, 1)
    exit_k = next(k for k, wp in enumerate(scenario.path) if k and scenario.path[k - 1].is_junction
                  and not wp.is_junction)  # fmt: skip
    assert (scenario.path[exit_k].road_id, scenario.path[exit_k].lane_id) == (0, -1)
    assert len(scenario.path) - 1 - exit_k == pytest.approx(39, abs=1)  # 1 m steps
    assert scenario.sink.is_junction and scenario.sink.junction_id == 123


# ------------------------------------------------------------------------------------------------ row 20: any angle


@pytest.fixture(scope="module")
def skewed_junction(tmp_path_factory):
    """Town198: junction 0 at the origin with three arms, south (CARLA y > 0), west and north-east (45°), closed by
    a ring road; no lights. The west entry has no straight connection: it turns 45° left to the north-east arm or
    90° right to the south one."""
    from b2d_data.maps.towngen.cross_sections import TownWidths, street
    from b2d_data.maps.towngen.network import EdgeSpec, NetworkBuilder, NodeSpec, TownPlan
    from b2d_data.maps.towngen.paths import Corner
    from b2d_data.maps.towngen.xodr_writer import to_xml

    section = street(TownWidths.draw(np.random.default_rng(0)))
    plan = TownPlan("Town198", "test", 0)
    plan.nodes += [NodeSpec("J", 0.0, 0.0), NodeSpec("S", 0.0, -200.0), NodeSpec("W", -200.0, 0.0),
                   NodeSpec("E", 150.0, 150.0)]  # fmt: skip
    plan.edges += [
        EdgeSpec("js", "J", "S", section), EdgeSpec("jw", "J", "W", section), EdgeSpec("je", "J", "E", section),
        EdgeSpec("sw", "S", "W", section),
        EdgeSpec("we", "W", "E", section, corners=(Corner(-200.0, 300.0, 40.0), Corner(350.0, 300.0, 40.0))),
        EdgeSpec("es", "E", "S", section, corners=(Corner(350.0, -200.0, 40.0),)),
    ]  # fmt: skip
    path = tmp_path_factory.mktemp("skewed") / "Town198.xodr"
    path.write_text(to_xml(NetworkBuilder(plan).build()))
    return load_opendrive(path)


def _right_turn_onto_the_skewed_arm(town, scenario_type: str, trigger_y: float = 60.0, **params: str):
    """``scenario_type`` on a route north from the south arm, right (45°) onto the north-east arm of junction 0,
    triggered at ``trigger_y`` on the south arm."""
    from b2d_data.scenarios.catalog.road_geometry import junction_lanes, move_along
    from b2d_data.scenarios.framework import scenario_class

    ego_entry = town.get_waypoint(Location(1.745, 60.0, 0.0))
    turn = next(lane for lane in junction_lanes(town.junctions[0])
                if (lane.entry.road_id, lane.entry.lane_id) == (ego_entry.road_id, ego_entry.lane_id)
                and lane.turn == "right")  # fmt: skip
    end = move_along(turn.exit, 60.0)
    start_y = max(150.0, trigger_y + 10.0)
    dense = DenseRoute.from_keypoints(town, [Location(1.745, start_y, 0.0), end.transform.location])
    trigger = Transform(Location(1.745, trigger_y, 0.0), Rotation(yaw=-90.0))
    config = ScenarioConfig(f"{scenario_type}_1", scenario_type, trigger,
                            {tag: {"value": value} for tag, value in params.items()})  # fmt: skip
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=1)  # fmt: skip
    return scenario_class(scenario_type)(ctx)


def _exit_of(path) -> tuple[int, int]:
    """Road and lane of the first point after the junction on a flow path."""
    k = next(k for k, wp in enumerate(path) if k and path[k - 1].is_junction and not wp.is_junction)
    return path[k].road_id, path[k].lane_id


@pytest.mark.parametrize("scenario_type", ("NonSignalizedJunctionRightTurn", "OppositeVehicleTakingPriority"))
def test_a_flow_entry_takes_its_straightest_branch_whatever_its_angle(skewed_junction, scenario_type):
    # signalized_junction_right_turn.py JunctionRightTurn._initialize_actors and opposite_vehicle_taking_priority.py
    # OppositeVehicleJunction._initialize_actors: the sink is sink_exit_wp.next(d)[0] with sink_exit_wp =
    # generate_target_waypoint(source, 0); scenario_helper.py choose_at_junction(direction=0) takes the branch whose
    # point 10 m on lies least to the side (min |cross|), with no angle limit. Here the left entry (from the west)
    # has no branch under 35°: LB2.0 sends the flow / the adversary 45° left onto the north-east arm (the other
    # branch turns 90° right). (We refused: "no left entry ... goes straight on" / "does not continue straight".)
    params = {"direction": "left"} if scenario_type == "OppositeVehicleTakingPriority" else {}
    scenario = _right_turn_onto_the_skewed_arm(skewed_junction, scenario_type, **params)
    assert scenario.junction.id == 0
    path = scenario.path
    west = skewed_junction.get_waypoint(Location(-60.0, 1.745, 0.0))
    assert (path[0].road_id, path[0].lane_id) == (west.road_id, west.lane_id)
    north_east = skewed_junction.get_waypoint(Location(60.0, -60.0, 0.0))
    assert _exit_of(path)[0] == north_east.road_id


# ------------------------------------------------------------------------------------------------ row 20: any distance


@pytest.mark.parametrize("scenario_type", ("SignalizedJunctionRightTurn", "NonSignalizedJunctionRightTurn",
                                           "PriorityAtJunction"))  # fmt: skip
def test_a_junction_far_ahead_of_the_trigger_sets_up(skewed_junction, scenario_type):
    # signalized_junction_right_turn.py JunctionRightTurn._initialize_actors and green_traffic_light.py
    # PriorityAtJunction._initialize_actors: the junction is found walking next(1.0)[0] from the trigger waypoint
    # until is_junction, with no distance limit (only a lane without next raises). Here the trigger lies ~150 m
    # before junction 0. (We refused: "the route enters no junction within 100 m of the trigger point".)
    from b2d_data.scenarios.catalog.junctions import JUNCTION_SEARCH, junction_entry

    scenario = _right_turn_onto_the_skewed_arm(skewed_junction, scenario_type, trigger_y=170.0)
    assert scenario.junction.id == 0
    assert scenario.ego_turn == "right"
    dense = scenario.ctx.route
    ahead = dense.cumulative_length[scenario.entry_index] - dense.cumulative_length[scenario.trigger_index]
    assert ahead > 140.0
    # generated-route placement keeps its own 100 m rule
    assert junction_entry(dense, scenario.trigger_index, JUNCTION_SEARCH) is None


def test_t_junction_sets_up_without_a_junction_ahead(skewed_junction):
    # Bench2Drive's t_junction.py T_Junction._initialize_actors does nothing (its behaviour is DriveDistance(200) and
    # a ScenarioTimeout), so any trigger sets up. Here the route runs 100 m along the south arm and ends before
    # junction 0. (We refused: "the route enters no junction within 100 m of the trigger point".)
    from b2d_data.scenarios.framework import scenario_class

    dense = DenseRoute.from_keypoints(skewed_junction, [Location(1.745, 170.0, 0.0), Location(1.745, 70.0, 0.0)])
    assert not any(wp.is_junction for wp in dense.waypoints)
    config = ScenarioConfig("T_Junction_1", "T_Junction", Transform(Location(1.745, 160.0, 0.0), Rotation(yaw=-90.0)))
    ctx = ScenarioContext(sim=None, map=skewed_junction, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=1)  # fmt: skip
    assert scenario_class("T_Junction")(ctx).trigger_index >= 0
