"""The builtin simulator's sensors: cameras (moderngl/EGL), LiDAR and radar (Embree), IMU, GNSS, speedometer.

Every sensor reads the same triangles: the static scene meshed once from the map and the actors meshed per tick,
so that boxes, LiDAR points, depth and segmentation agree. :class:`SensorSuite` is the entry point of the
Bench2Drive rig, :class:`MountedSensors` that of an agent's own sensors (CARLA's sensor data as a Leaderboard agent
reads it).
"""

from b2d_data.sim.builtin.sensors.mounted import MountedSensors
from b2d_data.sim.builtin.sensors.suite import CaptureTimings, SensorScene, SensorSuite

__all__ = ["CaptureTimings", "MountedSensors", "SensorScene", "SensorSuite"]
