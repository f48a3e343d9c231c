"""A minimal sensor-only Leaderboard 2.0 agent: follows the route from GNSS, IMU and speedometer, stops for LiDAR
obstacles.

It touches only what a CARLA Leaderboard agent may: its sensors and the route the evaluator hands over
(``set_global_plan``). It is an example of the agent API, not a good driver: it sees no traffic light or stop sign
and brakes for anything in a straight corridor ahead. Run it with::

    b2d-eval run --agent examples/sensor_agent.py --routes bench2drive220.xml --out eval/sensor_agent

What it does each step:

1. GNSS (lat, lon) → local CARLA x, y, with the geo-reference solved once from the first route point (the plan gives
   both its GPS and its world position; Bench2DriveZoo's agents solve the same equations with scipy's fsolve).
2. Heading from the IMU compass (CARLA's compass is the yaw + 90°).
3. Pure pursuit on the route's GPS points (``_plan_gps_HACK``, the dense plan Bench2Drive's base class keeps),
   steering with a PID on the heading error to a look-ahead point.
4. Speed: a PID towards 6 m/s (4 m/s where the route bends ahead); full brake when at least 5 LiDAR points of the
   last full sweep stand in a corridor 3 m wide ahead, within the stopping distance.
"""

from __future__ import annotations

import math
from collections import deque

import carla
import numpy as np
from leaderboard.autoagents import autonomous_agent

EARTH_RADIUS_EQUA = 6378137.0
CRUISE_SPEED = 6.0  # m/s
CURVE_SPEED = 4.0  # m/s
LIDAR_HEIGHT = 2.5  # m above the ego origin
LIDAR_X = 1.3  # m ahead of the ego origin


def get_entry_point() -> str:
    """The class the evaluator instantiates."""
    return "SensorAgent"


class PID:
    """A PID controller with a windowed integral (the form TCP's and Transfuser's controllers use)."""

    def __init__(self, k_p: float, k_i: float, k_d: float, window: int = 20) -> None:
        self.k_p, self.k_i, self.k_d = k_p, k_i, k_d
        self.errors: deque[float] = deque([0.0] * window, maxlen=window)

    def step(self, error: float) -> float:
        """Control for this error."""
        self.errors.append(error)
        integral = float(np.mean(self.errors))
        derivative = self.errors[-1] - self.errors[-2]
        return self.k_p * error + self.k_i * integral + self.k_d * derivative


def geo_reference(lat: float, lon: float, x: float, y: float) -> tuple[float, float]:
    """The (lat_ref, lon_ref) that put GPS point (lat, lon) at world (x, y) under the Leaderboard's projection."""
    lat_ref = lat
    for _ in range(8):  # fixed point: y / R is tiny, so this converges to machine precision in a few steps
        scale = math.cos(math.radians(lat_ref))
        mercator = math.log(math.tan((90.0 + lat) * math.pi / 360.0)) + y / (EARTH_RADIUS_EQUA * scale)
        lat_ref = math.degrees(2.0 * math.atan(math.exp(mercator))) - 90.0
    scale = math.cos(math.radians(lat_ref))
    lon_ref = lon - x * 180.0 / (math.pi * EARTH_RADIUS_EQUA * scale)
    return lat_ref, lon_ref


def gps_to_local(lat: float, lon: float, lat_ref: float, lon_ref: float) -> tuple[float, float]:
    """World x, y (CARLA frame) of a GPS point: the inverse of the Leaderboard's ``_location_to_gps``."""
    scale = math.cos(math.radians(lat_ref))
    x = (lon - lon_ref) * math.pi * EARTH_RADIUS_EQUA * scale / 180.0
    my_ref = scale * EARTH_RADIUS_EQUA * math.log(math.tan((90.0 + lat_ref) * math.pi / 360.0))
    my = scale * EARTH_RADIUS_EQUA * math.log(math.tan((90.0 + lat) * math.pi / 360.0))
    return x, my_ref - my


