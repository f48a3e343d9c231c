"""Driving primitives: IDM, pure pursuit through the bicycle model, junction reservations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.sim import blueprints
from b2d_data.sim.builtin.lane_following import (
    ANY_LANE,
    IdmParams,
    JunctionArbiter,
    idm_accel,
    lookahead_distance,
    pure_pursuit_steer,
)

P = IdmParams()


def test_idm_by_hand():
    assert idm_accel(0.0, 10.0, None, 0.0, P) == pytest.approx(P.max_accel)  # free road, at rest: a
    assert idm_accel(10.0, 10.0, None, 0.0, P) == pytest.approx(0.0)  # at the desired speed
    # standing behind a stopped leader exactly s0 away: s* = s0, so a·(1 − 0 − 1) = 0, it stays
    assert idm_accel(0.0, 10.0, P.min_gap, 0.0, P) == pytest.approx(0.0)
    # closing at 10 m/s on a stopped car 20 m ahead: s* = 10 + 10·1 + 10·10/(2·sqrt(2.5·3)) = 38.26 m
    s_star = 10.0 + 10.0 + 100.0 / (2.0 * math.sqrt(7.5))
    expected = max(-P.max_decel, P.max_accel * (1.0 - (10.0 / 13.9) ** 4 - (s_star / 20.0) ** 2))
    assert idm_accel(10.0, 13.9, 20.0, 0.0, P) == pytest.approx(expected)
    assert idm_accel(5.0, 0.0, None, 0.0, P) < 0.0  # ordered to stop


def test_pure_pursuit_curvature_goes_through_the_bicycle_model():
    g = blueprints.DEFAULT_GEOMETRY
    path = np.column_stack([np.arange(0.0, 30.0), np.zeros(30)])
    assert pure_pursuit_steer(0.0, 0.0, 0.0, 5.0, path, g) == pytest.approx(0.0)
    # 1 m left of the path (−y in CARLA's frame): steer right (positive)
    steer = pure_pursuit_steer(0.0, -1.0, 0.0, 5.0, path, g)
    ld = lookahead_distance(5.0)  # 3.5 m: the aim point is the first path point at least that far
    k = int(np.argmax(np.hypot(path[:, 0], path[:, 1] + 1.0) >= ld))
    alpha = math.atan2(1.0, path[k, 0])
    curvature = 2.0 * math.sin(alpha) / math.hypot(path[k, 0], 1.0)
    assert steer > 0.0 and steer == pytest.approx(g.steer_for_curvature(curvature))


def _lane(points):
    return np.asarray(points, dtype=float)


def test_arbiter_serialises_crossing_lanes_and_not_a_queue():
    arb = JunctionArbiter()
    # a straight north-south lane along x = 0, a straight west-east lane along y = 0, and a tight right turn
    # from the west entry that stays 4 m or more away from x = 0
    north_south, west_east, west_south = (1, 0, 1), (2, 0, 1), (3, 0, 1)
    arb._polylines[north_south] = _lane([(0, y) for y in range(-10, 11)])
    arb._polylines[west_east] = _lane([(x, 0) for x in range(-10, 11)])
    arb._polylines[west_south] = _lane([(x, (x + 10) ** 2 / 10) for x in range(-10, -3)])
    arb._entry_of.update({north_south: (10, 0, -1), west_east: (20, 0, -1), west_south: (20, 0, -1)})
    assert arb.conflict(north_south, west_east)
    assert not arb.conflict(north_south, west_south)
    assert not arb.conflict(west_east, west_south)  # same entry lane: the queue is IDM's business
    granted = arb.update(1, {}, {7: (5, (north_south,)), 8: (5, (west_east,))})
    assert granted == {7}  # first come (same tick: lower id)
    granted = arb.update(2, {}, {7: (5, (north_south,)), 8: (5, (west_east,)), 9: (5, (west_south,))})
    assert granted == {7, 9}
    granted = arb.update(3, {}, {8: (5, (west_east,))})  # 7 has left: 8 may go
    assert granted == {8}
    # a vehicle whose way is unknown (the ego) holds every lane of its junction; 8 has gone, 10 must wait
    assert arb.update(4, {100: (5, (ANY_LANE,))}, {10: (5, (west_east,))}, managed=[8, 10]) == set()
    # ... but not those of another junction
    assert arb.update(5, {100: (6, (ANY_LANE,))}, {10: (5, (west_east,))}, managed=[10]) == {10}


def test_arbiter_serves_conflicting_requests_first_come_first_served():
    arb = JunctionArbiter()
    # north-south along x = 0 (north entry); west-east along y = 0 and a west-to-south turn that runs down x = 0
    # (both from the west entry: they never conflict with each other, but the turn crosses the north-south lane)
    north_south, west_east, west_turn = (1, 0, 1), (2, 0, 1), (3, 0, 1)
    arb._polylines[north_south] = _lane([(0, y) for y in range(-10, 11)])
    arb._polylines[west_east] = _lane([(x, 0) for x in range(-10, 11)])
    arb._polylines[west_turn] = _lane([(x, 0) for x in range(-10, 0)] + [(0, y) for y in range(11)])
    arb._entry_of.update({north_south: (10, 0, -1), west_east: (20, 0, -1), west_turn: (20, 0, -1)})
    assert arb.conflict(west_turn, north_south) and not arb.conflict(west_turn, west_east)
    # 1 crosses on west-east; 2 (north) asks at tick 1 and must wait for it
    assert arb.update(1, {1: (5, (west_east,))}, {2: (5, (north_south,))}) == set()
    # 3 comes from the west behind 1 at tick 2: 1's lane does not stop it, but 2 asked first for a lane 3 crosses
    assert arb.update(2, {1: (5, (west_east,))}, {2: (5, (north_south,)), 3: (5, (west_turn,))}) == set()
    # 1 has left: 2 goes first, 3 waits for 2
    assert arb.update(3, {}, {2: (5, (north_south,)), 3: (5, (west_turn,))}) == {2}
    assert arb.update(4, {2: (5, (north_south,))}, {3: (5, (west_turn,))}) == set()
    assert arb.update(5, {}, {3: (5, (west_turn,))}) == {3}


def test_arbiter_knows_the_whole_lanes_of_a_junction_longer_than_a_path(carla_maps_dir):
    from b2d_data.format.transform import Location
    from b2d_data.maps import load_opendrive
    from b2d_data.sim.builtin.lane_following import LanePath

    town = load_opendrive(carla_maps_dir / "Town06.xodr")
    # Town06 junction 1050: five parallel lanes (road 1083, lanes −3…−7, 3.5 m apart) straight through a 71 m
    # junction from x = 480; a path 20 m before it reaches only 40 m into it
    arb = JunctionArbiter()
    keys = []
    for y in (45.2, 41.7):  # lanes −5 and −4
        path = LanePath(town.get_waypoint(Location(460.0, y, 0.0)), chooser=lambda options: 0)
        path.extend()
        junction_id, entry, exit_, lanes = path.first_junction()
        assert junction_id == 1050 and exit_ == len(path.waypoints)  # the path ends inside the junction
        arb.learn(path)
        keys.append(lanes[0])
    assert [k[0] for k in keys] == [1083, 1083]
    assert len(arb._polylines[keys[0]]) >= 70  # the whole centre line, from the map
    assert not arb.conflict(keys[0], keys[1])  # 3.5 m apart all along: side by side, they never meet


def test_speed_controls_of_many_actors_are_each_alone():
    # the traffic driver's pedals for all its vehicles at once: each as speed_control gives it alone, a standing
    # vehicle that is to slow down keeps its brake on
    from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
    from b2d_data.sim.api import ActorKind, ActorState
    from b2d_data.sim.builtin.lane_following import speed_control, speed_controls

    def car(type_id: str, speed: float) -> ActorState:
        return ActorState(id=1, type_id=type_id, kind=ActorKind.VEHICLE, transform=Transform(Location(), Rotation()),
                          velocity=Vector3D(speed, 0.0, 0.0), angular_velocity=Vector3D(), acceleration=Vector3D(),
                          bounding_box=BoundingBox(Location(), Location(2.0, 1.0, 0.8)), semantic_tags=(14,))

    types = ["vehicle.lincoln.mkz_2020", "vehicle.tesla.model3", "vehicle.unknown.kart"]
    rng = np.random.default_rng(2)
    actors = [car(types[k % 3], float(rng.uniform(-1.0, 30.0))) for k in range(60)]
    actors += [car(types[0], 0.0), car(types[1], 0.02)]
    accels = rng.uniform(-9.0, 4.0, len(actors)).tolist()
    accels[-2:] = [-1.0, 0.0]
    speeds = [a.velocity.x for a in actors]
    together = speed_controls(actors, accels, speeds)
    assert together == [speed_control(a, acc, speed=v) for a, acc, v in zip(actors, accels, speeds)]
    assert together[-2:] == [(0.0, 1.0), (0.0, 1.0)]
    assert speed_controls(actors[:3], accels[:3], speeds[:3], hold_when_stopped=False) == [
        speed_control(a, acc, hold_when_stopped=False, speed=v) for a, acc, v in zip(actors[:3], accels[:3], speeds[:3])]


def test_batch_arrays_of_the_driven_vehicles():
    # the padded per-vehicle arrays the traffic driver works on, worked out by hand: a vehicle 0.3 m past the first
    # point of a straight 10-point path (and 0.2 m beside it) heading along it at 5 m/s (plus 1 m/s sideways), and
    # one whose path is a single point
    from types import SimpleNamespace

    from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
    from b2d_data.sim.api import ActorKind, ActorState
    from b2d_data.sim.builtin.lane_following import DrivingAgent, LanePath, _Batch

    def wp(x: float, y: float) -> SimpleNamespace:
        return SimpleNamespace(transform=Transform(Location(x, y, 0.0), Rotation(yaw=90.0 if y else 0.0)),
                               lane_width=3.5)

    def car(actor_id: int, x: float, y: float, yaw: float, velocity: tuple[float, float]) -> ActorState:
        return ActorState(id=actor_id, type_id="vehicle.tesla.model3", kind=ActorKind.VEHICLE,
                          transform=Transform(Location(x, y, 0.0), Rotation(yaw=yaw)),
                          velocity=Vector3D(*velocity, 0.0), angular_velocity=Vector3D(), acceleration=Vector3D(),
                          bounding_box=BoundingBox(Location(), Location(2.4, 1.0, 0.8)), semantic_tags=(14,))

    agents = [DrivingAgent(1, LanePath.from_waypoints([wp(float(i), 0.0) for i in range(10)]), 8.0),
              DrivingAgent(2, LanePath.from_waypoints([wp(50.0, 7.0)]), 8.0)]
    actors = [car(1, 0.3, 0.2, 0.0, (5.0, 1.0)), car(2, 50.0, 9.0, 90.0, (0.0, 3.0))]
    batch = _Batch(actors, agents, 50)
    assert batch.count.tolist() == [10, 1] and batch.xy.shape == (2, 10, 2)
    assert batch.pos.tolist() == [[0.3, 0.2], [50.0, 9.0]]
    assert batch.speed == pytest.approx([5.0, 3.0]) and batch.half.tolist() == [[2.4, 1.0], [2.4, 1.0]]
    assert batch.s_self == pytest.approx([0.3, 0.0])
    assert batch.s[0] == pytest.approx(np.arange(10) - 0.3)
    assert batch.s[1, 0] == 0.0 and (batch.s[1, 1:] == _Batch.FAR).all() and (batch.xy[1, 1:] == _Batch.FAR).all()
    assert batch.path_yaw[1, 0] == pytest.approx(math.pi / 2)
    _, _, arc, _ = agents[0].path.arrays()
    assert arc.tolist() == list(range(10)) and not arc.flags.writeable
