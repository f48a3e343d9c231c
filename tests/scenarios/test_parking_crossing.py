"""ParkingCrossingPedestrian accepts what LB2.0's ``_initialize_actors`` accepts (scenario_runner leaderboard-2.0,
``object_crash_vehicle.py``): the blocker car stands one lane width to the side of the driving lane point
``distance`` m on, whatever that lane's type (``_get_blocker_transform``), and the walker one lane width to the side
of the point car half length + 0.5 m further (``_get_walker_transform``); only a lane without continuation refuses.

Town: ``light_less_grid`` (tests/conftest.py), streets of one 3.49 m driving lane each way and sidewalks, no parking.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.scenarios.catalog.actor_choices import half_extent
from b2d_data.scenarios.catalog.parking_crossing import ParkingCrossingPedestrian
from b2d_data.scenarios.framework import ScenarioContext
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import Route, ScenarioConfig
from b2d_data.sim.api import ActorSpec
from b2d_data.sim.builtin.world import BuiltinSimulator

LANE_WIDTH = 3.49
#: The eastbound lane along y = -120 (CARLA frame): right of the centre line by half a lane.
LANE_Y = -120.0 + LANE_WIDTH / 2


def build(town, trigger_x: float, distance: float) -> ParkingCrossingPedestrian:
    """An eastbound route through the centre junction with the scenario (direction right) built on it."""
    config = ScenarioConfig(
        "ParkingCrossingPedestrian_1", "ParkingCrossingPedestrian",
        Transform(Location(trigger_x, LANE_Y, 0.0), Rotation(yaw=0.0)),
        {"distance": {"value": str(distance)}, "direction": {"value": "right"}},
    )  # fmt: skip
    route = Route("1", "Town199", (Location(30.0, LANE_Y, 0.0), Location(210.0, LANE_Y, 0.0)), (config,))
    dense = DenseRoute.from_route(town, route)
    sim = BuiltinSimulator(town, seed=0)
    start = dense.waypoints[0].transform
    ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), Transform(start.location, start.rotation))
    scenario = ParkingCrossingPedestrian(ScenarioContext(sim, town, dense, config, np.random.default_rng(0), ego))
    scenario.build()
    return scenario


def test_without_a_parking_lane_the_car_stands_one_lane_width_right_of_the_driving_lane(light_less_grid):
    """Trigger at x = 40, distance 20: the lane point is (60, -118.255); one lane width (3.49 m) to the right of an
    eastbound lane is +y in CARLA's frame, so the car stands at (60, -114.765)."""
    scenario = build(light_less_grid, 40.0, 20.0)
    assert scenario.parking is None
    car = scenario.ctx.sim.tick().actors[scenario.car]
    lane = scenario.lane_waypoint.transform.location
    # the trigger snaps to the nearest dense route point (1 m apart), so the lane point is within 0.5 m of x = 60
    assert lane.x == pytest.approx(60.0, abs=0.5) and lane.y == pytest.approx(LANE_Y, abs=0.05)
    assert car.location.x == pytest.approx(lane.x, abs=0.05)
    assert car.location.y == pytest.approx(LANE_Y + LANE_WIDTH, abs=0.05)
    # the walker: one lane width right of the lane point car half length + 0.5 m beyond the car's
    assert scenario.walker_lateral == pytest.approx(LANE_WIDTH, abs=0.01)
    ahead = scenario.collision_waypoint.transform.location
    assert ahead.x == pytest.approx(lane.x + half_extent(scenario.car_model)[0] + 0.5, abs=0.05)


def test_a_lane_point_inside_a_junction_is_accepted(light_less_grid):
    """LB2.0 takes ``next(distance)[0]`` wherever it lies: trigger at x = 90, distance 30 reaches x = 120, the
    centre junction (its box spans about x = 110 to 130)."""
    scenario = build(light_less_grid, 90.0, 30.0)
    assert scenario.lane_waypoint.is_junction
    car = scenario.ctx.sim.tick().actors[scenario.car]
    lane = scenario.lane_waypoint.transform
    yaw = math.radians(lane.rotation.yaw)
    # one lane width to the right of the lane point, whatever lies there
    right = (-math.sin(yaw), math.cos(yaw))
    offset = (car.location.x - lane.location.x) * right[0] + (car.location.y - lane.location.y) * right[1]
    assert offset == pytest.approx(scenario.lane_waypoint.lane_width, abs=0.05)
