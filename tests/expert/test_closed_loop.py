"""The expert driving the builtin simulator: junction, red light, stopped car, stop sign, traffic, parked car.

Short runs (a few hundred ticks, no sensors). Lights are frozen where the test needs a known state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from b2d_data.expert import Expert, ExpertConfig
from b2d_data.expert.lights_and_signs import stop_sign_affects, stop_sign_centre
from b2d_data.format.transform import Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.format.transform import Vector3D
from b2d_data.sim.api import ActorSpec, ScenarioHint, TrafficLightState
from b2d_data.sim.builtin.world import BuiltinSimulator

CONFIG = ExpertConfig.for_builtin()


@dataclass
class Log:
    """Per-tick ego records of a run."""

    speed: list[float] = field(default_factory=list)
    location: list[np.ndarray] = field(default_factory=list)
    lane: list[tuple[int, int]] = field(default_factory=list)
    collisions: list[int] = field(default_factory=list)
    light_hazard: list[bool] = field(default_factory=list)
    changed_route: list[bool] = field(default_factory=list)


def _world(carla_maps_dir, town: str, seed: int = 0) -> BuiltinSimulator:
    return BuiltinSimulator(load_opendrive(carla_maps_dir / f"{town}.xodr"), seed=seed)


def _spawn_ego(sim: BuiltinSimulator, route) -> int:
    t = route[0][0].transform
    pose = Transform(Location(t.location.x, t.location.y, t.location.z + 0.5), t.rotation)
    return sim.spawn_actor(ActorSpec("vehicle.lincoln.mkz_2020", role_name="hero"), pose)


def _freeze_lights(sim: BuiltinSimulator, state: TrafficLightState) -> None:
    for light_id in sim.snapshot().traffic_lights:
        sim.set_traffic_light_state(light_id, state)


def _drive(sim: BuiltinSimulator, expert: Expert, ego: int, ticks: int, hints=(), log: Log | None = None,
           until=None) -> Log:
    log = log or Log()
    snap = sim.tick()
    for _ in range(ticks):
        sim.apply_control(ego, expert.run_step(snap, hints))
        snap = sim.tick()
        e = snap.actors[ego]
        wp = sim.map.get_waypoint(e.location)
        log.speed.append(e.speed())
        log.location.append(np.array([e.location.x, e.location.y]))
        log.lane.append((wp.road_id, wp.lane_id))
        log.collisions.extend(c.other_id for c in snap.collisions if c.actor_id == ego)
        log.light_hazard.append(expert.state.light_hazard)
        log.changed_route.append(expert.state.changed_route)
        if until is not None and until(snap, e):
            break
    return log


def _along(route, index: int, location: np.ndarray) -> float:
    """Signed distance of ``location`` past route point ``index`` along the route's direction there."""
    t = route[index][0].transform
    f = t.get_forward_vector()
    return float((location[0] - t.location.x) * f.x + (location[1] - t.location.y) * f.y)


def _town01_junction_route(sim):
    points = sim.map.get_spawn_points()
    return sim.map.trace_route(points[0].location, points[40].location)[:80]


def _max_route_deviation(route, log: Log) -> float:
    pts = np.array([[wp.transform.location.x, wp.transform.location.y] for wp, _ in route])
    # densify the 1 m route so the distance is to the polyline, not to its vertices
    fine = np.concatenate([np.linspace(pts[i], pts[i + 1], 10, endpoint=False) for i in range(len(pts) - 1)])
    return max(float(np.min(np.linalg.norm(fine - p[None, :], axis=1))) for p in log.location)


def test_follows_route_through_junction(carla_maps_dir):
    sim = _world(carla_maps_dir, "Town01")
    route = _town01_junction_route(sim)
    assert any(wp.is_junction for wp, _ in route)
    ego = _spawn_ego(sim, route)
    _freeze_lights(sim, TrafficLightState.GREEN)
    end = route[-1][0].transform.location
    expert = Expert(sim.map, route, CONFIG)
    log = _drive(sim, expert, ego, 400, until=lambda snap, e: e.location.distance_2d(end) < 2.0)
    assert np.linalg.norm(log.location[-1] - [end.x, end.y]) < 2.0, "did not reach the end of the route"
    state = expert.state
    assert state.route.shape == (20, 3) and state.route_original.shape == (20, 3)
    assert state.speed_limit == pytest.approx(30 / 3.6) and -1.0 <= state.angle <= 1.0
    assert not (state.brake or state.vehicle_hazard or state.light_hazard or state.changed_route)
    assert not log.collisions
    # a lane is 4 m wide on Town01: staying within 0.6 m of the route keeps the car inside its lane
    assert _max_route_deviation(route, log) < 0.6
    assert max(log.speed) < 30 / 3.6 * 0.72 * 1.05  # 0.72 × the 30 km/h limit (+5 %)


