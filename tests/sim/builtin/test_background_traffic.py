"""Background traffic on CARLA's Town01 with an ego driving a traced route."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.maps import load_opendrive
from b2d_data.sim.api import ActorSpec, BackgroundTraffic, Snapshot
from b2d_data.sim.builtin.background_traffic import ROLE_NAME
from b2d_data.sim.builtin.lane_following import DrivingAgent, LanePath, TrafficDriver
from b2d_data.sim.builtin.world import BuiltinSimulator


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town01.xodr")


@pytest.fixture(scope="module")
def route(town01):
    sp = town01.get_spawn_points()
    return [wp for wp, _ in town01.trace_route(sp[5].location, sp[60].location)]


class Run:
    """A world with an ego that follows the route (driven like traffic, sharing the junction arbiter)."""

    def __init__(self, town, route, seed: int, speed: float = 6.0):
        self.world = BuiltinSimulator(town, seed=seed)
        self.town = town
        self.route = route
        start = route[0].transform
        self.ego = self.world.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), start)
        self.bg = self.world.background
        self.driver = TrafficDriver(town, arbiter=self.bg.driver.arbiter)
        self.agent = DrivingAgent(self.ego, LanePath.from_waypoints(route), speed)
        self.bg.start(self.ego, route)

    def tick(self) -> Snapshot:
        s = self.world.snapshot()
        if self.ego in s.actors:
            loc = s.actors[self.ego].location
            self.agent.path.advance(loc.x, loc.y)
            out = self.driver.plan(s, [self.agent])
            if self.ego in out:
                self.world.apply_control(self.ego, out[self.ego].control)
        return self.world.tick()

    def run(self, ticks: int) -> list[Snapshot]:
        return [self.tick() for _ in range(ticks)]

    def ego_frame(self, s: Snapshot, vid: int) -> tuple[float, float, float]:
        """(ahead, right, heading difference in degrees) of a vehicle seen from the ego."""
        e = s.actors[self.ego].transform
        a = s.actors[vid].transform
        yaw = math.radians(e.rotation.yaw)
        dx, dy = a.location.x - e.location.x, a.location.y - e.location.y
        dyaw = (a.rotation.yaw - e.rotation.yaw + 180.0) % 360.0 - 180.0
        return dx * math.cos(yaw) + dy * math.sin(yaw), -dx * math.sin(yaw) + dy * math.cos(yaw), dyaw


def test_a_minute_of_traffic_stays_in_lane_without_crashes(town01, route):
    run = Run(town01, route, seed=1)
    assert isinstance(run.bg, BackgroundTraffic)
    seen: dict[int, str] = {}
    counts, worst = [], 0.0
    for t in range(1200):  # 60 s
        s = run.tick()
        ids = run.bg.vehicle_ids()
        counts.append(len(ids))
        seen.update(run.bg.vehicle_sources())
        bg = set(ids)
        crashes = [c for c in s.collisions if c.actor_id in bg or c.other_id in bg]
        assert not crashes, f"frame {s.frame}: {crashes[:2]}"
        if t % 10 == 0:
            for vid in ids:
                if vid not in s.actors:
                    continue  # spawned during this tick
                actor = s.actors[vid]
                assert actor.role_name == ROLE_NAME
                wp = town01.get_waypoint(actor.location)
                worst = max(worst, wp.transform.location.distance_2d(actor.location) / (0.5 * wp.lane_width))
    assert worst < 1.0  # every background vehicle within half a lane width of a lane centre
    assert max(counts) >= 8
    assert {"road", "opposite", "junction"} <= set(seen.values())
    # the ego made its way along the route
    assert run.world.snapshot().actors[run.ego].location.distance_2d(route[0].transform.location) > 30.0


def _signature(snapshots: list[Snapshot]) -> list[tuple]:
    return [
        (s.frame, tuple((a.id, a.type_id, a.transform, a.velocity) for a in s.actors.values()),
         tuple((i, l.state) for i, l in s.traffic_lights.items()))
        for s in snapshots
    ]


def test_same_seed_replays_identically(town01, route):
    a = Run(town01, route, seed=3).run(200)
    b = Run(town01, route, seed=3).run(200)
    assert a == b
    c = Run(town01, route, seed=4).run(200)
    assert _signature(a) != _signature(c)


def test_stop_front_vehicles_stops_them_within_seconds(town01, route):
    # LB2.0's StopFrontVehicles stops the road vehicles in front of the ego at that moment (later arrivals drive)
    run = Run(town01, route, seed=2)
    run.run(100)
    s = run.world.snapshot()
    ahead = []
    for vid in run.bg.vehicle_ids():
        x, _, dyaw = run.ego_frame(s, vid) if vid in s.actors else (0.0, 0.0, 0.0)
        if x > 0.0 and abs(dyaw) <= 45.0 and run.bg.vehicle_sources()[vid] != "opposite":
            ahead.append(vid)
    assert ahead
    run.bg.stop_front_vehicles()
    run.run(100)  # 5 s
    s = run.world.snapshot()
    for vid in ahead:
        if vid in s.actors:
            assert s.actors[vid].speed() < 0.1, (vid, s.actors[vid].speed())
            assert run.bg.last_outputs[vid].reason == "stopped"
    later = [v for v in run.bg.vehicle_ids() if v not in ahead and v in run.bg.last_outputs]
    assert all(run.bg.last_outputs[v].reason != "stopped" for v in later)
    run.bg.start_front_vehicles()
    run.run(2)
    # released: they now wait only for what is in front of them (a light, a leader), if anything
    assert all(run.bg.last_outputs[v].reason != "stopped" for v in ahead if v in run.bg.last_outputs)


def test_max_speed_and_leave_space(town01, route):
    run = Run(town01, route, seed=5)
    run.run(60)
    run.bg.set_max_speed(3.0)
    run.run(100)
    s = run.world.snapshot()
    assert max(s.actors[v].speed() for v in run.bg.vehicle_ids() if v in s.actors) <= 3.0 + 0.2
    run.bg.set_max_speed(None)
    run.bg.leave_space_in_front(40.0)
    s = run.tick()
    ego = s.actors[run.ego].location
    xy = np.array([[w.transform.location.x, w.transform.location.y] for w in route])
    start = int(np.argmin(np.hypot(xy[:, 0] - ego.x, xy[:, 1] - ego.y)))
    zone = xy[start:start + 40]
    for vid in run.bg.vehicle_ids():
        if vid in s.actors:
            loc = s.actors[vid].location
            assert np.min(np.hypot(zone[:, 0] - loc.x, zone[:, 1] - loc.y)) > 2.0


def test_opposite_off_and_lane_removal(town01, route):
    run = Run(town01, route, seed=6)
    run.run(200)
    assert "opposite" in run.bg.vehicle_sources().values()
    run.bg.change_opposite_behavior(active=False)
    assert "opposite" not in run.bg.vehicle_sources().values()
    run.run(100)
    assert "opposite" not in run.bg.vehicle_sources().values()
    # Town01 roads have one lane per direction: removing the ego's lane empties the road sources
    s = run.world.snapshot()
    run.bg.remove_road_lane(town01.get_waypoint(s.actors[run.ego].location))
    assert "road" not in run.bg.vehicle_sources().values()
    run.run(40)
    assert "road" not in run.bg.vehicle_sources().values()
    run.bg.readd_road_lane(0)
    run.run(20)
    assert "road" in run.bg.vehicle_sources().values()


def test_clear_and_stop_the_next_junction(town01, route):
    run = Run(town01, route, seed=7)
    for _ in range(600):  # until the first junction on the route is active (it has spawned vehicles)
        run.tick()
        if "junction" in run.bg.vehicle_sources().values():
            break
    junction = next(wp for wp in route if wp.is_junction).get_junction()

    def inside(s: Snapshot, sources: tuple[str, ...]) -> list[int]:
        out = []
        for vid, source in run.bg.vehicle_sources().items():
            if vid in s.actors and source in sources:
                wp = town01.get_waypoint(s.actors[vid].location)
                if wp.is_junction and wp.junction_id == junction.id:
                    out.append(vid)
        return out

    run.bg.handle_junction_scenario(clear_junction=True, stop_entries=True)
    s = run.tick()
    assert not inside(s, ("road", "detached", "junction", "opposite"))
    waiting = set()
    for _ in range(200):  # 10 s: junction-source vehicles now wait at the entries
        s = run.tick()
        assert not inside(s, ("junction",))
        waiting |= {v for v, o in run.bg.last_outputs.items() if o.reason == "junction_stopped"}
    assert waiting


def test_no_car_is_born_in_the_ego_lane_where_the_ego_cannot_stop_for_it():
    from types import SimpleNamespace

    from b2d_data.format.transform import Location, Rotation, Transform
    from b2d_data.sim.builtin.background_traffic import BackgroundTrafficManager

    # ego at the origin heading +x at 18 m/s; closing 18 m/s at 3 m/s^2 takes 18² / 6 = 54 m, plus the 10 m gap
    ego = SimpleNamespace(transform=Transform(Location(0.0, 0.0, 0.0), Rotation(yaw=0.0)), speed=lambda: 18.0)
    too_close = BackgroundTrafficManager._too_close_ahead
    assert too_close(ego, Location(19.5, 0.0, 0.0), 0.0)  # route 29430003's car: born standing 19.5 m ahead
    assert too_close(ego, Location(63.9, 0.0, 0.0), 0.0)  # 53.9 m of room < 54 m
    assert not too_close(ego, Location(64.1, 0.0, 0.0), 0.0)  # 54.1 m > 54 m
    assert not too_close(ego, Location(19.5, 0.0, 0.0), 18.0)  # born at the ego's speed: nothing to close
    # at 12 m/s it closes (324 - 144) / 6 = 30 m: 35 m ahead leaves 25 m, 45 m ahead 35 m
    assert too_close(ego, Location(35.0, 0.0, 0.0), 12.0) and not too_close(ego, Location(45.0, 0.0, 0.0), 12.0)
    assert not too_close(ego, Location(-19.5, 0.0, 0.0), 0.0)  # behind the ego


def test_no_car_is_born_in_front_of_a_background_car_that_cannot_stop_for_it():
    from types import SimpleNamespace

    from b2d_data.format.transform import Location, Rotation, Transform
    from b2d_data.sim.api import ActorKind
    from b2d_data.sim.builtin.background_traffic import BackgroundTrafficManager, _Newborn

    def car(actor_id: int, x: float, y: float, yaw: float, speed: float) -> SimpleNamespace:
        return SimpleNamespace(id=actor_id, kind=ActorKind.VEHICLE, transform=Transform(Location(x, y, 0.0),
                               Rotation(yaw=yaw)), speed=lambda: speed)

    def stops(actors, pending=(), initial: float = 0.0) -> bool:
        manager = SimpleNamespace(_ego_id=1, _vehicles={a.id: None for a in actors if a.id != 1},
                                  _pending=list(pending))
        snapshot = SimpleNamespace(actors={a.id: a for a in actors})
        return BackgroundTrafficManager._stops_a_follower(manager, snapshot, Location(0.0, 0.0, 0.0), 0.0, initial)

    # a follower at 11 m/s closes on a standing newborn in 11² / (2 × 3) = 20.17 m, and must keep 10 m:
    # 30 m behind leaves 20 m (too little), 30.5 m behind leaves 20.5 m (enough)
    assert stops([car(7, -30.0, 0.0, 0.0, 11.0)])
    assert not stops([car(7, -30.5, 0.0, 0.0, 11.0)])
    # born at 5 m/s: (121 - 25) / 6 = 16 m to close, so 25 m behind (15 m of room) is too little, 27 m is not
    assert stops([car(7, -25.0, 0.0, 0.0, 11.0)], initial=5.0)
    assert not stops([car(7, -27.0, 0.0, 0.0, 11.0)], initial=5.0)
    assert not stops([car(7, -20.0, 3.5, 0.0, 11.0)])  # the next lane
    assert not stops([car(7, -20.0, 0.0, 180.0, 11.0)])  # oncoming
    assert not stops([car(7, 20.0, 0.0, 0.0, 11.0)])  # ahead of the newborn
    assert not stops([car(1, -20.0, 0.0, 0.0, 11.0)])  # the ego: _too_close_ahead decides for it
    # a car born nearer in the same update is not in the snapshot yet (route 29000009: born at 11 m/s 11 m behind)
    assert stops([], pending=[_Newborn(Location(-11.0, 0.0, 0.0), 0.0, 11.0)])


def test_a_car_standing_in_a_lane_taper_is_removed_after_2_s_even_near_the_ego():
    from types import SimpleNamespace

    from b2d_data.format.transform import Location, Rotation, Transform
    from b2d_data.sim.builtin.background_traffic import (
        NARROW_LANE_TICKS,
        BackgroundSettings,
        BackgroundTrafficManager,
        _Vehicle,
    )

    def recycled(narrow_ticks: int, still_ticks: int = 0) -> bool:
        # a road car 8 m ahead of the ego: far from every radius, so only the taper rule can remove it
        agent = SimpleNamespace(path=SimpleNamespace(waypoints=[SimpleNamespace(is_junction=False)]))
        veh = _Vehicle(5, "road", agent, narrow_ticks=narrow_ticks, still_ticks=still_ticks)
        gone: list[int] = []
        manager = SimpleNamespace(settings=BackgroundSettings(), _vehicles={5: veh}, _junctions=[])
        manager._radii = lambda speed: BackgroundTrafficManager._radii(manager, speed)
        manager._location = lambda snapshot, vid: Location(8.0, 0.0, 0.0)
        manager._destroy = gone.append
        ego = SimpleNamespace(transform=Transform(Location(0.0, 0.0, 0.0), Rotation(yaw=0.0)), speed=lambda: 0.0)
        BackgroundTrafficManager._recycle(manager, SimpleNamespace(), ego)
        return gone == [5]

    assert NARROW_LANE_TICKS == 40  # 2 s at 20 Hz
    assert recycled(41)
    assert not recycled(40)
    assert not recycled(0, still_ticks=10_000)  # merely stuck within 15 m of the ego: kept (the older rule)


def test_lane_offsets_count_from_the_route_lane_while_the_ego_is_one_lane_over():
    from types import SimpleNamespace

    from b2d_data.format.transform import Location, Rotation, Transform
    from b2d_data.sim.builtin.background_traffic import ROUTE_LANE_TOLERANCE, BackgroundTrafficManager

    route_wp = SimpleNamespace(transform=Transform(Location(0.0, 0.0, 0.0), Rotation(yaw=0.0)), is_junction=False)
    own_lane = object()
    manager = SimpleNamespace(_route=[route_wp], _ego_index=0,
                              _map=SimpleNamespace(get_waypoint=lambda location: own_lane))  # fmt: skip

    def lane(y: float, junction: bool = False):
        route_wp.is_junction = junction
        ego = SimpleNamespace(transform=Transform(Location(0.0, y, 0.0), Rotation(yaw=0.0)))
        return BackgroundTrafficManager._ego_waypoint(manager, SimpleNamespace(), ego)

    assert ROUTE_LANE_TOLERANCE == 5.0
    assert lane(0.5) is route_wp  # on its lane
    assert lane(3.5) is route_wp  # one 3.5 m lane over (yielding, passing): still the route's lane
    assert lane(7.0) is own_lane  # two lanes over: where it is
    assert lane(3.5, junction=True) is own_lane  # in a junction the lanes are the ego's own
