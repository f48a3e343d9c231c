"""``leaderboard.autoagents.autonomous_agent``: the base class of Leaderboard agents, as Bench2Drive's fork has it.

Bench2Drive's changes to the Leaderboard 2.0 class are kept: the constructor looks the ego up (``self.hero_actor``),
``set_global_plan`` downsamples to 50 m (not 200) and keeps the full plan in ``_plan_HACK`` / ``_plan_gps_HACK``, and
``get_metric_info`` reports the ego's motion for the efficiency and comfort metrics.
"""

from __future__ import annotations

import logging
from typing import Any

import carla
from srunner.scenariomanager.carla_data_provider import CarlaDataProvider
from srunner.scenariomanager.timer import GameTime

from b2d_data.closed_loop.sensor_config import Track
from leaderboard.envs.sensor_interface import SensorInterface
from leaderboard.utils.route_manipulation import downsample_route

__all__ = ["AutonomousAgent", "Track"]

log = logging.getLogger(__name__)

#: Bench2Drive's plan spacing (m) for ``set_global_plan`` (the Leaderboard 2.0 uses 200).
PLAN_SAMPLE_DISTANCE = 50


class AutonomousAgent:
    """Base class of an agent: declare ``sensors()``, implement ``setup()`` and ``run_step()``."""

    def __init__(self, carla_host: str, carla_port: int, debug: bool = False) -> None:
        self.track = Track.SENSORS
        #  current global plans to reach a destination
        self._global_plan: list[tuple[dict, Any]] | None = None
        self._global_plan_world_coord: list[tuple[carla.Transform, Any]] | None = None
        # this data structure will contain all sensor data
        self.sensor_interface = SensorInterface()
        self.wallclock_t0 = None
        self.hero_actor: carla.Actor | None = None
        self.get_hero()

    def setup(self, path_to_conf_file: str) -> None:
        """Initialise the agent from its configuration (called after ``set_global_plan``)."""
        return

    def sensors(self) -> list[dict[str, Any]]:
        """The agent's sensor specs (``[{'type': ..., 'id': ..., 'x': ...}]``)."""
        return []

    def run_step(self, input_data: dict[str, tuple[int, Any]], timestamp: float) -> carla.VehicleControl:
        """One step: sensor data in, control out (the base class stands still)."""
        return carla.VehicleControl(throttle=0.0, steer=0.0, brake=0.0)

    def destroy(self) -> None:
        """Release the agent's resources at the end of a route."""
        return

    @staticmethod
    def get_ros_version() -> int:
        """-1: not a ROS agent."""
        return -1

    def __call__(self) -> carla.VehicleControl:
        """The evaluator's call each tick: this frame's sensor data and game time → ``run_step`` → its control."""
        input_data = self.sensor_interface.get_data(GameTime.get_frame())
        timestamp = GameTime.get_time()
        if not self.wallclock_t0:
            self.wallclock_t0 = GameTime.get_wallclocktime()
        wallclock = GameTime.get_wallclocktime()
        wallclock_diff = (wallclock - self.wallclock_t0).total_seconds()
        if log.isEnabledFor(logging.DEBUG):
            ratio = 0.0 if wallclock_diff == 0 else timestamp / wallclock_diff
            log.debug("agent step: wallclock %s, system time %.3f s, game time %.3f s, ratio %.3fx",
                      wallclock, wallclock_diff, timestamp, ratio)  # fmt: skip
        control = self.run_step(input_data, timestamp)
        control.manual_gear_shift = False
        return control

    def set_global_plan(
        self, global_plan_gps: list[tuple[dict, Any]], global_plan_world_coord: list[tuple[carla.Transform, Any]]
    ) -> None:
        """Set the route: the full plan in ``_plan_HACK`` / ``_plan_gps_HACK``, the 50 m downsampling in
        ``_global_plan_world_coord`` / ``_global_plan``."""
        self._plan_gps_HACK = global_plan_gps
        self._plan_HACK = global_plan_world_coord
        ds_ids = downsample_route(global_plan_world_coord, PLAN_SAMPLE_DISTANCE)
        self._global_plan_world_coord = [(global_plan_world_coord[x][0], global_plan_world_coord[x][1])
                                         for x in ds_ids]  # fmt: skip
        self._global_plan = [global_plan_gps[x] for x in ds_ids]

    def get_hero(self) -> None:
        """Find the ego (``role_name == 'hero'``) among the world's actors into ``self.hero_actor``."""
        hero_actor = None
        for actor in CarlaDataProvider.get_world().get_actors():
            if actor.attributes.get("role_name") == "hero":
                hero_actor = actor
                break
        self.hero_actor = hero_actor

    def get_metric_info(self) -> dict[str, list[float]]:
        """The ego's acceleration, angular velocity, forward/right vectors, location ([x, y, z]) and rotation
        ([roll, pitch, yaw]) after the last tick (Bench2Drive's ``metric_info.json`` entry)."""
        if self.hero_actor is None:
            raise RuntimeError("get_metric_info: no ego vehicle (an actor with role_name 'hero') was found")

        def as_list(vector: Any, rotation: bool = False) -> list[float]:
            if rotation:
                return [vector.roll, vector.pitch, vector.yaw]
            return [vector.x, vector.y, vector.z]

        transform = self.hero_actor.get_transform()
        return {
            "acceleration": as_list(self.hero_actor.get_acceleration()),
            "angular_velocity": as_list(self.hero_actor.get_angular_velocity()),
            "forward_vector": as_list(transform.get_forward_vector()),
            "right_vector": as_list(transform.get_right_vector()),
            "location": as_list(transform.location),
            "rotation": as_list(transform.rotation, rotation=True),
        }
