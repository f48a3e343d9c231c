"""The roof LiDAR (``sensor.lidar.ray_cast``): 64 channels from +10° to −30°, a full 360° sweep per capture.

Points are returned the way Bench2Drive stores them: sensor-frame xyz plus the mount translation, i.e. in the
left-handed CARLA ego frame (x forward, y right, z up, origin at the ego actor origin).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from b2d_data.format.rig import LIDAR, LidarSpec
from b2d_data.sim.builtin.sensors.raycast import RayCaster


def lidar_directions(spec: LidarSpec, azimuth_steps: int) -> np.ndarray:
    """Unit ray directions in the sensor frame, (channels · azimuth_steps, 3), channel-major from the top.

    Channel elevations are uniform from ``upper_fov`` down to ``lower_fov`` (CARLA's layout); azimuths are uniform
    over 360° starting at the sensor's x axis and turning towards +y (clockwise seen from above, as CARLA spins).
    """
    elev = np.radians(np.linspace(spec.upper_fov, spec.lower_fov, spec.channels))
    azim = np.radians(np.arange(azimuth_steps) * (360.0 / azimuth_steps))
    ce, se = np.cos(elev)[:, None], np.sin(elev)[:, None]
    ca, sa = np.cos(azim)[None, :], np.sin(azim)[None, :]
    d = np.stack([ce * ca, ce * sa, np.broadcast_to(se, (spec.channels, azimuth_steps))], axis=-1)
    return d.reshape(-1, 3).astype(np.float32)


@dataclass
class LidarSweep:
    """One sweep: ego-frame points (N, 3) float32, their CARLA tags (N,) uint8 and actor ids (N,) int32."""

    points: np.ndarray
    tags: np.ndarray
    actor_ids: np.ndarray


class Lidar:
    """Casts the sweep of a :class:`LidarSpec` into a :class:`RayCaster`."""

    def __init__(self, spec: LidarSpec = LIDAR, azimuth_steps: int = 1000) -> None:
        self.spec = spec
        self.azimuth_steps = azimuth_steps
        self._dirs = lidar_directions(spec, azimuth_steps)
        m = spec.mount
        self.mount_translation = np.array([m.x, m.y, m.z], np.float32)

    def scan(self, caster: RayCaster, sensor_to_world: np.ndarray) -> LidarSweep:
        """One full sweep from the sensor pose (4×4 sensor → world)."""
        pose = np.asarray(sensor_to_world, np.float64)
        world_dirs = (self._dirs @ pose[:3, :3].T.astype(np.float32)).astype(np.float32)
        origin = pose[:3, 3].astype(np.float32)
        hits = caster.cast(origin[None, :], world_dirs, self.spec.range_m)
        keep = hits.hit
        # Sensor-frame point = direction · distance; Bench2Drive adds the mount translation (no rotation).
        pts = self._dirs[keep] * hits.t[keep, None] + self.mount_translation
        return LidarSweep(pts.astype(np.float32), hits.tags[keep], hits.actor_ids[keep])
