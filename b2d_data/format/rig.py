"""The Bench2Drive sensor rig: mounts, fields of view and image sizes (format.md §2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from b2d_data.format.transform import Location, Rotation, Transform


@dataclass(frozen=True)
class Mount:
    """A sensor pose relative to the ego actor origin in CARLA's ego frame (x fwd, y right, z up; degrees)."""

    x: float
    y: float
    z: float
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def transform(self) -> Transform:
        """The sensor pose relative to the ego origin."""
        return Transform(Location(self.x, self.y, self.z), Rotation(pitch=self.pitch, yaw=self.yaw, roll=self.roll))

    def matrix(self) -> np.ndarray:
        """Sensor → ego 4×4 (CARLA ``get_matrix``): the ``cam2ego`` / ``lidar2ego`` / ``radar2ego`` of annotations."""
        return self.transform().matrix()


@dataclass(frozen=True)
class CameraSpec:
    """A pinhole camera of the rig; ``folder`` is the suffix of its ``camera/rgb_<folder>`` directory."""

    sensor_id: str
    folder: str
    mount: Mount
    fov: float
    width: int = 1600
    height: int = 900
    has_dense_labels: bool = True  # depth / semantic / instance are written for this camera

    @property
    def focal(self) -> float:
        """Focal length in pixels: W / (2 tan(FOV/2))."""
        return self.width / (2.0 * math.tan(self.fov * math.pi / 360.0))

    def intrinsic(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        """3×3 K as tools/utils.py builds it (principal point at the image centre, no skew)."""
        w = self.width if width is None else width
        h = self.height if height is None else height
        f = w / (2.0 * math.tan(self.fov * math.pi / 360.0))
        return np.array([[f, 0.0, w / 2.0], [0.0, f, h / 2.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class LidarSpec:
    """The roof LiDAR (``LIDAR_TOP``)."""

    sensor_id: str = "LIDAR_TOP"
    mount: Mount = Mount(-0.39, 0.0, 1.84)
    range_m: float = 85.0
    channels: int = 64
    rotation_frequency: float = 10.0
    points_per_second: int = 600_000
    upper_fov: float = 10.0
    lower_fov: float = -30.0
    atmosphere_attenuation_rate: float = 0.004


@dataclass(frozen=True)
class RadarSpec:
    """One of the 5 radars; ``dataset`` is its dataset name in ``radar/NNNNN.h5``."""

    sensor_id: str
    dataset: str
    mount: Mount
    range_m: float = 100.0
    horizontal_fov: float = 30.0
    vertical_fov: float = 30.0
    points_per_second: int = 1500


@dataclass(frozen=True)
class NoiseSpec:
    """GNSS / IMU mounts and noise (format.md §2.6)."""

    gnss_mount: Mount = Mount(-1.4, 0.0, 0.0)
    gnss_noise_deg: float = 5e-6  # std of lat / lon
    gnss_noise_alt: float = 5e-6
    imu_mount: Mount = Mount(-1.4, 0.0, 0.0)
    accel_noise: tuple[float, float, float] = (0.001, 0.001, 0.015)
    gyro_noise: tuple[float, float, float] = (0.001, 0.001, 0.001)


CAMERAS: tuple[CameraSpec, ...] = (
    CameraSpec("CAM_FRONT", "front", Mount(0.80, 0.00, 1.60, yaw=0.0), 70.0),
    CameraSpec("CAM_FRONT_LEFT", "front_left", Mount(0.27, -0.55, 1.60, yaw=-55.0), 70.0),
    CameraSpec("CAM_FRONT_RIGHT", "front_right", Mount(0.27, 0.55, 1.60, yaw=55.0), 70.0),
    CameraSpec("CAM_BACK", "back", Mount(-2.00, 0.00, 1.60, yaw=180.0), 110.0),
    CameraSpec("CAM_BACK_LEFT", "back_left", Mount(-0.32, -0.55, 1.60, yaw=-110.0), 70.0),
    CameraSpec("CAM_BACK_RIGHT", "back_right", Mount(-0.32, 0.55, 1.60, yaw=110.0), 70.0),
)
TOP_DOWN = CameraSpec("TOP_DOWN", "top_down", Mount(0.0, 0.0, 50.0, pitch=-90.0), 110.0, has_dense_labels=False)
ALL_CAMERAS: tuple[CameraSpec, ...] = CAMERAS + (TOP_DOWN,)

LIDAR = LidarSpec()

#: Radars as the released (v0) collector mounts them, including the BACK_RIGHT yaw bug (−90, fixed in v0.0.4).
RADARS_V0: tuple[RadarSpec, ...] = (
    RadarSpec("RADAR_FRONT", "radar_front", Mount(2.27, 0.00, 0.48, yaw=0.0)),
    RadarSpec("RADAR_FRONT_LEFT", "radar_front_left", Mount(1.21, -0.85, 0.74, yaw=-90.0)),
    RadarSpec("RADAR_FRONT_RIGHT", "radar_front_right", Mount(1.21, 0.85, 0.74, yaw=90.0)),
    RadarSpec("RADAR_BACK_LEFT", "radar_back_left", Mount(-2.00, -0.67, 0.51, yaw=-90.0)),
    RadarSpec("RADAR_BACK_RIGHT", "radar_back_right", Mount(-2.00, 0.67, 0.51, yaw=-90.0)),
)
#: Radars with both back radars looking backwards, as v0.0.4 fixed them.
RADARS_V004: tuple[RadarSpec, ...] = RADARS_V0[:3] + (
    RadarSpec("RADAR_BACK_LEFT", "radar_back_left", Mount(-2.00, -0.67, 0.51, yaw=180.0)),
    RadarSpec("RADAR_BACK_RIGHT", "radar_back_right", Mount(-2.00, 0.67, 0.51, yaw=180.0)),
)

NOISE = NoiseSpec()

#: Ego vehicle blueprint and its half extents (Lincoln MKZ 2020).
EGO_TYPE_ID = "vehicle.lincoln.mkz_2020"
EGO_HALF_EXTENT = (2.451, 1.064, 0.755)

#: Key order of ``anno["sensors"]`` (format.md §3.2).
SENSOR_ORDER: tuple[str, ...] = tuple(c.sensor_id for c in ALL_CAMERAS) + tuple(
    r.sensor_id for r in RADARS_V0
) + (LIDAR.sensor_id,)

CAMERA_BY_ID: dict[str, CameraSpec] = {c.sensor_id: c for c in ALL_CAMERAS}
CAMERA_BY_FOLDER: dict[str, CameraSpec] = {c.folder: c for c in ALL_CAMERAS}


def camera(name: str) -> CameraSpec:
    """Find a camera by sensor id (``CAM_FRONT``) or folder name (``front``, ``top_down``)."""
    spec = CAMERA_BY_ID.get(name) or CAMERA_BY_FOLDER.get(name)
    if spec is None:
        known = ", ".join(c.folder for c in ALL_CAMERAS)
        raise KeyError(f"unknown camera {name!r}; known: {known}")
    return spec
