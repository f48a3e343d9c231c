"""The obstacle-scenario manager: a construction site (props, not vehicles) and the two-way overtake gate."""

from __future__ import annotations

from types import SimpleNamespace

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.obstacle_scenarios import ObstacleScenarioManager
from b2d_data.sim.api import OPPOSITE_LANE_OPEN, ScenarioHint

from .conftest import FakeWaypoint

EGO, BOARD, CONE = 1, 2, 3
SPEED = 10.0  # the ego's speed and its free target speed (m/s)


def _lane_of(location):
    """The fake town's lane under a location: the ego's lane −1 along y = 0, the lane left of it (−y) beyond 1.75 m."""
    return FakeWaypoint(location.x, -3.5, 1) if location.y < -1.75 else FakeWaypoint(location.x, 0.0, -1)


def _step(make_route, make_vehicle, ego_x: float, ego_y: float = 0.0, others=()):
    config = ExpertConfig()
    route = make_route(100.0, config)
    route.index = round(ego_x * config.points_per_meter)
    ego = make_vehicle(EGO, ego_x, ego_y, speed=SPEED)
    # the board 5 m of free road ahead of the ego's front at x = 10 (ego half length 2.4 m, board half length
    # 1.19 m): the shift starts 1.19 + 10.5 m before the board's index 186, at index 70 (7.0 m), its ramp ends at 17.5 m
    board = make_vehicle(BOARD, 10.0 + 2.4 + 5.0 + 1.19, 0.0, half=(1.19, 1.44, 0.9))
    cone = make_vehicle(CONE, 30.0, 1.5, half=(0.17, 0.17, 0.3))
    cars = [ego, *others]
    snapshot = SimpleNamespace(actors={EGO: ego, BOARD: board, CONE: cone, **{c.id: c for c in others}},
                               vehicles=lambda: cars)
    hint = ScenarioHint("ConstructionObstacle", BOARD, CONE, direction="right")
    manager = ObstacleScenarioManager(config, town=SimpleNamespace(get_waypoint=_lane_of))
    return manager.step(snapshot, ego, route, [hint], SPEED), route, manager


def test_the_construction_board_is_a_standing_leader_while_the_ego_is_in_its_lane(make_route, make_vehicle):
    result, route, _ = _step(make_route, make_vehicle, 10.0)
    assert (route.points != route.original_points).any()  # the shift around the site is planned
    # IDM (s0 2 m, T 0.1 s, a 24, b 3.72) over one 0.05 s step: at 10 m/s s* = 2 + 1 + 10·10 / (2·√(24·3.72))
    # = 8.29 m against the 5 m gap, dv/dt = −24·(8.29/5)² = −66 m/s²; at 7.9 m/s (gap 4.55 m, s* 6.09 m) it has
    # eased to 24·(1 − 0.79⁴ − (6.09/4.55)²) = −28 m/s². The speed reached lies between those two held for 0.05 s.
    assert 10.0 - 66.0 * 0.05 < result.target_speed < 10.0 - 28.0 * 0.05
    assert result.reduced_by is not None and result.reduced_by.actor_id == BOARD


def test_the_board_no_longer_holds_the_ego_once_it_left_its_lane(make_route, make_vehicle):
    result, _, _ = _step(make_route, make_vehicle, 10.0, ego_y=-2.0)  # 2 m to the left (−y), beyond the 1 m tolerance
    assert result.target_speed == SPEED and result.reduced_by is None


CAR = 4


def test_the_ego_waits_before_the_shift_while_a_car_comes_up_behind_in_the_target_lane(make_route, make_vehicle):
    # ego at 2 m (5 m before the shift start, inside the 8 m decision window), 10 m/s; a car 22 m behind in the left
    # lane at 20 m/s. The ego covers |(17.5, −3.5) − (2, 0)| + 4.8 + 10 = 30.69 m (ramp end, its length, 10 m) at
    # 10 m/s: 3.07 s; the car's front reaches the ego's rear at the ramp end after (37.5 − 4.8) / 20 = 1.64 s.
    car = make_vehicle(CAR, -20.0, -3.5, speed=20.0)
    result, _, manager = _step(make_route, make_vehicle, 2.0, others=[car])
    assert not manager.records[("ConstructionObstacle", BOARD)].path_clear
    # IDM toward the waiting point 1.5 m past the shift start, 6.5 m ahead: gap 6.5 − 2.4 = 4.1 m. At 10 m/s
    # s* = 8.29 m (as below), dv/dt = −24·(8.29/4.1)² = −98 m/s²; down to 8 m/s (gap ≥ 3.65 m, s* ≤ 7.19 m) it
    # stays below 24·(1 − 0.8⁴ − (7.19/3.65)²) = −79 m/s², so 8 m/s is reached within 2/79 < 0.05 s. Standing
    # before the board instead (gap 16.59 − 3.59 = 13 m) it would brake at most 24·(8.29/13)² = 9.8 m/s², to ≥ 9.5 m/s.
    assert result.target_speed < 8.0
    assert result.reduced_by is not None and result.reduced_by.actor_id == BOARD


def test_the_ego_commits_to_the_shift_when_the_car_behind_is_far(make_route, make_vehicle):
    # the car 62 m behind: (77.5 − 4.8) / 20 = 3.64 s > 3.07 + 0.2 s, clear; the board is the standing leader again
    car = make_vehicle(CAR, -60.0, -3.5, speed=20.0)
    result, _, manager = _step(make_route, make_vehicle, 2.0, others=[car])
    assert manager.records[("ConstructionObstacle", BOARD)].path_clear
    assert 10.0 - 0.05 * 24.0 * (8.29 / 13.0) ** 2 - 0.01 < result.target_speed < 10.0


