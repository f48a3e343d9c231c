"""The world on a small hand-written OpenDRIVE road: vehicles and walkers follow its surface."""

from __future__ import annotations

import math

import pytest

from b2d_data.format.transform import Location, Transform, Vector3D
from b2d_data.maps import load_opendrive
from b2d_data.sim.api import ActorSpec, VehicleControl, WalkerControl
from b2d_data.sim.builtin.world import BuiltinSimulator

# A 200 m straight road along +x climbing 5 % (elevation a = 0, b = 0.05), one 3.5 m lane each way, then on
# the right of the forward lane a 2.5 m parking lane and a 2 m sidewalk.
SLOPE_XODR = """<?xml version="1.0" standalone="yes"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="4" name="Slope" version="1.00" north="0" south="0" east="0" west="0"/>
  <road name="r" length="200.0" id="1" junction="-1">
    <link/>
    <planView>
      <geometry s="0.0" x="0.0" y="0.0" hdg="0.0" length="200.0"><line/></geometry>
    </planView>
    <elevationProfile><elevation s="0.0" a="0.0" b="0.05" c="0.0" d="0.0"/></elevationProfile>
    <lanes>
      <laneSection s="0.0">
        <left>
          <lane id="1" type="driving" level="false"><link/><width sOffset="0.0" a="3.5" b="0" c="0" d="0"/></lane>
        </left>
        <center><lane id="0" type="driving" level="false"><link/></lane></center>
        <right>
          <lane id="-1" type="driving" level="false"><link/><width sOffset="0.0" a="3.5" b="0" c="0" d="0"/></lane>
          <lane id="-2" type="parking" level="false"><link/><width sOffset="0.0" a="2.5" b="0" c="0" d="0"/></lane>
          <lane id="-3" type="sidewalk" level="false"><link/><width sOffset="0.0" a="2.0" b="0" c="0" d="0"/></lane>
        </right>
      </laneSection>
    </lanes>
  </road>
</OpenDRIVE>
"""


@pytest.fixture(scope="module")
def slope_town(tmp_path_factory):
    path = tmp_path_factory.mktemp("xodr") / "Slope.xodr"
    path.write_text(SLOPE_XODR)
    return load_opendrive(path)


def test_vehicle_climbs_the_slope(slope_town):
    world = BuiltinSimulator(slope_town, seed=0)
    # lane −1 is on the right of the reference line: +y in CARLA's frame (OpenDRIVE y flipped)
    car = world.spawn_actor(ActorSpec("vehicle.tesla.model3"), Transform(Location(20.0, 1.75, 3.0)))
    s = world.tick()
    assert s.actors[car].location.z == pytest.approx(0.05 * 20.0, abs=0.02)  # put on the road, not left at 3 m
    world.apply_control(car, VehicleControl(throttle=0.6))
    for _ in range(100):
        s = world.tick()
    a = s.actors[car]
    assert a.location.x > 30.0
    assert a.location.z == pytest.approx(0.05 * a.location.x, abs=0.02)
    assert a.transform.rotation.pitch == pytest.approx(math.degrees(math.atan(0.05)), abs=0.05)
    # the reported velocity climbs with the road (vz = 5 % of vx): the speedometer reads along the pitch
    assert a.velocity.z == pytest.approx(0.05 * a.velocity.x, rel=0.05)
    assert a.forward_speed() == pytest.approx(a.speed(), rel=1e-3)
    world.close()


def test_walker_stands_on_the_sidewalk(slope_town):
    world = BuiltinSimulator(slope_town, seed=0)
    walker = world.spawn_actor(ActorSpec("walker.pedestrian.0002"), Transform(Location(50.0, 7.0, 0.0)))
    world.apply_control(walker, WalkerControl(direction=Vector3D(1.0, 0.0, 0.0), speed=1.4))
    for _ in range(40):
        s = world.tick()
    w = s.actors[walker]
    assert w.location.x == pytest.approx(52.8)
    assert w.location.y == pytest.approx(7.0)
    # the walker origin is its capsule centre: half its height above the surface
    assert w.location.z == pytest.approx(0.05 * w.location.x + w.bounding_box.extent.z, abs=0.02)
    world.close()


def test_stock_town_loads_by_name():
    world = BuiltinSimulator("Town01", seed=0)
    s = world.snapshot()
    assert world.map.name == "Town01" and len(s.traffic_lights) == 36
    light = next(iter(s.traffic_lights.values()))
    assert light.stop_waypoints and light.id in s.actors and s.actors[light.id].type_id == "traffic.traffic_light"
    world.close()


def test_parked_cars_fill_the_parking_lane(slope_town):
    world = BuiltinSimulator(slope_town, seed=4)
    start = slope_town.get_waypoint(Location(10.0, 1.75, 0.0))
    route = [start] + start.next_until_lane_end(1.0)
    ego = world.spawn_actor(ActorSpec("vehicle.lincoln.mkz_2020", role_name="hero"), start.transform)
    world.background.start(ego, route)
    parked = world.background.spawn_parked_cars(spacing=7.0, probability=1.0)
    s = world.tick()
    assert len(parked) >= 20  # every 7 m of the 200 m lane that no car overlaps
    for pid in parked:
        a = s.actors[pid]
        assert a.type_id == "static.prop.mesh" and a.is_static and a.base_type == "car"
        assert a.location.y == pytest.approx(3.5 + 1.25, abs=0.01)  # parking-lane centre
    world.close()


def test_a_light_pole_is_an_obstacle():
    world = BuiltinSimulator("Town01", seed=0)
    light = next(iter(world.snapshot().traffic_lights.values()))
    pole = light.transform.location
    car = world.spawn_actor(ActorSpec("vehicle.audi.a2"), Transform(Location(pole.x - 6.0, pole.y, pole.z)))
    hits = []
    for _ in range(40):
        world.set_target_velocity(car, Vector3D(4.0, 0.0, 0.0))
        hits += [e for e in world.tick().collisions if e.actor_id == car]
    assert hits and hits[0].other_id == light.id and hits[0].other_type_id == "traffic.traffic_light"
    world.close()
