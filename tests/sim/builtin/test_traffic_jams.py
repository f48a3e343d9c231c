"""Regressions for background-traffic jams found by ``scripts/traffic_soak.py`` (Town01 with lights frozen green,
Town07's stop signs):

- a car whose junction exit is full rolled into the junction without a reservation and stood across it;
- junction reservations outlived the vehicles holding them (destroyed cars, the ego once through the junction);
- the ego held every lane of a junction, also those of traffic it waited for;
- cars stopped for a stop sign inside the junction, at a stop line the map puts there.
"""

from __future__ import annotations

import math

import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.sim.api import ActorSpec, TrafficLightState, VehicleControl
from b2d_data.sim.builtin.lane_following import ANY_LANE, DriverOutput, DrivingAgent, LanePath, TrafficDriver
from b2d_data.sim.builtin.world import BuiltinSimulator

CAR = "vehicle.lincoln.mkz_2020"


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town01.xodr")


def green_world(town) -> BuiltinSimulator:
    world = BuiltinSimulator(town, seed=0)
    for light_id in world.snapshot().traffic_lights:
        world.set_traffic_light_state(light_id, TrafficLightState.GREEN, freeze=True)
    return world


def approach(town):
    """Spawn point 6 of Town01 (road 1, lane −1): 23 m of lane, then a 23 m junction (first branch taken)."""
    start = town.get_waypoint(town.get_spawn_points()[6].location)
    path = LanePath(start, chooser=lambda options: 0)
    path.extend()
    record = path.first_junction()
    assert record is not None and record[1] > 15 and record[2] - record[1] > 15
    return start, path, record


def drive(world: BuiltinSimulator, driver: TrafficDriver, agents: list[DrivingAgent], ticks: int
          ) -> dict[int, DriverOutput]:
    out: dict[int, DriverOutput] = {}
    for _ in range(ticks):
        s = world.snapshot()
        for agent in agents:
            loc = s.actors[agent.id].location
            agent.path.advance(loc.x, loc.y)
        out = driver.plan(s, agents)
        for vid, o in out.items():
            world.apply_control(vid, o.control)
        world.tick()
    return out


def test_a_car_waits_at_the_entry_while_the_junction_exit_is_full(town01):
    world = green_world(town01)
    start, path, (_, _, exit_, _) = approach(town01)
    # a standing car 4 m past the exit: its rear is ~1.6 m past it, so a follower 10 m behind it (IDM's gap)
    # would stand inside the junction, across the lanes of the other entries
    exit_wp = path.waypoints[exit_]
    blocker = world.spawn_actor(ActorSpec(CAR), path.waypoints[exit_ + 4].transform)
    world.apply_control(blocker, VehicleControl(brake=1.0))
    car = world.spawn_actor(ActorSpec(CAR), start.transform)
    agent = DrivingAgent(car, path, target_speed=8.0)
    driver = TrafficDriver(town01)
    world.tick()  # new actors appear in the snapshot of the next tick
    out = drive(world, driver, [agent], 300)  # 15 s
    s = world.snapshot()
    actor = s.actors[car]
    yaw = math.radians(actor.transform.rotation.yaw)
    front = Location(actor.location.x + math.cos(yaw) * actor.bounding_box.extent.x,
                     actor.location.y + math.sin(yaw) * actor.bounding_box.extent.x, actor.location.z)
    assert actor.speed() < 0.1
    assert out[car].reason == "exit_blocked"
    assert not town01.get_waypoint(front).is_junction  # it waits in front of the junction, not inside it
    assert car not in driver.arbiter.holders
    # once the exit clears it drives through
    world.destroy_actor(blocker)
    drive(world, driver, [agent], 200)
    loc = world.snapshot().actors[car].location
    forward = exit_wp.transform.get_forward_vector()
    past = (loc.x - exit_wp.transform.location.x) * forward.x + (loc.y - exit_wp.transform.location.y) * forward.y
    assert past > 0.0