PARKED = 5


def _two_way_step(make_route, make_vehicle, extra):
    """ParkedObstacleTwoWays: the ego at 10 m (10 m/s), a parked car at 20 m pushed 1.2 m right, nothing else."""
    config = ExpertConfig()
    route = make_route(100.0, config)
    route.index = round(10.0 * config.points_per_meter)
    ego = make_vehicle(EGO, 10.0, 0.0, speed=SPEED)
    parked = make_vehicle(PARKED, 20.0, 1.2)
    snapshot = SimpleNamespace(actors={EGO: ego, PARKED: parked}, vehicles=lambda: [ego, parked])
    hint = ScenarioHint("ParkedObstacleTwoWays", PARKED, None, direction="right", extra=extra)
    manager = ObstacleScenarioManager(config, town=SimpleNamespace(get_waypoint=_lane_of))
    return manager.step(snapshot, ego, route, [hint], SPEED), manager


def test_the_ego_waits_at_the_two_way_shift_until_the_scenario_opens_the_opposite_lane(make_route, make_vehicle):
    # The shift starts 2.4 + 4 − 0.5 m before the car's index 200: at index 200 − int(24 + 40 − 5) = 141 (14.1 m),
    # 4.1 m ahead of the ego, inside the 8 m decision window. With the lane still closed (LB2.0 switches the
    # wrong-direction test off 5 s after the 50 m approach) the ego waits: IDM toward 1.5 m past the start, a gap
    # of 15.6 − 10 − 2.4 = 3.2 m at 10 m/s: s* = 2 + 1 + 100 / (2·√(24·3.72)) = 8.29 m, dv/dt = −24·(8.29/3.2)²
    # = −161 m/s², and at any speed down to 0 it stays below 24·(1 − (3/3.2)²) ≈ 2.9 m/s², so the target falls.
    result, manager = _two_way_step(make_route, make_vehicle, {OPPOSITE_LANE_OPEN: 0})
    assert not manager.records[("ParkedObstacleTwoWays", PARKED)].path_clear
    assert not result.keep_driving
    assert result.target_speed < SPEED - 0.05 * 24.0  # braking harder than 24 m/s² over the 0.05 s step
    assert result.reduced_by is not None and result.reduced_by.actor_id == PARKED


def test_the_ego_commits_once_the_opposite_lane_is_open_or_when_the_scenario_does_not_say(make_route, make_vehicle):
    # the opposite lane is empty: the path-clear test passes and the ego commits at PDM-Lite's 50 km/h
    for extra in ({OPPOSITE_LANE_OPEN: 1}, {}):
        result, manager = _two_way_step(make_route, make_vehicle, extra)
        assert manager.records[("ParkedObstacleTwoWays", PARKED)].path_clear
        assert result.keep_driving and result.target_speed == 50.0 / 3.6


def _same_direction_lane_of(location):
    """A one-way road: the ego's lane −2 along y = 0, the same-direction lane −1 left of it (−y) beyond 1.75 m."""
    return FakeWaypoint(location.x, -3.5, -1) if location.y < -1.75 else FakeWaypoint(location.x, 0.0, -2)


def _multi_lane_two_way_step(make_route, make_vehicle, flow_car):
    """ParkedObstacleTwoWays as a route file may put it on a one-way two-lane road: the ego on lane −2 at 10 m
    (10 m/s), a parked car at 20 m pushed 1.2 m right, the scenario's flow car in lane −1, the lane open."""
    config = ExpertConfig()
    route = make_route(100.0, config, lane_id=-2)
    route.index = round(10.0 * config.points_per_meter)
    ego = make_vehicle(EGO, 10.0, 0.0, speed=SPEED)
    parked = make_vehicle(PARKED, 20.0, 1.2)
    snapshot = SimpleNamespace(actors={EGO: ego, PARKED: parked, CAR: flow_car},
                               vehicles=lambda: [ego, parked, flow_car])
    hint = ScenarioHint("ParkedObstacleTwoWays", PARKED, None, direction="right", extra={OPPOSITE_LANE_OPEN: 1})
    manager = ObstacleScenarioManager(config, town=SimpleNamespace(get_waypoint=_same_direction_lane_of))
    return manager.step(snapshot, ego, route, [hint], SPEED), manager


def test_a_same_direction_flow_lane_is_judged_by_the_cars_behind(make_route, make_vehicle):
    # LB2.0's OppositeActorFlow runs on the obstacle's get_left_lane() whatever its direction (route_obstacles.py);
    # on a one-way road (Bench2Drive v0.0.4 val 25783, 25727, 25986 on Town04) its cars come up from behind in the
    # ego's direction. A flow car 20 m ahead driving away is a leader, not a block (the oncoming test saw it inside
    # the overtaking zone and the ego waited until TickRuntime); one 22 m behind at 20 m/s blocks as for the
    # construction shift (its front reaches the ramp end well before the ego has covered ramp + length + 10 m).
    result, manager = _multi_lane_two_way_step(make_route, make_vehicle, make_vehicle(CAR, 30.0, -3.5, speed=SPEED))
    assert manager.records[("ParkedObstacleTwoWays", PARKED)].path_clear and result.keep_driving
    result, manager = _multi_lane_two_way_step(make_route, make_vehicle, make_vehicle(CAR, -12.0, -3.5, speed=20.0))
    assert not manager.records[("ParkedObstacleTwoWays", PARKED)].path_clear and not result.keep_driving
