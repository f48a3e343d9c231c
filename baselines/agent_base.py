"""What the three baseline agents share: GNSS/IMU/speed sensors, the route in local coordinates, the target point.

An agent sees what a Bench2Drive agent sees: GNSS (lat, lon) turned into CARLA world x, y through the geo-reference
solved from the plan's first point (the plan gives both its GPS and its world position), the compass heading
(yaw = compass − 90°, a NaN compass counted as due south, ``b2d_data.coords`` fix 1), the speedometer and the IMU
accelerometer. The route target point and command come from the same planner that fills ``x_target`` /
``next_command`` while collecting (``b2d_data.collection.route_planners``: points within 7.5 m popped, 50 m look
ahead, over the dense plan downsampled at command changes and every 50 m), run on the dense plan
(``_plan_gps_HACK``), so a model meets the target point at test time as it met it in training.

Configuration string (``--agent-config``): a checkpoint path, or ``key=value`` pairs separated by commas
(``ckpt=runs/tcp/last.pt,planner=only_traj,throttle_cap=1``); ``b2d-eval run`` appends ``+<save_name>``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from b2d_data import coords
from b2d_data.collection.route_planners import CommandPlanners
from b2d_data.format.road_option import RoadOption
from b2d_data.maps.geolocation import EARTH_RADIUS_EQUA, GeoReference

from baselines.features import PoseHistory, to_ego

#: GNSS / IMU mounts of Bench2Drive's agents (and of the clips' rig).
GNSS_SPEC = {"type": "sensor.other.gnss", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "sensor_tick": 0.01, "id": "GPS"}  # fmt: skip
IMU_SPEC = {"type": "sensor.other.imu", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
            "sensor_tick": 0.05, "id": "IMU"}  # fmt: skip
SPEED_SPEC = {"type": "sensor.speedometer", "reading_frequency": 20, "id": "SPEED"}
#: Seconds per agent step (the Leaderboard's 20 Hz).
TICK_DT = 0.05


def parse_config(text: str) -> dict[str, str]:
    """``a.pt+save`` → {ckpt: a.pt}; ``k=v,k2=v2+save`` → {k: v, k2: v2} (the ``+<save_name>`` tail dropped)."""
    head = text.split("+")[0].strip() if text else ""
    if not head:
        return {}
    if "=" not in head:
        return {"ckpt": head}
    return {k.strip(): v.strip() for k, _, v in (item.partition("=") for item in head.split(",")) if k.strip()}


def geo_reference(lat: float, lon: float, x: float, y: float) -> GeoReference:
    """The map's geo-reference that puts GPS point (lat, lon) at world (x, y) (fixed point; converges in a few steps)."""
    lat_0 = lat
    for _ in range(10):
        scale = math.cos(math.radians(lat_0))
        merc = math.log(math.tan(math.radians(90.0 + lat) / 2.0)) + y / (EARTH_RADIUS_EQUA * scale)
        lat_0 = math.degrees(2.0 * math.atan(math.exp(merc))) - 90.0
    scale = math.cos(math.radians(lat_0))
    lon_0 = lon - math.degrees(x / (EARTH_RADIUS_EQUA * scale))
    return GeoReference(lat_0, lon_0)


@dataclass(frozen=True)
class EgoState:
    """One step's ego state as the sensors give it (CARLA world, radians, m/s)."""

    x: float
    y: float
    yaw: float
    speed: float
    accel: np.ndarray
    command: int
    target_point: np.ndarray  # (2,) in the CARLA ego frame


class RouteState:
    """The plan in local coordinates, the target planner and the pose history of one route."""

    def __init__(self, plan_gps: list[tuple[dict, Any]], first_gps: dict, first_world: Any) -> None:
        loc = first_world.location
        self.geo = geo_reference(float(first_gps["lat"]), float(first_gps["lon"]), float(loc.x), float(loc.y))
        self.route_xy = np.array([self.local(g["lat"], g["lon"]) for g, _ in plan_gps], np.float64)
        commands = [RoadOption(int(getattr(c, "value", c))) for _, c in plan_gps]
        self.planner = CommandPlanners.from_dense_route([tuple(p) for p in self.route_xy], commands).target
        self.history = PoseHistory(TICK_DT)
        self.progress = 0
        # The plan continued straight for 30 m: a route's last points count as passed only when driven through
        # (> 99 % of the route and within 10 m of its end), so waypoints that stop at the end would stall short.
        tail = self.route_xy[-1] - self.route_xy[-2] if len(self.route_xy) > 1 else np.array([1.0, 0.0])
        tail = tail / max(float(np.hypot(*tail)), 1e-6)
        extension = self.route_xy[-1] + np.arange(1, 31)[:, None] * tail
        self._ahead_xy = np.concatenate([self.route_xy, extension])

    @classmethod
    def of_agent(cls, agent: Any) -> RouteState:
        """The route state of a Leaderboard agent's global plan (dense GPS plan, first GPS and world points)."""
        return cls(agent._plan_gps_HACK, agent._global_plan[0][0], agent._global_plan_world_coord[0][0])

    def local(self, lat: float, lon: float) -> tuple[float, float]:
        """World x, y of a GPS fix."""
        p = self.geo.inverse(float(lat), float(lon))
        return p.x, p.y

    def update(self, input_data: dict) -> EgoState:
        """Read this step's GNSS, IMU and speed; advance the planner and the history."""
        lat, lon = input_data["GPS"][1][:2]
        imu = np.asarray(input_data["IMU"][1], np.float64)
        x, y = self.local(lat, lon)
        yaw = coords.compass_to_carla_yaw(float(imu[-1]))
        speed = float(input_data["SPEED"][1]["speed"])
        target = self.planner.run_step(x, y)
        self.history.append(x, y, yaw)
        tp = to_ego(np.array([[target.x, target.y]]), x, y, yaw)[0].astype(np.float32)
        return EgoState(x, y, yaw, speed, imu[:3].astype(np.float32), int(target.command), tp)

    def route_ahead(self, x: float, y: float, distances: np.ndarray) -> np.ndarray:
        """World points at the given arc lengths (m) ahead of the ego's projection on the dense route."""
        window = self._ahead_xy[self.progress : self.progress + 40]
        self.progress += int(np.argmin(np.hypot(window[:, 0] - x, window[:, 1] - y)))
        pts = self._ahead_xy[self.progress :]
        if len(pts) < 2:
            return np.repeat(self._ahead_xy[-1:], len(distances), axis=0)
        seg = np.hypot(*np.diff(pts, axis=0).T)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        return np.stack([np.interp(distances, s, pts[:, 0]), np.interp(distances, s, pts[:, 1])], axis=1)


def torch_device(options: dict[str, str]) -> str:
    """The agent's torch device: ``device=`` option, else cuda when available."""
    import torch

    if "device" in options:
        return options["device"]
    return "cuda" if torch.cuda.is_available() else "cpu"


def checkpoint_path(options: dict[str, str]) -> str:
    """The checkpoint to load: ``ckpt=`` option or ``$B2D_BASELINE_CKPT``."""
    path = options.get("ckpt") or os.environ.get("B2D_BASELINE_CKPT")
    if not path:
        raise ValueError("no checkpoint: pass --agent-config PATH/last.pt (or ckpt=PATH)")
    return path