def test_stops_at_red_light_and_goes_on_green(carla_maps_dir):
    sim = _world(carla_maps_dir, "Town01")
    route = _town01_junction_route(sim)
    ego = _spawn_ego(sim, route)
    _freeze_lights(sim, TrafficLightState.RED)
    expert = Expert(sim.map, route, CONFIG)
    log = _drive(sim, expert, ego, 240)
    light_id = expert.state.next_traffic_light_id
    assert light_id is not None and expert.state.light_hazard
    stop_wp = sim.snapshot().traffic_lights[light_id].stop_waypoints[0]
    stop_index = int(np.argmin([wp.transform.location.distance_2d(stop_wp.transform.location) for wp, _ in route]))
    bumper = _along(route, stop_index, log.location[-1]) + 2.451  # ego front relative to the stop line
    assert log.speed[-1] < 0.1
    assert -6.0 < bumper < -1.0, f"front bumper {bumper:.2f} m from the stop line"
    assert all(_along(route, stop_index, p) + 2.451 < 0.0 for p in log.location)  # never crossed it on red
    sim.set_traffic_light_state(light_id, TrafficLightState.GREEN)
    log = _drive(sim, expert, ego, 200)
    assert _along(route, stop_index, log.location[-1]) > 15.0
    assert not log.collisions


def test_stops_behind_stopped_vehicle(carla_maps_dir):
    sim = _world(carla_maps_dir, "Town01")
    route = _town01_junction_route(sim)
    ego = _spawn_ego(sim, route)
    _freeze_lights(sim, TrafficLightState.GREEN)
    t = route[40][0].transform  # 40 m ahead, just after the junction
    other = sim.spawn_actor(ActorSpec("vehicle.tesla.model3"),
                            Transform(Location(t.location.x, t.location.y, t.location.z + 0.3), t.rotation))
    log = _drive(sim, Expert(sim.map, route, CONFIG), ego, 300)
    o = sim.snapshot().actors[other].location
    gap = float(np.linalg.norm(log.location[-1] - [o.x, o.y]))
    assert not log.collisions
    assert log.speed[-1] < 0.1
    assert 6.0 < gap < 12.0, f"centre distance {gap:.2f} m"  # IDM s0 = 4 m between the bumpers, ~4.9 m of cars


def test_stops_at_stop_sign_and_clears_it(carla_maps_dir):
    sim = _world(carla_maps_dir, "Town07")
    snap = sim.snapshot()
    sign = min((s for s in snap.traffic_signs.values() if s.type_id == "traffic.stop"), key=lambda s: s.id)
    centre = stop_sign_centre(sign)
    wp = sim.map.get_waypoint(Location(*centre))
    route = sim.map.trace_route(wp.previous(40.0)[0].transform.location, wp.next(30.0)[0].transform.location)
    ego = _spawn_ego(sim, route)
    expert = Expert(sim.map, route, CONFIG)
    log = _drive(sim, expert, ego, 320,
                 until=lambda snap, e: expert.stop_signs.cleared and e.location.distance_2d(Location(*centre)) > 12.0)
    stopped_in_zone = [
        i for i, v in enumerate(log.speed)
        if v < 0.1 and stop_sign_affects(sim.map, np.array([*log.location[i], 0.0]), sign)
    ]  # fmt: skip
    assert stopped_in_zone, "never stood still where the stop sign applies (RunningStopTest would fire)"
    assert not log.collisions
    # it went on through the junction: more than 10 m from the trigger centre at the end
    assert np.linalg.norm(log.location[-1] - centre[:2]) > 10.0
    assert expert.state.next_stop_sign_id != sign.id or not expert.state.stop_sign_hazard


def test_background_traffic_without_collisions(carla_maps_dir):
    sim = _world(carla_maps_dir, "Town01", seed=3)
    points = sim.map.get_spawn_points()
    route = sim.map.trace_route(points[0].location, points[40].location)[:160]
    ego = _spawn_ego(sim, route)
    sim.background.start(ego, [wp for wp, _ in route])
    log = _drive(sim, Expert(sim.map, route, CONFIG), ego, 500)
    assert not log.collisions
    assert sum(s * 0.05 for s in log.speed) > 30.0  # it made progress (lights and traffic permitting)


