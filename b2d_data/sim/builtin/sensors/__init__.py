"""The builtin simulator's sensors: cameras (moderngl/EGL), LiDAR and radar (Embree), IMU, GNSS, speedometer.

Every sensor reads the same triangles: the static scene meshed once from the map and the actors meshed per tick,
so that boxes, LiDAR points, depth and segmentation agree. :class:`SensorSuite` is the entry point.
"""

from b2d_data.sim.builtin.sensors.suite import CaptureTimings, SensorSuite

__all__ = ["CaptureTimings", "SensorSuite"]
