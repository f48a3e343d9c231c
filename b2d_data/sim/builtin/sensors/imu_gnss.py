"""IMU, GNSS and speedometer of the rig (format.md §2.6), with the Bench2Drive noise from a seeded generator.

CARLA conventions reproduced here:

- accelerometer: the sensor's acceleration plus gravity (+9.81 m/s² on world z), expressed in the sensor axes,
  so a car at rest reads (0, 0, 9.81);
- gyroscope: angular velocity in rad/s in the sensor axes;
- compass: angle from north = −y to the sensor's forward vector (horizontal), in [0, 2π); it equals
  yaw (rad) + π/2 mod 2π;
- GNSS: the sensor location through the town's geo-reference (spherical Mercator, y flipped), plus noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from b2d_data.format.rig import NOISE, Mount, NoiseSpec
from b2d_data.format.transform import Location, Transform
from b2d_data.sim.api import ActorState, GnssReading, ImuReading

#: CARLA's gravity constant in the IMU.
GRAVITY = 9.81
#: CARLA's equatorial earth radius for the geolocation projection.
EARTH_RADIUS_EQUA = 6378137.0


def compass_of(forward_x: float, forward_y: float) -> float:
    """CARLA's compass: angle between north (0, −1) and the horizontal forward direction, in [0, 2π).

    CARLA only guards ``dot ≥ 1``; here the dot product is clamped to [−1, 1] as well, so a heading of due south
    gives π instead of CARLA's occasional NaN.
    """
    norm = math.hypot(forward_x, forward_y)
    if norm == 0.0:
        return 0.0
    fx, fy = forward_x / norm, forward_y / norm
    dot = -fy
    if dot >= 1.0:
        return 0.0
    angle = math.acos(max(-1.0, dot))
    # z of cross(north, forward) = north_x·f_y − north_y·f_x = f_x.
    return 2.0 * math.pi - angle if fx < 0.0 else angle


def carla_geolocation(
    location: Location, lat0: float = 0.0, lon0: float = 0.0, alt0: float = 0.0
) -> tuple[float, float, float]:
    """CARLA's ``GeoLocation.Transform``: (lat, lon, alt) of a world location for a geo-reference origin."""
    scale = math.cos(math.radians(lat0))
    mx = scale * math.radians(lon0) * EARTH_RADIUS_EQUA + location.x
    my = scale * EARTH_RADIUS_EQUA * math.log(math.tan((90.0 + lat0) * math.pi / 360.0)) - location.y
    lon = mx * 180.0 / (math.pi * EARTH_RADIUS_EQUA * scale)
    lat = 360.0 * math.atan(math.exp(my / (EARTH_RADIUS_EQUA * scale))) / math.pi - 90.0
    return lat, lon, alt0 + location.z


def _as_lat_lon_alt(geo: object) -> tuple[float, float, float]:
    """Accept a GeoLocation-like object (latitude/longitude/altitude) or a 3-sequence."""
    if hasattr(geo, "latitude"):
        return float(geo.latitude), float(geo.longitude), float(getattr(geo, "altitude", 0.0))
    lat, lon, alt = geo  # type: ignore[misc]
    return float(lat), float(lon), float(alt)


def geolocator_of(town_map: object | None) -> Callable[[Location], tuple[float, float, float]]:
    """The map's ``transform_to_geolocation`` when it has one, else CARLA's projection with a (0, 0, 0) origin."""
    fn = getattr(town_map, "transform_to_geolocation", None) if town_map is not None else None
    if fn is None:
        return carla_geolocation
    return lambda loc: _as_lat_lon_alt(fn(loc))


@dataclass(frozen=True)
class ImuNoise:
    """IMU noise per sensor axis (CARLA's ``noise_accel_stddev_*``, ``noise_gyro_stddev_*``, ``noise_gyro_bias_*``)."""

    accel_stddev: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_stddev: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class GnssNoise:
    """GNSS noise of latitude, longitude (degrees) and altitude (m): standard deviations and biases."""

    stddev: tuple[float, float, float] = (0.0, 0.0, 0.0)
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)