def test_parked_obstacle_lane_change(carla_maps_dir):
    sim = _world(carla_maps_dir, "Town10HD")
    start = sim.map.get_waypoint_xodr(7, -2, 0.0)  # rightmost of two same-direction lanes for 150 m
    route = sim.map.trace_route(start.transform.location, start.next(150.0)[0].transform.location)
    ego = _spawn_ego(sim, route)
    _freeze_lights(sim, TrafficLightState.GREEN)
    spot = start.next(50.0)[0]
    yaw = math.radians(spot.transform.rotation.yaw)
    offset = 0.35 * spot.lane_width  # ParkedObstacle: 35 % of the lane to the right
    loc = spot.transform.location
    parked = sim.spawn_actor(ActorSpec("vehicle.tesla.model3"), Transform(
        Location(loc.x - math.sin(yaw) * offset, loc.y + math.cos(yaw) * offset, loc.z + 0.3), spot.transform.rotation))
    sim.set_simulate_physics(parked, False)
    hint = ScenarioHint("ParkedObstacle", parked, parked, "right")
    expert = Expert(sim.map, route, CONFIG)
    p = np.array([loc.x, loc.y])
    f = np.array([math.cos(yaw), math.sin(yaw)])
    log = _drive(sim, expert, ego, 300, hints=[hint],
                 until=lambda snap, e: float((np.array([e.location.x, e.location.y]) - p) @ f) > 15.0)
    assert not log.collisions
    assert float((log.location[-1] - p) @ f) > 15.0, "did not pass the parked car"
    left = spot.get_left_lane()
    beside = [lane for loc_, lane in zip(log.location, log.lane) if abs(float((loc_ - p) @ f)) < 3.0]
    assert beside and all(lane == (left.road_id, left.lane_id) for lane in beside), "not in the left lane beside it"
    assert any(log.changed_route) and not log.changed_route[-1]  # shifted route recorded, then back to normal


def test_between_two_cars_of_a_flow_that_never_brakes_the_ego_keeps_their_speed(carla_maps_dir):
    # LB2.0's ActorFlow cars drive on at their speed whatever is ahead of them (HighwayExit's flow). The ego sits
    # between two such cars at 8 m/s on Town01's straight (limit 30 km/h: its own target 0.72 x 8.33 = 6 m/s, raised
    # to the flow's 8 m/s): the leader 14 m ahead (bumper gap 14 - 2.45 - 2.45 = 9.1 m), the follower 8 m behind
    # (3.1 m). PDM-Lite's IDM behind the leader (desired speed 8, s0 4 m, T 0.25 s) settles below 8 m/s whatever
    # the gap, since 1 - (v/8)^4 = 0 at v = 8, and the follower closes in until it hits the ego.
    sim = _world(carla_maps_dir, "Town01")
    start = sim.map.get_waypoint(sim.map.get_spawn_points()[18].location).next(20.0)[0]  # 150 m without junction
    route = sim.map.trace_route(start.transform.location, start.next(120.0)[0].transform.location)
    ego = _spawn_ego(sim, route)
    flow_speed = 8.0
    cars = []
    for wp in (start.next(14.0)[0], start.previous(8.0)[0]):
        t = wp.transform
        cars.append(sim.spawn_actor(ActorSpec("vehicle.lincoln.mkz_2020", role_name="scenario"),
                                    Transform(Location(t.location.x, t.location.y, t.location.z + 0.3), t.rotation)))
    forward = start.transform.get_forward_vector()
    expert = Expert(sim.map, route, CONFIG)
    hint = ScenarioHint("HighwayExit", None, None)
    log = Log()
    snap = sim.tick()
    for tick in range(200):
        for actor_id in cars + ([ego] if tick == 0 else []):
            sim.set_target_velocity(actor_id, Vector3D(forward.x * flow_speed, forward.y * flow_speed, 0.0))
        sim.apply_control(ego, expert.run_step(snap, [hint]))
        snap = sim.tick()
        log.speed.append(snap.actors[ego].speed())
        log.collisions.extend(c.other_id for c in snap.collisions if c.actor_id == ego)
    assert not log.collisions
    # within a tick's rounding of the flow's speed once settled: never slower than the follower by more than 0.3 m/s
    assert min(log.speed[40:]) > flow_speed - 0.3
