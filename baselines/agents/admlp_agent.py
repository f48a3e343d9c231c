"""AD-MLP as a Leaderboard 2.0 agent: ego history + command → waypoints → PID (Bench2DriveZoo's conversion).

No camera: GNSS, IMU and speedometer, as Bench2DriveZoo's ``admlp_b2d_agent.py`` uses them (its front and ``bev``
cameras only feed its saved visualisations). The model runs every step (the Zoo agent holds each control for
10 steps)::

    b2d-eval run --agent baselines/agents/admlp_agent.py --agent-config runs/admlp/last.pt --routes R.xml --out eval/admlp
"""

from __future__ import annotations

import sys
from pathlib import Path

import carla
import torch
from leaderboard.autoagents import autonomous_agent

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root, for ``baselines``

from baselines.agent_base import (  # noqa: E402
    GNSS_SPEC, IMU_SPEC, SPEED_SPEC, RouteState, checkpoint_path, parse_config, torch_device,
)  # fmt: skip
from baselines.controller import WaypointController, agent_control  # noqa: E402
from baselines.features import admlp_input  # noqa: E402
from baselines.train import load_checkpoint  # noqa: E402


def get_entry_point() -> str:
    """The class the evaluator instantiates."""
    return "ADMLPAgent"


class ADMLPAgent(autonomous_agent.AutonomousAgent):
    """Waypoints from the ego's own past, turned into controls by the waypoint PID."""

    def setup(self, path_to_conf_file: str) -> None:
        """Load the checkpoint (``--agent-config PATH`` or ``ckpt=PATH,device=cpu,throttle_cap=1``)."""
        self.track = autonomous_agent.Track.SENSORS
        self.options = parse_config(path_to_conf_file)
        torch.set_num_threads(1)  # route processes run side by side
        self.device = torch_device(self.options)
        self.net, _ = load_checkpoint(checkpoint_path(self.options), self.device)
        self.controller = WaypointController()
        self.throttle_cap = self.options.get("throttle_cap", "0") == "1"
        self.route: RouteState | None = None
        self.last_waypoints = None

    def sensors(self) -> list[dict]:
        """GNSS, IMU and speedometer."""
        return [dict(GNSS_SPEC), dict(IMU_SPEC), dict(SPEED_SPEC)]

    @torch.no_grad()
    def run_step(self, input_data: dict, timestamp: float) -> carla.VehicleControl:
        """History → waypoints → control."""
        if self.route is None:
            self.route = RouteState.of_agent(self)
        ego = self.route.update(input_data)
        past_xy, past_yaw = self.route.history.past()
        x = admlp_input(past_xy, past_yaw, ego.speed, ego.accel, ego.command)
        pred = self.net(torch.from_numpy(x).unsqueeze(0).to(self.device))[0].float().cpu().numpy()
        self.last_waypoints = pred
        out = self.controller.step(pred[:, :2], ego.speed, ego.target_point)
        steer, throttle, brake = agent_control(out, ego.speed, self.throttle_cap)
        return carla.VehicleControl(throttle=float(throttle), steer=float(steer), brake=float(brake))

    def destroy(self) -> None:
        """Free the model."""
        self.net = None