def imu_reading(ego: ActorState, sensor_to_world: np.ndarray, rng: np.random.Generator, noise: ImuNoise) -> ImuReading:
    """The IMU of a sensor rigidly mounted on the ego (pose 4×4 sensor → world); draws accelerometer then gyroscope
    noise from ``rng``."""
    rot = sensor_to_world[:3, :3]
    omega = np.radians(ego.angular_velocity.to_array())
    # Rigid-body lever arm of the mount: centripetal term of the yaw rate (roll/pitch rates are small).
    lever = sensor_to_world[:3, 3] - ego.transform.location.to_array()
    yaw_rate = omega[2]
    centripetal = np.array([-lever[0], -lever[1], 0.0]) * yaw_rate * yaw_rate
    accel_world = ego.acceleration.to_array() + centripetal + np.array([0.0, 0.0, GRAVITY])
    accel = rot.T @ accel_world + rng.normal(0.0, noise.accel_stddev)
    gyro = rot.T @ omega + rng.normal(0.0, noise.gyro_stddev) + np.asarray(noise.gyro_bias)
    return ImuReading(
        accelerometer=(float(accel[0]), float(accel[1]), float(accel[2])),
        gyroscope=(float(gyro[0]), float(gyro[1]), float(gyro[2])),
        compass=compass_of(rot[0, 0], rot[1, 0]),
    )


def gnss_reading(
    location: np.ndarray,
    geolocate: Callable[[Location], tuple[float, float, float]],
    rng: np.random.Generator,
    noise: GnssNoise,
) -> GnssReading:
    """The GNSS fix of a world location; draws latitude, longitude then altitude noise from ``rng``."""
    lat, lon, alt = geolocate(Location.from_array(location))
    lat_bias, lon_bias, alt_bias = noise.bias
    lat_std, lon_std, alt_std = noise.stddev
    return GnssReading(
        latitude=lat + lat_bias + float(rng.normal(0.0, lat_std)),
        longitude=lon + lon_bias + float(rng.normal(0.0, lon_std)),
        altitude=alt + alt_bias + float(rng.normal(0.0, alt_std)),
    )


@dataclass
class ImuGnss:
    """Reads IMU, GNSS and speedometer from the ego state; noise is seeded by ``seed`` and the frame number."""

    noise: NoiseSpec = NOISE
    seed: int = 0
    _mount: tuple[Mount, np.ndarray] | None = field(default=None, init=False, repr=False, compare=False)

    def sensor_pose(self, ego: ActorState) -> np.ndarray:
        """IMU / GNSS sensor → world 4×4 (both share the mount)."""
        return ego.transform.matrix() @ self._mount_matrix()

    def _mount_matrix(self) -> np.ndarray:
        """Sensor → ego 4×4 of the mount, worked out once per mount (the noise spec is frozen)."""
        m = self.noise.imu_mount
        if self._mount is None or self._mount[0] != m:
            self._mount = (m, Transform(Location(m.x, m.y, m.z)).matrix())
        return self._mount[1]

    def read(
        self, ego: ActorState, frame: int, geolocate: Callable[[Location], tuple[float, float, float]]
    ) -> tuple[ImuReading, GnssReading, float]:
        """(IMU, GNSS, speed) at this tick."""
        rng = np.random.default_rng([self.seed, frame, 77])
        pose = self.sensor_pose(ego)
        imu = imu_reading(ego, pose, rng, ImuNoise(self.noise.accel_noise, self.noise.gyro_noise))
        deg, alt = self.noise.gnss_noise_deg, self.noise.gnss_noise_alt
        gnss = gnss_reading(pose[:3, 3], geolocate, rng, GnssNoise((deg, deg, alt)))
        return imu, gnss, float(ego.forward_speed())
