"""The obstacle-scenario manager's handling of a construction site (props, not vehicles)."""

from __future__ import annotations

from types import SimpleNamespace

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.obstacle_scenarios import ObstacleScenarioManager
from b2d_data.sim.api import ScenarioHint

EGO, BOARD, CONE = 1, 2, 3
SPEED = 10.0  # the ego's speed and its free target speed (m/s)


def _step(make_route, make_vehicle, ego_x: float, ego_y: float = 0.0):
    config = ExpertConfig()
    route = make_route(100.0, config)
    route.index = round(ego_x * config.points_per_meter)
    ego = make_vehicle(EGO, ego_x, ego_y, speed=SPEED)
    # the board 5 m of free road ahead of the ego's front (ego half length 2.4 m, board half length 1.19 m)
    board = make_vehicle(BOARD, 10.0 + 2.4 + 5.0 + 1.19, 0.0, half=(1.19, 1.44, 0.9))
    cone = make_vehicle(CONE, 30.0, 1.5, half=(0.17, 0.17, 0.3))
    snapshot = SimpleNamespace(actors={EGO: ego, BOARD: board, CONE: cone})
    hint = ScenarioHint("ConstructionObstacle", BOARD, CONE, direction="right")
    manager = ObstacleScenarioManager(config, town=None)
    return manager.step(snapshot, ego, route, [hint], SPEED), route


def test_the_construction_board_is_a_standing_leader_while_the_ego_is_in_its_lane(make_route, make_vehicle):
    result, route = _step(make_route, make_vehicle, 10.0)
    assert (route.points != route.original_points).any()  # the shift around the site is planned
    # IDM (s0 2 m, T 0.1 s, a 24, b 3.72) over one 0.05 s step: at 10 m/s s* = 2 + 1 + 10·10 / (2·√(24·3.72))
    # = 8.29 m against the 5 m gap, dv/dt = −24·(8.29/5)² = −66 m/s²; at 7.9 m/s (gap 4.55 m, s* 6.09 m) it has
    # eased to 24·(1 − 0.79⁴ − (6.09/4.55)²) = −28 m/s². The speed reached lies between those two held for 0.05 s.
    assert 10.0 - 66.0 * 0.05 < result.target_speed < 10.0 - 28.0 * 0.05
    assert result.reduced_by is not None and result.reduced_by.actor_id == BOARD


def test_the_board_no_longer_holds_the_ego_once_it_left_its_lane(make_route, make_vehicle):
    result, _ = _step(make_route, make_vehicle, 10.0, ego_y=-2.0)  # 2 m to the left (−y), beyond the 1 m tolerance
    assert result.target_speed == SPEED and result.reduced_by is None
