"""The builtin world on a flat stand-in town: registry, errors, motion, collisions, determinism."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from b2d_data.format.transform import Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import preset
from b2d_data.sim.api import (
    FIXED_DELTA_SECONDS,
    ActorKind,
    ActorSpec,
    Simulator,
    SimulatorError,
    SpawnError,
    VehicleControl,
    VehicleDoor,
    WalkerControl,
)
from b2d_data.sim.builtin.world import DOOR_OPEN_WIDTH, BuiltinSimulator

CAR = ActorSpec("vehicle.lincoln.mkz_2020", role_name="hero")
OTHER = ActorSpec("vehicle.tesla.model3", role_name="other")


def _at(x: float, y: float = 0.0, yaw: float = 0.0) -> Transform:
    return Transform(Location(x, y, 0.0), Rotation(yaw=yaw))


def test_implements_the_protocol(flat_world):
    assert isinstance(flat_world, Simulator)
    s = flat_world.snapshot()
    assert (s.frame, s.timestamp, dict(s.actors), list(s.collisions)) == (0, 0.0, {}, [])


def test_ids_increase_and_snapshot_reports_actors(flat_world):
    a = flat_world.spawn_actor(CAR, _at(0))
    b = flat_world.spawn_actor(OTHER, _at(20))
    assert b > a
    s = flat_world.tick()
    assert (s.frame, s.timestamp) == (1, pytest.approx(FIXED_DELTA_SECONDS))
    hero = s.hero()
    assert hero.id == a and hero.kind is ActorKind.VEHICLE and hero.base_type == "car"
    assert hero.bounding_box.extent.x == pytest.approx(2.451) and hero.semantic_tags == (14,)
    assert hero.attributes["role_name"] == "hero"
    with pytest.raises(dataclasses.FrozenInstanceError):
        hero.role_name = "x"  # type: ignore[misc]
    flat_world.destroy_actor(b)
    c = flat_world.spawn_actor(OTHER, _at(40))
    assert c > b and b not in flat_world.tick().actors


def test_spawn_on_top_of_another_actor(flat_world):
    a = flat_world.spawn_actor(CAR, _at(0))
    with pytest.raises(SpawnError, match=f"overlaps actor {a}"):
        flat_world.spawn_actor(OTHER, _at(3.0))  # 2.45 + 2.40 > 3 m apart: the boxes overlap
    assert flat_world.try_spawn_actor(OTHER, _at(3.0)) is None
    assert flat_world.try_spawn_actor(OTHER, _at(5.0)) is not None  # 4.85 < 5: free


def test_errors_name_what_is_wrong(flat_world):
    with pytest.raises(SpawnError, match="vehicle.lincoln.mkz_2020"):
        flat_world.spawn_actor(ActorSpec("vehicle.lincoln.mkz2020"), _at(0))
    with pytest.raises(SimulatorError, match="12345"):
        flat_world.destroy_actor(12345)
    with pytest.raises(SimulatorError, match="999"):
        flat_world.apply_control(999, VehicleControl())
    car = flat_world.spawn_actor(CAR, _at(0))
    with pytest.raises(SimulatorError, match="WalkerControl"):
        flat_world.apply_control(car, WalkerControl())
    with pytest.raises(SimulatorError, match="attach_rig"):
        flat_world.read_sensors()
    with pytest.raises(SpawnError, match="77"):
        flat_world.spawn_actor(CAR, _at(50), attach_to=77)


def test_throttle_and_velocity_bookkeeping(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    flat_world.apply_control(car, VehicleControl(throttle=1.0))
    prev = flat_world.tick().actors[car]
    s = flat_world.tick()
    now = s.actors[car]
    # the origin moved by the speed reported at the previous tick (positions use the speed before the update)
    assert now.location.x - prev.location.x == pytest.approx(prev.velocity.x * FIXED_DELTA_SECONDS)
    # acceleration is the velocity change over the tick, as an IMU would integrate it
    assert now.acceleration.x == pytest.approx((now.velocity.x - prev.velocity.x) / FIXED_DELTA_SECONDS)
    assert now.control == VehicleControl(throttle=1.0)
    assert now.forward_speed() == pytest.approx(now.velocity.x)


def test_steering_turns_right_and_reports_yaw_rate(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    flat_world.set_target_velocity(car, Vector3D(8.0, 0.0, 0.0))
    flat_world.tick()
    flat_world.apply_control(car, VehicleControl(throttle=0.3, steer=0.3))
    for _ in range(20):
        prev = flat_world.snapshot().actors[car]
        s = flat_world.tick()
    now = s.actors[car]
    assert now.transform.rotation.yaw > 10.0 and now.location.y > 0.0  # positive steer: clockwise, toward +y
    dyaw = now.transform.rotation.yaw - prev.transform.rotation.yaw
    assert now.angular_velocity.z == pytest.approx(dyaw / FIXED_DELTA_SECONDS)


def test_target_velocity_lasts_one_tick(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    flat_world.set_target_velocity(car, Vector3D(10.0, 0.0, 0.0))
    s = flat_world.tick()
    assert s.actors[car].location.x == pytest.approx(0.5) and s.actors[car].velocity.x == pytest.approx(10.0)
    s = flat_world.tick()  # then it coasts from 10 m/s: 0.5 m more, slightly slower
    assert s.actors[car].location.x == pytest.approx(1.0)
    assert 9.9 < s.actors[car].speed() < 10.0


def test_physics_off_stays_put_and_props_never_move(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    cone = flat_world.spawn_actor(ActorSpec("static.prop.constructioncone"), _at(10))
    flat_world.set_simulate_physics(car, False)
    flat_world.apply_control(car, VehicleControl(throttle=1.0))
    flat_world.set_target_velocity(cone, Vector3D(5.0, 0.0, 0.0))
    for _ in range(10):
        s = flat_world.tick()
    assert s.actors[car].location.x == 0.0 and s.actors[car].is_static
    assert s.actors[cone].location.x == 10.0 and s.actors[cone].kind is ActorKind.PROP
    flat_world.set_transform(car, _at(30, 3.0, 45.0))
    s = flat_world.tick()
    assert (s.actors[car].location.x, s.actors[car].location.y) == (30.0, 3.0)


def test_walker_moves_as_commanded(flat_world):
    walker = flat_world.spawn_actor(ActorSpec("walker.pedestrian.0003"), _at(0))
    flat_world.apply_control(walker, WalkerControl(direction=Vector3D(0.0, 2.0, 0.0), speed=1.5))
    for _ in range(20):  # 1 s
        s = flat_world.tick()
    w = s.actors[walker]
    assert (w.location.x, w.location.y) == pytest.approx((0.0, 1.5))
    assert w.transform.rotation.yaw == pytest.approx(90.0)  # faces its walking direction
    assert w.velocity.y == pytest.approx(1.5) and w.kind is ActorKind.WALKER
    assert w.attributes["age"] == "adult"


def test_open_door_widens_the_box(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    flat_world.open_door(car, VehicleDoor.FL)
    box = flat_world.tick().actors[car].bounding_box
    # left (−y) side pushed out by the door: half width + half the door, centre shifted left by half the door
    assert box.extent.y == pytest.approx(1.064 + DOOR_OPEN_WIDTH / 2)
    assert box.location.y == pytest.approx(-DOOR_OPEN_WIDTH / 2)
    # a car 0.5 m left of the closed box's side now overlaps the open door
    with pytest.raises(SpawnError):
        flat_world.spawn_actor(ActorSpec("vehicle.audi.a2"), _at(0.0, -1.064 - 0.5 - 0.894))
    flat_world.open_door(car, VehicleDoor.ALL)
    s = flat_world.tick()
    assert s.actors[car].bounding_box.extent.y == pytest.approx(1.064 + DOOR_OPEN_WIDTH)
    assert set(s.actors[car].open_doors) == {VehicleDoor.FL, VehicleDoor.FR, VehicleDoor.RL, VehicleDoor.RR}
    bike = flat_world.spawn_actor(ActorSpec("vehicle.bh.crossbike"), _at(30))
    with pytest.raises(SimulatorError, match="no doors"):
        flat_world.open_door(bike, VehicleDoor.FL)


def test_light_state_and_weather(flat_world):
    police = flat_world.spawn_actor(ActorSpec("vehicle.dodge.charger_police_2020"), _at(0))
    flat_world.set_light_state(police, "Special1")
    flat_world.set_weather(preset(3))
    s = flat_world.tick()
    assert s.actors[police].light_state == "Special1" and s.weather == preset(3)


def test_head_on_collision_reports_both_and_stops_them(flat_world):
    a = flat_world.spawn_actor(CAR, _at(0))
    b = flat_world.spawn_actor(OTHER, _at(12, 0.0, 180.0))
    cone = flat_world.spawn_actor(ActorSpec("static.prop.trafficcone01"), _at(0, 10))
    events = []
    for _ in range(40):
        flat_world.set_target_velocity(a, Vector3D(5.0, 0.0, 0.0))
        flat_world.set_target_velocity(b, Vector3D(-5.0, 0.0, 0.0))
        s = flat_world.tick()
        events += list(s.collisions)
    first = [e for e in events if e.frame == events[0].frame]
    assert {(e.actor_id, e.other_id, e.other_type_id) for e in first} == {
        (a, b, "vehicle.tesla.model3"), (b, a, "vehicle.lincoln.mkz_2020")}
    # 12 m apart, half lengths 2.451 + 2.396: the boxes meet after (12 − 4.847) / 10 m/s = 0.72 s
    assert first[0].frame == math.ceil((12.0 - 2.451 - 2.396) / 10.0 / FIXED_DELTA_SECONDS)
    # the forced velocity keeps pushing them, but they are never driven through each other
    end = flat_world.snapshot().actors
    assert end[b].location.x - end[a].location.x > 2.451 + 2.396 - 0.6
    assert not [e for e in events if cone in (e.actor_id, e.other_id)]


def test_driving_into_a_prop_stops_the_car(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    barrier = flat_world.spawn_actor(ActorSpec("static.prop.streetbarrier"), _at(8, 0, 90))
    flat_world.apply_control(car, VehicleControl(throttle=0.6))
    hits = []
    for _ in range(100):
        s = flat_world.tick()
        hits += [e for e in s.collisions if e.actor_id == car]
    assert hits and hits[0].other_id == barrier and hits[0].other_type_id == "static.prop.streetbarrier"
    assert s.actors[car].speed() < 0.5
    assert s.actors[car].location.x < 8.0 - 0.19 - 2.451 + 0.6  # never through the barrier
    assert hits[0].normal_impulse.x < 0.0  # pushed back


def test_debris_does_not_collide(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    flat_world.spawn_actor(ActorSpec("static.prop.dirtdebris01"), _at(6))
    for _ in range(30):
        flat_world.set_target_velocity(car, Vector3D(6.0, 0.0, 0.0))
        assert not flat_world.tick().collisions


def test_attached_actor_follows_its_parent(flat_world):
    car = flat_world.spawn_actor(CAR, _at(0))
    rider = flat_world.spawn_actor(ActorSpec("walker.pedestrian.0001"), Transform(Location(0, 0, 2.0)),
                                   attach_to=car)
    flat_world.set_target_velocity(car, Vector3D(4.0, 0.0, 0.0))
    s = flat_world.tick()
    assert s.actors[rider].parent_id == car
    assert (s.actors[rider].location.x, s.actors[rider].location.z) == pytest.approx((0.2, 2.0))
    assert not s.collisions
    flat_world.destroy_actor(car)
    assert rider not in flat_world.tick().actors



def _scripted_run(town, seed: int, ticks: int = 200):
    world = BuiltinSimulator(town, seed=seed)
    rng = np.random.default_rng(seed)
    ids = [world.spawn_actor(CAR, _at(0))]
    for k in range(1, 6):
        ids.append(world.spawn_actor(OTHER, _at(15.0 * k, rng.uniform(-3, 3), rng.uniform(-30, 30))))
    walker = world.spawn_actor(ActorSpec("walker.pedestrian.0005"), _at(20, 12))
    out = []
    for t in range(ticks):
        for vid in ids:
            world.apply_control(vid, VehicleControl(throttle=float(rng.uniform(0, 1)), steer=float(rng.uniform(-1, 1)),
                                                    brake=float(rng.uniform(0, 0.2))))
        world.apply_control(walker, WalkerControl(Vector3D(float(rng.normal()), float(rng.normal()), 0.0), 1.4))
        out.append(world.tick())
    world.close()
    return out


def test_same_seed_same_snapshots(flat_town):
    a = _scripted_run(flat_town, 5)
    b = _scripted_run(flat_town, 5)
    assert a == b
    c = _scripted_run(flat_town, 6)
    assert a[-1] != c[-1]


def test_collisions_see_actors_spawned_frozen_and_destroyed_between_ticks(flat_world):
    # the colliding movers are remembered between ticks: a car spawned, frozen or destroyed later must count as the
    # world is now (a frozen car stands 8 m ahead of another driving at it at 5 m/s: they meet after ~0.6 s)
    a = flat_world.spawn_actor(CAR, _at(0))
    for _ in range(5):
        flat_world.tick()
    b = flat_world.spawn_actor(OTHER, _at(8.0))
    flat_world.set_simulate_physics(b, False)
    hits = []
    for _ in range(20):
        flat_world.set_target_velocity(a, Vector3D(5.0, 0.0, 0.0))
        hits += [(e.actor_id, e.other_id) for e in flat_world.tick().collisions]
    assert (a, b) in hits and (b, a) in hits
    flat_world.destroy_actor(b)
    c = flat_world.spawn_actor(OTHER, _at(20.0))
    late = []
    for _ in range(80):
        flat_world.set_target_velocity(a, Vector3D(5.0, 0.0, 0.0))
        late += [(e.actor_id, e.other_id) for e in flat_world.tick().collisions]
    assert (a, c) in late and not [h for h in late if b in h]
