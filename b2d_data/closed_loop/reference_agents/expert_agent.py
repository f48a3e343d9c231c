"""b2d-data's privileged expert as a Leaderboard 2.0 agent (``b2d-eval run --agent expert``).

Like PDM-Lite, the expert is privileged: instead of sensors it reads the world state, the dense route and the running
scenarios' hints through the data provider (``CarlaDataProvider.get_b2d_route()``, b2d-data's extension of the
scenario runner's provider). By default it asks for no sensor, so an evaluation with it is physics only. Its driving
is the collection's expert (``ExpertConfig.for_builtin()``), seeded by the route's simulator seed.

``--agent-config rig=uniad`` mounts the sensor rig of Bench2DriveZoo's UniAD and VAD agents (six 1600×900 cameras,
the 512×512 ``bev`` camera 50 m up, IMU, GNSS, speedometer; the ``bev`` camera needs ``SAVE_PATH`` set, as in
Bench2Drive) and ignores its data: an agent that costs nearly nothing, to measure what the sensors cost
(``scripts/bench_eval.py``). ``width=W,height=H`` change the six cameras' size.
"""

from __future__ import annotations

import carla
from leaderboard.autoagents import autonomous_agent
from srunner.scenariomanager.carla_data_provider import CarlaDataProvider

from b2d_data.expert import Expert, ExpertConfig
from b2d_data.format.rig import CAMERAS


def get_entry_point() -> str:
    """The agent class the Leaderboard instantiates."""
    return "ExpertAgent"


class ExpertAgent(autonomous_agent.AutonomousAgent):
    """The PDM-Lite-style expert driving through the Leaderboard agent API."""

    def setup(self, path_to_conf_file: str) -> None:
        """Options ``rig=uniad``, ``width=W``, ``height=H`` (see the module docstring); the rest is the collection's."""
        self.track = autonomous_agent.Track.SENSORS
        self._expert: Expert | None = None
        head = path_to_conf_file.split("+")[0]
        self.options = dict(item.partition("=")[::2] for item in head.split(",") if "=" in item)

    def sensors(self) -> list[dict]:
        """Privileged: no sensor, or the UniAD/VAD rig with ``rig=uniad``."""
        if self.options.get("rig") != "uniad":
            return []
        width, height = int(self.options.get("width", 1600)), int(self.options.get("height", 900))
        rig = [
            {"type": "sensor.camera.rgb", "id": c.sensor_id, "x": c.mount.x, "y": c.mount.y, "z": c.mount.z,
             "roll": c.mount.roll, "pitch": c.mount.pitch, "yaw": c.mount.yaw, "width": width, "height": height,
             "fov": c.fov}
            for c in CAMERAS
        ]  # fmt: skip
        return rig + [
            {"type": "sensor.other.imu", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "sensor_tick": 0.05, "id": "IMU"},
            {"type": "sensor.other.gnss", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
             "sensor_tick": 0.01, "id": "GPS"},
            {"type": "sensor.speedometer", "reading_frequency": 20, "id": "SPEED"},
            {"type": "sensor.camera.rgb", "x": 0.0, "y": 0.0, "z": 50.0, "roll": 0.0, "pitch": -90.0, "yaw": 0.0,
             "width": 512, "height": 512, "fov": 50, "id": "bev"},
        ]  # fmt: skip

    def run_step(self, input_data: dict, timestamp: float) -> carla.VehicleControl:
        """The expert's control for this tick."""
        route = CarlaDataProvider.get_b2d_route()
        if self._expert is None:
            seed = int(getattr(route.sim, "seed", 0))
            self._expert = Expert(route.map, route.route, ExpertConfig.for_builtin(), seed=seed)
        control = self._expert.run_step(route.snapshot, route.hints)
        return carla.VehicleControl(throttle=control.throttle, steer=control.steer, brake=control.brake,
                                    hand_brake=control.hand_brake, reverse=control.reverse)
