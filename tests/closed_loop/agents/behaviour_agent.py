"""A test agent whose misbehaviour is chosen by its configuration string: ``key=value`` pairs joined by ``,``
for every route, or ``<route id>:<pairs>`` groups joined by ``;`` for one route each.

``raise_at=N``: run_step raises at step N. ``setup_error``: setup raises. ``init_error``: the constructor raises.
``sleep_at=N:S``: step N sleeps S seconds. ``segfault_at=N``: the process kills itself with SIGSEGV at step N.
``return_none``: run_step returns None. ``sensor=full``: a camera, a LiDAR, a radar, GNSS, IMU and speedometer;
``stand``: full brake, never moves.
``dump``: at step 3 write what each sensor delivered to ``$SAVE_PATH/<save_name>_inputs.json``. ``nan_steer``: steer is NaN. ``sensor=<kind>``: an invalid rig (``radius``:
a camera 5 m away; ``duplicate``: two sensors with one id; ``too_many``: three LiDARs; ``opendrive``: an OpenDRIVE
map on the SENSORS track; ``unknown``: an unknown sensor type). Otherwise it drives straight at a gentle throttle.
"""

from __future__ import annotations

import json
import os
import signal
import time

import carla
from leaderboard.autoagents import autonomous_agent


def get_entry_point() -> str:
    """The class to instantiate."""
    return "BehaviourAgent"


def _options(config: str) -> dict[str, str]:
    """The options for this route: ``opts`` applies to every route, ``<route id>:opts;...`` to one route each."""
    head, save_name = config.split("+")[0], config.split("+")[-1]
    route_id = save_name.split("_")[1] if save_name.startswith("RouteScenario_") else ""
    chosen = ""
    for part in head.split(";"):
        key, sep, opts = part.partition(":")
        if not sep or not key.isdigit():
            chosen = part
        elif key == route_id:
            chosen = opts
            break
    pairs = (item.partition("=") for item in chosen.split(",") if item)
    return {key: value for key, _, value in pairs}


class BehaviourAgent(autonomous_agent.AutonomousAgent):
    """Drives straight, or fails in the way its configuration asks."""

    def __init__(self, carla_host, carla_port, debug=False):
        super().__init__(carla_host, carla_port, debug)
        if os.environ.get("B2D_TEST_INIT_ERROR"):
            raise RuntimeError("constructor failed on purpose")

    def setup(self, path_to_conf_file):
        self.options = _options(path_to_conf_file)
        self.save_name = path_to_conf_file.split("+")[-1]
        self.step = -1
        if "setup_error" in self.options:
            raise ValueError("setup failed on purpose")

    def sensors(self):
        kind = self.options.get("sensor")
        camera = {"type": "sensor.camera.rgb", "x": 0.8, "y": 0.0, "z": 1.6, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
                  "width": 32, "height": 24, "fov": 70, "id": "CAM"}
        speed = {"type": "sensor.speedometer", "reading_frequency": 20, "id": "SPEED"}
        if kind == "full":
            lidar = {"type": "sensor.lidar.ray_cast", "x": 0.0, "y": 0.0, "z": 2.5, "roll": 0.0, "pitch": 0.0,
                     "yaw": 0.0, "id": "LIDAR"}
            radar = {"type": "sensor.other.radar", "x": 2.2, "y": 0.0, "z": 0.5, "roll": 0.0, "pitch": 0.0,
                     "yaw": 0.0, "horizontal_fov": 30, "vertical_fov": 30, "id": "RADAR"}
            gnss = {"type": "sensor.other.gnss", "x": -1.4, "y": 0.0, "z": 0.0, "id": "GPS"}
            imu = {"type": "sensor.other.imu", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
                   "id": "IMU"}
            return [camera, lidar, radar, gnss, imu, speed]
        if kind == "radius":
            return [dict(camera, x=5.0), speed]
        if kind == "duplicate":
            return [camera, dict(speed, id="CAM")]
        if kind == "too_many":
            lidar = {"type": "sensor.lidar.ray_cast", "x": 0.0, "y": 0.0, "z": 2.0, "roll": 0.0, "pitch": 0.0,
                     "yaw": 0.0}
            return [dict(lidar, id=f"L{i}") for i in range(3)]
        if kind == "opendrive":
            return [{"type": "sensor.opendrive_map", "reading_frequency": 1, "id": "MAP"}]
        if kind == "unknown":
            return [{"type": "sensor.camera.thermal", "x": 0.0, "y": 0.0, "z": 1.0, "id": "T"}]
        return [speed]

    def run_step(self, input_data, timestamp):
        self.step += 1
        options = self.options
        if options.get("raise_at") == str(self.step):
            raise RuntimeError(f"run_step failed on purpose at step {self.step}")
        if "sleep_at" in options:
            at, _, seconds = options["sleep_at"].partition(":")
            if at == str(self.step):
                time.sleep(float(seconds))
        if options.get("segfault_at") == str(self.step):
            os.kill(os.getpid(), signal.SIGSEGV)
        if "dump" in options and self.step == 3:
            described = {
                key: {"frame": frame, "type": type(data).__name__,
                      "shape": list(getattr(data, "shape", ())), "dtype": str(getattr(data, "dtype", "")),
                      "keys": sorted(data) if isinstance(data, dict) else None}
                for key, (frame, data) in input_data.items()
            }
            with open(os.path.join(os.environ["SAVE_PATH"], f"{self.save_name}_inputs.json"), "w") as f:
                json.dump({"timestamp": timestamp, "inputs": described}, f)
        if "return_none" in options:
            return None
        control = carla.VehicleControl()
        if "stand" in options:
            control.brake = 1.0
            return control
        control.throttle = 0.75 if input_data["SPEED"][1]["speed"] < 5.0 else 0.0
        control.steer = float("nan") if "nan_steer" in options else 0.0
        return control