def test_reservations_end_with_their_holders(town01):
    world = green_world(town01)
    _, path, (junction_id, entry, _, _) = approach(town01)
    inside = path.waypoints[entry + 3]
    car = world.spawn_actor(ActorSpec(CAR), inside.transform)
    agent = DrivingAgent(car, LanePath(inside, chooser=lambda options: 0), target_speed=0.0)
    driver = TrafficDriver(town01)
    driver.plan(world.tick(), [agent])
    assert driver.arbiter.holders[car][0] == junction_id  # inside a junction: it holds its lane
    # recycled while inside: the next plan no longer lists it, and its lane is free again
    world.destroy_actor(car)
    driver.plan(world.tick(), [])
    assert car not in driver.arbiter.holders
    # an outside vehicle handed in as holding the whole junction (the ego) holds it only while handed in
    driver.plan(world.tick(), [], extra_inside={4242: (junction_id, (ANY_LANE,))})
    assert driver.arbiter.holders[4242] == (junction_id, (ANY_LANE,))
    driver.plan(world.tick(), [], extra_inside={})
    assert 4242 not in driver.arbiter.holders


def test_the_ego_holds_its_route_lanes_through_a_junction_only_while_in_it(town01):
    world = green_world(town01)
    sp = town01.get_spawn_points()
    route = [wp for wp, _ in town01.trace_route(sp[5].location, sp[60].location)]
    first = next(i for i, wp in enumerate(route) if wp.is_junction)
    junction_id = route[first].junction_id
    ego = world.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), route[first + 2].transform)
    world.apply_control(ego, VehicleControl(brake=1.0))
    world.tick()
    world.background.start(ego, route)
    world.tick()
    exit_ = next(i for i in range(first, len(route)) if not route[i].is_junction)
    lanes = tuple(dict.fromkeys((wp.road_id, wp.section_id, wp.lane_id) for wp in route[first:exit_]))
    # background traffic gives way to the ego in there: the ego holds its route's lanes through the junction
    assert world.background.driver.arbiter.holders.get(ego) == (junction_id, lanes)
    after = route[min(exit_ + 30, len(route) - 1)]
    assert not after.is_junction
    world.set_transform(ego, Transform(after.transform.location, after.transform.rotation))
    for _ in range(2):
        world.tick()
    assert ego not in world.background.driver.arbiter.holders


@pytest.fixture(scope="module")
def town07(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town07.xodr")


def test_a_stop_sign_whose_line_lies_inside_the_junction_stops_cars_at_its_entry(town07):
    world = BuiltinSimulator(town07, seed=0)
    snapshot = world.snapshot()
    sign_ids = {info.opendrive_id: sign_id for sign_id, info in snapshot.traffic_signs.items()
                if info.type_id.startswith("traffic.stop")}
    # Town07's stop signs stop their lanes at waypoints inside the junction (and the line is half the trigger
    # box further on): the first such sign with a lane 30 m long in front of its junction
    found = None
    for signal in sorted(town07.stop_signs(), key=lambda sig: str(sig.id)):
        for stop_wp in signal.stop_waypoints:
            before = stop_wp.previous(30.0)
            if str(signal.id) in sign_ids and stop_wp.is_junction and before and not before[0].is_junction:
                found = stop_wp, before[0]
                break
        if found:
            break
    assert found is not None
    stop_wp, start = found

    def towards_the_sign(options) -> int:
        roads = [wp.road_id for wp in options]
        return roads.index(stop_wp.road_id) if stop_wp.road_id in roads else 0

    path = LanePath(start, chooser=towards_the_sign)
    path.extend()
    junction_id, _, exit_, _ = path.first_junction()
    assert junction_id == stop_wp.junction_id
    exit_wp = path.waypoints[exit_]
    car = world.spawn_actor(ActorSpec(CAR), start.transform)
    agent = DrivingAgent(car, path, target_speed=8.0)
    driver = TrafficDriver(town07)
    world.tick()  # new actors appear in the snapshot of the next tick
    drive(world, driver, [agent], 20)
    for _ in range(300):  # until it stops (a stop sign is cleared below 0.1 m/s), 15 s at most
        drive(world, driver, [agent], 1)
        if world.snapshot().actors[car].forward_speed() < 0.1:
            break
    actor = world.snapshot().actors[car]
    yaw = math.radians(actor.transform.rotation.yaw)
    front = Location(actor.location.x + math.cos(yaw) * actor.bounding_box.extent.x,
                     actor.location.y + math.sin(yaw) * actor.bounding_box.extent.x, actor.location.z)
    assert actor.forward_speed() < 0.1
    assert not town07.get_waypoint(front).is_junction  # it stops in front of the junction, not inside it
    # having stopped, it goes on through the (empty) junction
    drive(world, driver, [agent], 300)
    loc = world.snapshot().actors[car].location
    forward = exit_wp.transform.get_forward_vector()
    assert (loc.x - exit_wp.transform.location.x) * forward.x + (loc.y - exit_wp.transform.location.y) * forward.y > 0
