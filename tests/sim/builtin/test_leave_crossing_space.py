"""BackgroundTraffic.leave_crossing_space: BackgroundActivity's ``_leave_crossing_space`` on the generated town."""

from __future__ import annotations

import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.placement import make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import ActorSpec
from b2d_data.sim.builtin.world import BuiltinSimulator


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def test_leave_crossing_space_removes_near_opposite_vehicles_and_stops_the_next_ones(town):
    # background_activity.py _leave_crossing_space(collision_wp): opposite_loc = collision_wp.get_left_lane()'s
    # location; every opposite actor closer than destruction_dist = 20 m to it is destroyed, one closer than
    # stop_dist = 30 m gets set_target_velocity(0); the rest are untouched. Here the crossing point is taken
    # beside one of the opposite vehicles (distance 0: removed); the others are sorted by their own distances.
    route = make_routes(town, "ParkedObstacleTwoWays", 1, seed=0)[0]
    dense = DenseRoute.from_route(town, route)
    with BuiltinSimulator(town, seed=3) as sim:
        ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), dense.waypoints[0].transform)
        bg = sim.background
        bg.start(ego, list(dense.waypoints))
        snapshot = sim.tick()
        for _ in range(400):
            opposite = [v for v, src in bg.vehicle_sources().items() if src == "opposite" and v in snapshot.actors]
            if len(opposite) >= 3:
                break
            snapshot = sim.tick()
        assert len(opposite) >= 3, "no opposite traffic to test with"
        first = snapshot.actors[opposite[0]]
        beside = town.get_waypoint(first.location).get_left_lane()  # the ego-direction lane beside it
        assert beside is not None
        target = beside.get_left_lane().transform.location
        distance = {v: snapshot.actors[v].location.distance(target) for v in opposite}
        bg.leave_crossing_space(beside)
        after = sim.tick()
        for v, d in distance.items():
            if d < 20.0:
                assert v not in after.actors and v not in bg.vehicle_ids()
            elif d < 30.0:
                assert after.actors[v].speed() < 0.1
            else:
                assert v in after.actors
        assert distance[opposite[0]] < 1.0