class SensorAgent(autonomous_agent.AutonomousAgent):
    """Route following from GNSS/IMU/speed with a LiDAR emergency brake."""

    def setup(self, path_to_conf_file: str) -> None:
        """Controllers and state; the configuration string is not used."""
        self.track = autonomous_agent.Track.SENSORS
        self.turn = PID(1.25, 0.75, 0.3, window=40)
        self.speed = PID(5.0, 0.5, 1.0, window=40)
        self.route_xy: np.ndarray | None = None
        self.progress = 0
        self.sweeps: deque[np.ndarray] = deque(maxlen=2)  # each tick brings half a LiDAR turn

    def sensors(self) -> list[dict]:
        """GNSS and IMU where Bench2Drive's agents mount them, the speedometer, a roof LiDAR."""
        return [
            {"type": "sensor.other.gnss", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "sensor_tick": 0.01, "id": "GPS"},
            {"type": "sensor.other.imu", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "sensor_tick": 0.05, "id": "IMU"},
            {"type": "sensor.speedometer", "reading_frequency": 20, "id": "SPEED"},
            {"type": "sensor.lidar.ray_cast", "x": LIDAR_X, "y": 0.0, "z": LIDAR_HEIGHT, "roll": 0.0, "pitch": 0.0,
             "yaw": 0.0, "id": "LIDAR"},
        ]  # fmt: skip

    def _init_route(self) -> None:
        """The dense route in local coordinates, through the geo-reference of its first point."""
        first_gps, _ = self._global_plan[0]
        first_world, _ = self._global_plan_world_coord[0]
        self.lat_ref, self.lon_ref = geo_reference(first_gps["lat"], first_gps["lon"], first_world.location.x,
                                                   first_world.location.y)  # fmt: skip
        points = [gps_to_local(g["lat"], g["lon"], self.lat_ref, self.lon_ref) for g, _ in self._plan_gps_HACK]
        self.route_xy = np.array(points)

    def _aim(self, position: np.ndarray, speed: float) -> tuple[np.ndarray, float]:
        """The look-ahead point and how much the route bends over the next 15 m (radians)."""
        assert self.route_xy is not None
        window = self.route_xy[self.progress : self.progress + 30]
        self.progress += int(np.argmin(np.linalg.norm(window - position, axis=1)))
        ahead = max(4.0, 0.8 * speed + 3.0)
        index = min(self.progress + int(ahead), len(self.route_xy) - 1)
        far = min(self.progress + 15, len(self.route_xy) - 1)
        seg0 = self.route_xy[min(self.progress + 1, far)] - self.route_xy[self.progress]
        seg1 = self.route_xy[far] - self.route_xy[max(far - 1, self.progress)]
        bend = abs(math.atan2(seg0[0] * seg1[1] - seg0[1] * seg1[0], float(seg0 @ seg1))) if far > self.progress else 0.0
        return self.route_xy[index], bend

    def _obstacle(self, speed: float) -> bool:
        """Whether the last full LiDAR sweep has points in the corridor ahead within the stopping distance."""
        if not self.sweeps:
            return False
        points = np.concatenate(list(self.sweeps))
        reach = 3.0 + speed * speed / (2.0 * 4.0) + 1.5 * speed
        x, y, z = points[:, 0], points[:, 1], points[:, 2]
        above_ground = (z > -LIDAR_HEIGHT + 0.4) & (z < 0.0)
        corridor = (x > 2.5 - LIDAR_X) & (x < reach) & (np.abs(y) < 1.5)
        return int(np.count_nonzero(above_ground & corridor)) >= 5

    def run_step(self, input_data: dict, timestamp: float) -> carla.VehicleControl:
        """Steer to the look-ahead point, hold the target speed, brake for obstacles."""
        if self.route_xy is None:
            self._init_route()
        lat, lon = input_data["GPS"][1][:2]
        compass = float(input_data["IMU"][1][-1])
        speed = float(input_data["SPEED"][1]["speed"])
        self.sweeps.append(np.asarray(input_data["LIDAR"][1]))
        if math.isnan(compass):  # CARLA's compass can be NaN facing due south
            compass = math.pi
        yaw = compass - math.pi / 2.0
        position = np.array(gps_to_local(float(lat), float(lon), self.lat_ref, self.lon_ref))
        aim, bend = self._aim(position, speed)
        direction = aim - position
        error = math.atan2(direction[1], direction[0]) - yaw
        error = (error + math.pi) % (2.0 * math.pi) - math.pi
        steer = float(np.clip(self.turn.step(error / (math.pi / 2.0)), -1.0, 1.0))
        target = CURVE_SPEED if bend > 0.35 else CRUISE_SPEED
        control = carla.VehicleControl()
        control.steer = steer
        if self._obstacle(speed):
            control.throttle, control.brake = 0.0, 1.0
            return control
        throttle = float(np.clip(self.speed.step(target - speed), 0.0, 0.75))
        control.throttle = throttle
        control.brake = 1.0 if speed > target * 1.3 else 0.0
        return control
