"""Constant-speed route follower: the floor of the baselines table (no perception, no learning).

It drives the route's dense plan at a fixed speed (``speed=`` m/s, default 6) through the same waypoint → PID
conversion as the learned agents (``baselines.controller``): its "predicted" waypoints are the route points the
ego would reach every 0.5 s at that speed. It sees nothing, so it stops for nothing::

    b2d-eval run --agent baselines/agents/route_follower_agent.py --agent-config speed=6 --routes R.xml --out eval/rf
"""

from __future__ import annotations

import sys
from pathlib import Path

import carla
import numpy as np
from leaderboard.autoagents import autonomous_agent

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root, for ``baselines``

from baselines.agent_base import GNSS_SPEC, IMU_SPEC, SPEED_SPEC, RouteState, parse_config  # noqa: E402
from baselines.controller import WaypointController, agent_control  # noqa: E402
from baselines.features import WAYPOINT_DT, to_ego  # noqa: E402

DEFAULT_SPEED = 6.0  # m/s
STEPS = 4


def get_entry_point() -> str:
    """The class the evaluator instantiates."""
    return "RouteFollowerAgent"


class RouteFollowerAgent(autonomous_agent.AutonomousAgent):
    """Follows the plan at a constant speed."""

    def setup(self, path_to_conf_file: str) -> None:
        """Options: ``speed=`` (m/s)."""
        self.track = autonomous_agent.Track.SENSORS
        self.options = parse_config(path_to_conf_file)
        self.options.pop("ckpt", None)
        self.speed = float(self.options.get("speed", DEFAULT_SPEED))
        self.controller = WaypointController()
        self.route: RouteState | None = None

    def sensors(self) -> list[dict]:
        """GNSS, IMU and speedometer only."""
        return [dict(GNSS_SPEC), dict(IMU_SPEC), dict(SPEED_SPEC)]

    def planned_waypoints(self, x: float, y: float, yaw: float) -> np.ndarray:
        """(4, 2) route points 0.5 s apart at the set speed, in the CARLA ego frame."""
        assert self.route is not None
        distances = self.speed * WAYPOINT_DT * np.arange(1, STEPS + 1)
        return to_ego(self.route.route_ahead(x, y, distances), x, y, yaw)

    def run_step(self, input_data: dict, timestamp: float) -> carla.VehicleControl:
        """Steer along the plan, hold the set speed."""
        if self.route is None:
            self.route = RouteState.of_agent(self)
        ego = self.route.update(input_data)
        out = self.controller.step(self.planned_waypoints(ego.x, ego.y, ego.yaw), ego.speed, ego.target_point)
        steer, throttle, brake = agent_control(out, ego.speed)
        return carla.VehicleControl(throttle=float(throttle), steer=float(steer), brake=float(brake))
