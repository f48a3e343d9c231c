"""The TCP-style model as a Leaderboard 2.0 agent: front camera + speed, target point, command → control.

The front camera is mounted as the clips' CAM_FRONT (x 0.80, z 1.60, FOV 70) at the size the training clips were
collected at (the checkpoint records it), and each frame goes through JPEG quality 20 as the clips' images did
(Bench2DriveZoo's agents do the same). ``planner=`` picks the output as Bench2DriveZoo's ``PLANNER_TYPE`` does:
``only_traj`` (default: predicted waypoints → PID), ``only_ctrl`` (the predicted discrete action) or
``merge_ctrl_traj`` (steer and throttle averaged, the stronger brake); ``$PLANNER_TYPE`` is read too::

    b2d-eval run --agent baselines/agents/tcp_agent.py --agent-config runs/tcp/last.pt --routes R.xml --out eval/tcp
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import carla
import cv2
import numpy as np
import torch
from leaderboard.autoagents import autonomous_agent

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root, for ``baselines``

from b2d_data.format.expert_actions import action_control  # noqa: E402
from b2d_data.format.rig import camera  # noqa: E402

from baselines.agent_base import (  # noqa: E402
    GNSS_SPEC, IMU_SPEC, SPEED_SPEC, RouteState, checkpoint_path, parse_config, torch_device,
)  # fmt: skip
from baselines.controller import ControlOutput, WaypointController, agent_control  # noqa: E402
from baselines.features import tcp_state  # noqa: E402
from baselines.train import load_checkpoint  # noqa: E402

PLANNERS = ("only_traj", "only_ctrl", "merge_ctrl_traj")


def get_entry_point() -> str:
    """The class the evaluator instantiates."""
    return "TCPAgent"


def jpeg_roundtrip(bgr: np.ndarray, quality: int = 20) -> np.ndarray:
    """The image as the clips store it: JPEG at ``quality``, decoded back to RGB."""
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(bgr), [int(cv2.IMWRITE_JPEG_QUALITY), quality])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


class TCPAgent(autonomous_agent.AutonomousAgent):
    """Camera and measurements in, trajectory and action out, PID or action to control."""

    def setup(self, path_to_conf_file: str) -> None:
        """Load the checkpoint; options ``planner=``, ``device=``, ``throttle_cap=1``, ``width=``/``height=``."""
        self.track = autonomous_agent.Track.SENSORS
        self.options = parse_config(path_to_conf_file)
        torch.set_num_threads(1)
        self.device = torch_device(self.options)
        self.net, ckpt = load_checkpoint(checkpoint_path(self.options), self.device)
        height, width = ckpt.get("camera_hw", (180, 320))
        self.width = int(self.options.get("width", width))
        self.height = int(self.options.get("height", height))
        self.planner = self.options.get("planner") or os.environ.get("PLANNER_TYPE") or "only_traj"
        if self.planner not in PLANNERS:
            raise ValueError(f"planner must be one of {PLANNERS}, got {self.planner!r}")
        self.controller = WaypointController()
        self.throttle_cap = self.options.get("throttle_cap", "0") == "1"
        self.route: RouteState | None = None

    def sensors(self) -> list[dict]:
        """The clips' front camera at the training size, GNSS, IMU, speedometer."""
        front = camera("CAM_FRONT")
        m = front.mount
        cam = {"type": "sensor.camera.rgb", "x": m.x, "y": m.y, "z": m.z, "roll": m.roll, "pitch": m.pitch,
               "yaw": m.yaw, "width": self.width, "height": self.height, "fov": front.fov, "id": "CAM_FRONT"}  # fmt: skip
        return [cam, dict(GNSS_SPEC), dict(IMU_SPEC), dict(SPEED_SPEC)]

    @torch.no_grad()
    def run_step(self, input_data: dict, timestamp: float) -> carla.VehicleControl:
        """Image + measurements → model → control by the chosen planner."""
        if self.route is None:
            self.route = RouteState.of_agent(self)
        ego = self.route.update(input_data)
        rgb = jpeg_roundtrip(np.asarray(input_data["CAM_FRONT"][1])[:, :, :3])
        dev = self.device
        image = torch.from_numpy(rgb).unsqueeze(0).to(dev)
        state = torch.from_numpy(tcp_state(ego.speed, ego.target_point, ego.command)).unsqueeze(0).to(dev)
        target = torch.from_numpy(ego.target_point).unsqueeze(0).to(dev)
        pred = self.net(image, state, target)
        waypoints = pred["pred_wp"][0].float().cpu().numpy()
        traj = self.controller.step(waypoints, ego.speed, ego.target_point)
        action = action_control(int(pred["action_logits"][0].argmax()))
        if self.planner == "only_traj":
            out = traj
        elif self.planner == "only_ctrl":
            out = ControlOutput(action.steer, action.throttle, action.brake > 0.0, traj.desired_speed, 0.0, traj.aim)
        else:
            out = ControlOutput(
                0.5 * traj.steer + 0.5 * action.steer, 0.5 * traj.throttle + 0.5 * action.throttle,
                traj.brake or action.brake > 0.0, traj.desired_speed, traj.angle_final, traj.aim,
            )  # fmt: skip
        steer, throttle, brake = agent_control(out, ego.speed, self.throttle_cap)
        return carla.VehicleControl(throttle=float(throttle), steer=float(np.clip(steer, -1, 1)), brake=float(brake))

    def destroy(self) -> None:
        """Free the model."""
        self.net = None
