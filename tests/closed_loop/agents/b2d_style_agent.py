"""A test agent written the way Bench2DriveZoo's agents are: module-level ``import carla`` and
``leaderboard.autoagents``, BGRA cameras converted with OpenCV and JPEG-compressed, compass from the IMU, GPS turned
into local coordinates through a geo-reference solved with scipy's ``fsolve`` from the plan's first point, per-step
files under ``$SAVE_PATH/<save_name>/`` when ``IS_BENCH2DRIVE`` is set, a ``carla.VehicleControl`` returned.

Besides driving (a plain waypoint follower on the downsampled plan), it writes what it perceived each step to
``meta/NNNN.json`` so that a test can compare it with the truth (``get_metric_info``).
"""
# ruff: noqa: UP018, UP031 - written in the style of the agents it stands for ("%04d.png" % step, float(0.0))

import json
import math
import os
import pathlib
from collections import deque

import carla
import cv2
import numpy as np
from leaderboard.autoagents import autonomous_agent
from scipy.optimize import fsolve

EARTH_RADIUS_EQUA = 6378137.0
SAVE_PATH = os.environ.get("SAVE_PATH", None)
IS_BENCH2DRIVE = os.environ.get("IS_BENCH2DRIVE", None)


def get_entry_point():
    return "B2DStyleAgent"


class B2DStyleAgent(autonomous_agent.AutonomousAgent):
    def setup(self, path_to_conf_file):
        self.track = autonomous_agent.Track.SENSORS
        self.step = -1
        self.initialized = False
        self.config_path = path_to_conf_file.split("+")[0]
        self.save_name = path_to_conf_file.split("+")[-1]
        self.metric_info = {}
        self.save_path = None
        if IS_BENCH2DRIVE and SAVE_PATH is not None:
            self.save_path = pathlib.Path(SAVE_PATH) / self.save_name
            self.save_path.mkdir(parents=True, exist_ok=False)
            (self.save_path / "rgb_front").mkdir()
            (self.save_path / "meta").mkdir()

    def _init(self):
        locx, locy = self._global_plan_world_coord[0][0].location.x, self._global_plan_world_coord[0][0].location.y
        lon, lat = self._global_plan[0][0]["lon"], self._global_plan[0][0]["lat"]

        def equations(variables):
            x, y = variables
            eq1 = lon * math.cos(x * math.pi / 180) - (locx * 180) / (math.pi * EARTH_RADIUS_EQUA) - math.cos(
                x * math.pi / 180) * y
            eq2 = math.log(math.tan((lat + 90) * math.pi / 360)) * EARTH_RADIUS_EQUA * math.cos(
                x * math.pi / 180) + locy - math.cos(x * math.pi / 180) * EARTH_RADIUS_EQUA * math.log(
                math.tan((90 + x) * math.pi / 360))
            return [eq1, eq2]

        self.lat_ref, self.lon_ref = fsolve(equations, [0, 0])
        self.targets = deque(
            (self.gps_to_location(np.array([gps["lat"], gps["lon"]])), command) for gps, command in self._global_plan
        )
        self.initialized = True

    def gps_to_location(self, gps):
        lat, lon = gps
        scale = math.cos(self.lat_ref * math.pi / 180.0)
        my = math.log(math.tan((lat + 90) * math.pi / 360.0)) * (EARTH_RADIUS_EQUA * scale)
        mx = (lon * (math.pi * EARTH_RADIUS_EQUA * scale)) / 180.0
        y = scale * EARTH_RADIUS_EQUA * math.log(math.tan((90.0 + self.lat_ref) * math.pi / 360.0)) - my
        x = mx - scale * self.lon_ref * math.pi * EARTH_RADIUS_EQUA / 180.0
        return np.array([x, y])

    def sensors(self):
        sensors = [
            {"type": "sensor.camera.rgb", "x": 0.80, "y": 0.0, "z": 1.60, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "width": 64, "height": 36, "fov": 70, "id": "CAM_FRONT"},
            {"type": "sensor.other.imu", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "sensor_tick": 0.05, "id": "IMU"},
            {"type": "sensor.other.gnss", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "sensor_tick": 0.01, "id": "GPS"},
            {"type": "sensor.speedometer", "reading_frequency": 20, "id": "SPEED"},
        ]
        if IS_BENCH2DRIVE:
            sensors.append({"type": "sensor.camera.rgb", "x": 0.0, "y": 0.0, "z": 50.0, "roll": 0.0, "pitch": -90.0,
                            "yaw": 0.0, "width": 64, "height": 64, "fov": 50, "id": "bev"})
        return sensors

    def tick(self, input_data):
        bgra = input_data["CAM_FRONT"][1]
        img = cv2.cvtColor(bgra[:, :, :3], cv2.COLOR_BGR2RGB)
        _, encoded = cv2.imencode(".jpg", img, [int(cv2.IMWRITE_JPEG_QUALITY), 20])
        img = cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED)
        gps = input_data["GPS"][1][:2]
        speed = input_data["SPEED"][1]["speed"]
        compass = input_data["IMU"][1][-1]
        if math.isnan(compass):
            compass = 0.0
        return {"rgb": img, "bgra": bgra, "gps": gps, "speed": speed, "compass": compass,
                "pos": self.gps_to_location(gps), "frame": input_data["CAM_FRONT"][0]}

    def run_step(self, input_data, timestamp):
        if not self.initialized:
            self._init()
        self.step += 1
        data = self.tick(input_data)
        pos = data["pos"]
        while len(self.targets) > 1 and np.linalg.norm(self.targets[0][0] - pos) < 4.0:
            self.targets.popleft()
        target = self.targets[0][0]
        theta = data["compass"] - np.pi / 2  # CARLA's compass is the yaw + 90 degrees
        direction = target - pos
        angle = math.atan2(direction[1], direction[0]) - theta
        angle = (angle + math.pi) % (2 * math.pi) - math.pi
        control = carla.VehicleControl()
        control.steer = float(np.clip(1.25 * angle / (math.pi / 2), -1.0, 1.0))
        control.throttle = float(0.5 if data["speed"] < 4.0 else 0.0)
        control.brake = float(0.0)
        metric_info = self.get_metric_info()
        self.metric_info[self.step] = metric_info
        if self.save_path is not None:
            cv2.imwrite(str(self.save_path / "rgb_front" / ("%04d.png" % self.step)), data["rgb"])
            meta = {
                "step": self.step, "frame": int(data["frame"]), "timestamp": timestamp,
                "gps_xy": [float(v) for v in pos], "true_xy": metric_info["location"][:2],
                "compass_yaw": float(np.degrees(theta)), "true_yaw": metric_info["rotation"][2],
                "speed": float(data["speed"]), "image_shape": list(data["bgra"].shape),
                "image_dtype": str(data["bgra"].dtype), "alpha": int(data["bgra"][:, :, 3].min()),
                "sky_bgr": [float(v) for v in data["bgra"][:3, :, :3].reshape(-1, 3).mean(axis=0)],
                "bev_shape": list(input_data["bev"][1].shape) if "bev" in input_data else None,
                "sensors": sorted(input_data),
            }
            with open(self.save_path / "meta" / ("%04d.json" % self.step), "w") as f:
                json.dump(meta, f)
        return control

    def destroy(self):
        if self.save_path is not None:
            with open(self.save_path / "metric_info.json", "w") as f:
                json.dump(self.metric_info, f)
