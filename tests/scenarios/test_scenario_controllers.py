"""Scenario actor controllers: path geometry and speed laws by hand, then driving in the builtin simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.road_geometry import heading_change, lane_walk
from b2d_data.scenarios.controllers import (
    ConstantVelocityAgent,
    LaneFollowingAgent,
    PathTrack,
    WalkerController,
    allowed_speed,
    leader_gap,
    pure_pursuit_steer,
    speed_control,
)
from b2d_data.sim.api import ActorKind, ActorSpec, ActorState, Snapshot
from b2d_data.sim.builtin.world import BuiltinSimulator


def car(
    x: float,
    y: float,
    yaw: float = 0.0,
    vx: float = 0.0,
    vy: float = 0.0,
    actor_id: int = 1,
    half_length: float = 2.0,
    half_width: float = 1.0,
) -> ActorState:
    """A car with a centred box of the given half extents."""
    return ActorState(
        id=actor_id, type_id="vehicle.audi.a2", kind=ActorKind.VEHICLE,
        transform=Transform(Location(x, y, 0.0), Rotation(yaw=yaw)), velocity=Vector3D(vx, vy, 0.0),
        angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.7), Location(half_length, half_width, 0.7)), semantic_tags=(14,),
    )  # fmt: skip


def snapshot_of(*actors: ActorState) -> Snapshot:
    return Snapshot(frame=0, timestamp=0.0, actors={a.id: a for a in actors}, traffic_lights={}, traffic_signs={},
                    collisions=(), weather=ROUTE_DEFAULT)  # fmt: skip


L_PATH = PathTrack(np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]]))


def test_path_track_projection_and_sampling():
    assert L_PATH.length == pytest.approx(20.0)
    seg, s, lateral = L_PATH.project(5.0, 1.0)
    # heading east: CARLA's right is +y
    assert (seg, s, lateral) == (0, pytest.approx(5.0), pytest.approx(1.0))
    seg, s, lateral = L_PATH.project(11.0, 5.0)
    # heading south (+y): right is -x, so x = 11 is 1 m to the left
    assert (seg, s, lateral) == (1, pytest.approx(15.0), pytest.approx(-1.0))
    x, y, yaw = L_PATH.point_at(15.0)
    assert (x, y, yaw) == (pytest.approx(10.0), pytest.approx(5.0), pytest.approx(math.pi / 2))
    assert L_PATH.point_at(99.0)[:2] == (pytest.approx(10.0), pytest.approx(10.0))
    with pytest.raises(ValueError):
        PathTrack(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0]]))


def test_allowed_speed_and_speed_control():
    assert allowed_speed(10.0, 4.0, 2.0) == pytest.approx(8.0)  # sqrt(2 * 4 * 8)
    assert allowed_speed(1.0, 4.0, 2.0) == 0.0
    command, control = speed_control(10.0, 0.0, accel=3.0, decel=8.0)
    assert command == pytest.approx(9.6)  # 8 m/s² for one 0.05 s tick
    assert (control.throttle, control.brake) == (0.0, pytest.approx(1.0))
    command, control = speed_control(5.0, 10.0, accel=3.0, decel=8.0)
    assert command == pytest.approx(5.15)
    assert control.throttle == 1.0  # 3 m/s² needs more than PDM-Lite's 0.563 m/s² per unit throttle
    command, control = speed_control(5.0, 5.01, accel=3.0, decel=8.0)
    assert command == pytest.approx(5.01)
    assert control.throttle == pytest.approx(0.2 / 0.56338)
    command, control = speed_control(5.0, 5.0, accel=3.0, decel=8.0)
    assert (command, control.throttle, control.brake) == (5.0, 0.0, 0.0)  # cruising reports no pedal


def test_pure_pursuit_steers_toward_the_path():
    straight = PathTrack(np.array([[0.0, 0.0, 0.0], [50.0, 0.0, 0.0]]))
    assert pure_pursuit_steer(car(0, 0), straight, 0.0, 5.0) == pytest.approx(0.0)
    assert pure_pursuit_steer(car(0, -2.0), straight, 0.0, 5.0) > 0.0  # path to the right: steer right
    assert pure_pursuit_steer(car(0, 2.0), straight, 0.0, 5.0) < 0.0


def test_leader_gap_counts_boxes_reaching_into_the_path():
    straight = PathTrack(np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]]))
    me = car(0, 0, actor_id=1)
    ahead = car(15.0, 0.0, actor_id=2)
    # rear corners of the other car at x = 13; my front at x = 2
    assert leader_gap(snapshot_of(me, ahead), me, straight, 0.0, 30.0) == (pytest.approx(11.0), 2)
    beside = car(15.0, 3.5, actor_id=3)  # corners at lateral 2.5 > 1 + 0.3
    assert leader_gap(snapshot_of(me, beside), me, straight, 0.0, 30.0) == (math.inf, None)
    assert leader_gap(snapshot_of(me, ahead), me, straight, 0.0, 5.0)[1] is None  # beyond the horizon
    assert leader_gap(snapshot_of(me, ahead), me, straight, 0.0, 30.0, ignore=[2])[1] is None
    cutting_in = car(15.0, 3.5, vy=-2.5, actor_id=4)  # in 1 s its near corners are at lateral 0
    gap, other = leader_gap(snapshot_of(me, cutting_in), me, straight, 0.0, 30.0, predict=1.0)
    assert other == 4 and gap == pytest.approx(11.0)


def test_leader_gap_lateral_margin():
    # A car waiting to cross with its nose 1.2 m from the path centre: my half width 1.0 plus the default 0.3 m margin
    # (1.3 m) counts it, a margin of 0 (1.0 m: only a box that really reaches into my swept path) does not.
    straight = PathTrack(np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]]))
    me = car(0, 0, actor_id=1)
    waiting = car(15.0, 3.2, yaw=-90.0, actor_id=2)  # facing the path: its front corners at lateral 3.2 - 2 = 1.2
    assert leader_gap(snapshot_of(me, waiting), me, straight, 0.0, 30.0)[1] == 2
    assert leader_gap(snapshot_of(me, waiting), me, straight, 0.0, 30.0, lateral_margin=0.0) == (math.inf, None)


# ------------------------------------------------------------------------------------------------ in the simulator


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


@pytest.fixture(scope="module")
def straight_lane(town):
    """A driving lane point with 80 m of straight lane ahead."""
    for wp in town.generate_waypoints(20.0):
        if wp.is_junction:
            continue
        ahead = lane_walk(wp, 80.0)
        if len(ahead) > 80 and not any(w.is_junction for w in ahead) and heading_change(ahead) < 2.0:
            return ahead
    pytest.fail("the generated town has no straight 80 m lane")


def _spawn_car(sim: BuiltinSimulator, wp) -> int:
    t = wp.transform
    return sim.spawn_actor(ActorSpec("vehicle.audi.a2", role_name="scenario"),
                           Transform(Location(t.location.x, t.location.y, t.location.z + 0.2), t.rotation))  # fmt: skip


def test_constant_velocity_agent_holds_speed_on_its_path(town, straight_lane):
    with BuiltinSimulator(town, seed=0) as sim:
        actor_id = _spawn_car(sim, straight_lane[0])
        agent = ConstantVelocityAgent(sim, actor_id, PathTrack.from_waypoints(straight_lane), 8.0)
        snap = sim.tick()
        for _ in range(40):  # 2 s
            agent.run_step(snap)
            snap = sim.tick()
        state = snap.actors[actor_id]
        assert state.speed() == pytest.approx(8.0, abs=0.05)
        _, s, lateral = agent.path.project(state.location.x, state.location.y)
        assert abs(lateral) < 0.2
        assert s == pytest.approx(8.0 * 2.0, abs=0.6)
        assert not agent.done


def test_constant_velocity_agent_stops_behind_a_vehicle_and_resumes(town, straight_lane):
    with BuiltinSimulator(town, seed=0) as sim:
        follower = _spawn_car(sim, straight_lane[0])
        leader = _spawn_car(sim, straight_lane[30])
        agent = ConstantVelocityAgent(sim, follower, PathTrack.from_waypoints(straight_lane), 10.0,
                                      detect_vehicles=True, base_threshold=10.0, speed_ratio=0.15)  # fmt: skip
        snap = sim.tick()
        for _ in range(200):
            agent.run_step(snap)
            snap = sim.tick()
        gap = snap.actors[leader].location.distance_2d(snap.actors[follower].location)
        assert snap.actors[follower].speed() < 0.1 and agent.blocked_by == leader
        assert 4.0 < gap < 10.0  # stopped 2 m short of the leader's box (two 3.7 m cars)
        sim.destroy_actor(leader)
        snap = sim.tick()
        for _ in range(40):
            agent.run_step(snap)
            snap = sim.tick()
        assert snap.actors[follower].speed() > 5.0


def test_lane_following_agent_keeps_its_offset_and_stops_after_its_distance(town, straight_lane):
    with BuiltinSimulator(town, seed=0) as sim:
        actor_id = _spawn_car(sim, straight_lane[0])
        agent = LaneFollowingAgent(sim, actor_id, straight_lane[0], 5.0, lateral_offset=0.8, max_distance=30.0)
        snap = sim.tick()
        for _ in range(300):
            agent.run_step(snap)
            snap = sim.tick()
        state = snap.actors[actor_id]
        lane = PathTrack.from_waypoints(straight_lane)
        _, s, lateral = lane.project(state.location.x, state.location.y)
        assert s == pytest.approx(agent.travelled, abs=1.5)
        assert agent.done and state.speed() < 0.1
        assert 30.0 <= agent.travelled < 33.0
        assert lateral == pytest.approx(0.8, abs=0.25)


def test_walker_controller_walks_its_distance(town, straight_lane):
    with BuiltinSimulator(town, seed=0) as sim:
        t = straight_lane[10].transform
        pose = Transform(Location(t.location.x, t.location.y, t.location.z + 1.0), t.rotation)
        walker = sim.spawn_actor(ActorSpec("walker.pedestrian.0001", role_name="scenario"), pose)
        yaw = math.radians(t.rotation.yaw)
        ctrl = WalkerController(sim, walker, Vector3D(math.cos(yaw), math.sin(yaw), 0.0), 2.0, 3.0)
        snap = sim.snapshot()
        ticks = 0
        while not ctrl.done and ticks < 100:
            ctrl.run_step(snap)
            snap = sim.tick()
            ticks += 1
        # 3 m at 2 m/s: 30 ticks of motion plus the first tick that only starts it
        assert 30 <= ticks <= 33
        assert ctrl.travelled == pytest.approx(3.0, abs=0.15)
        with pytest.raises(ValueError):
            WalkerController(sim, walker, Vector3D(0.0, 0.0, 1.0), 1.0, 1.0)
