"""The junction turns through a flow (``catalog/junction_turns.py``) on routes of Bench2Drive's own route files, as
scenario_runner's ``leaderboard-2.0`` branch (Bench2Drive ``da12001``) sets them up.

Built on the shipped Town07 without a simulator (the constructors need only the map and the route); the keypoints
are those of Bench2Drive v0.0.4's validation route 24948.
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
