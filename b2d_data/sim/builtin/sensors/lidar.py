"""LiDARs (``sensor.lidar.ray_cast``): the Bench2Drive roof LiDAR and CARLA's spinning ray-cast LiDAR.

:class:`Lidar` is the data-collection rig's LiDAR: 64 channels from +10° to −30°, a full 360° sweep per capture,
points returned the way Bench2Drive stores them: sensor-frame xyz plus the mount translation, i.e. in the
left-handed CARLA ego frame (x forward, y right, z up, origin at the ego actor origin).

:class:`SpinningLidar` is the LiDAR as CARLA 0.9.15 delivers it to a Leaderboard agent: each tick the part of the
turn swept since the previous tick, with CARLA's general and intensity drop-off, as (N, 4) x, y, z, intensity in
the sensor frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from b2d_data.format.rig import LIDAR, LidarSpec
from b2d_data.sim.api import FIXED_DELTA_SECONDS
from b2d_data.sim.builtin.sensors.raycast import RayCaster, RayHits


def _directions(elevations: np.ndarray, azimuths: np.ndarray) -> np.ndarray:
    """Unit directions (len(elevations) · len(azimuths), 3) float32 of every (elevation, azimuth) pair in radians,
    channel-major."""
    ce, se = np.cos(elevations)[:, None], np.sin(elevations)[:, None]
    ca, sa = np.cos(azimuths)[None, :], np.sin(azimuths)[None, :]
    d = np.stack([ce * ca, ce * sa, np.broadcast_to(se, (len(elevations), len(azimuths)))], axis=-1)
    return d.reshape(-1, 3).astype(np.float32)


def channel_elevations(spec: LidarSpec) -> np.ndarray:
    """Channel elevations in radians, uniform from ``upper_fov`` down to ``lower_fov`` (CARLA's laser layout)."""
    return np.radians(np.linspace(spec.upper_fov, spec.lower_fov, spec.channels))


def lidar_directions(spec: LidarSpec, azimuth_steps: int) -> np.ndarray:
    """Unit ray directions in the sensor frame, (channels · azimuth_steps, 3), channel-major from the top.

    Channel elevations are uniform from ``upper_fov`` down to ``lower_fov`` (CARLA's layout); azimuths are uniform
    over 360° starting at the sensor's x axis and turning towards +y (clockwise seen from above, as CARLA spins).
    """
    azim = np.radians(np.arange(azimuth_steps) * (360.0 / azimuth_steps))
    return _directions(channel_elevations(spec), azim)


def cast_from(caster: RayCaster, sensor_to_world: np.ndarray, directions: np.ndarray, max_range: float) -> RayHits:
    """Cast sensor-frame unit ``directions`` from a sensor pose (4×4 sensor → world)."""
    turned = getattr(caster, "cast_turned", None)
    if turned is not None:  # the GPU caster turns the rays itself (no per-sweep copy of them on the CPU)
        return turned(sensor_to_world, directions, max_range)
    pose = np.asarray(sensor_to_world, np.float64)
    world_dirs = (directions @ pose[:3, :3].T.astype(np.float32)).astype(np.float32)
    origin = pose[:3, 3].astype(np.float32)
    return caster.cast(origin[None, :], world_dirs, max_range)


@dataclass
class LidarSweep:
    """One sweep: ego-frame points (N, 3) float32, their CARLA tags (N,) uint8 and actor ids (N,) int32."""

    points: np.ndarray
    tags: np.ndarray
    actor_ids: np.ndarray

    @classmethod
    def empty(cls) -> LidarSweep:
        """No points (a rig without the LiDAR)."""
        return cls(np.zeros((0, 3), np.float32), np.zeros(0, np.uint8), np.zeros(0, np.int32))


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
        return self.sweep_of(cast_from(caster, sensor_to_world, self._dirs, self.spec.range_m))

    @property
    def directions(self) -> np.ndarray:
        """The sweep's sensor-frame unit ray directions (one array for the sensor's life: a GPU caster keeps it)."""
        return self._dirs

    def sweep_of(self, hits: RayHits) -> LidarSweep:
        """The sweep of the hits of :attr:`directions` cast from the sensor."""
        # Rows by index (``take``): half the CPU of boolean-mask indexing for 64 k rays, the same values.
        rows = np.flatnonzero(hits.hit)
        # Sensor-frame point = direction · distance; Bench2Drive adds the mount translation (no rotation).
        pts = self._dirs.take(rows, axis=0)
        pts *= hits.t.take(rows)[:, None]
        pts += self.mount_translation
        return LidarSweep(pts, hits.tags.take(rows), hits.actor_ids.take(rows))


@dataclass(frozen=True)
class DropOff:
    """CARLA's ray-cast LiDAR losses (blueprint attributes ``dropoff_*`` and ``noise_stddev``).

    Before casting, each ray is lost with probability ``general_rate``. A hit of intensity I (the atmospheric
    attenuation ``exp(−rate · distance)``) at or below ``intensity_limit`` is kept with probability
    ``zero_intensity / intensity_limit · I + 1 − zero_intensity``; brighter hits are always kept. ``noise_stddev``
    moves each point along its ray by a Gaussian distance (metres).
    """

    general_rate: float = 0.45
    intensity_limit: float = 0.8
    zero_intensity: float = 0.4
    noise_stddev: float = 0.0

    def keep_probability(self, intensity: np.ndarray) -> np.ndarray:
        """Probability that a hit of each intensity survives the intensity drop-off."""
        beta = 1.0 - self.zero_intensity
        # A limit of 0 leaves no hit at or below it (intensities are positive), so the slope never applies.
        alpha = self.zero_intensity / self.intensity_limit if self.intensity_limit > 0.0 else 0.0
        return np.where(intensity > self.intensity_limit, 1.0, alpha * intensity + beta)


def round_half_away_from_zero(x: float) -> int:
    """Unreal's ``FMath::RoundHalfFromZero``."""
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


class SpinningLidar:
    """CARLA 0.9.15's ``sensor.lidar.ray_cast`` as a Leaderboard agent reads it, one tick at a time.

    Each tick covers ``rotation_frequency · horizontal_fov · Δt`` degrees of azimuth, continuing where the previous
    tick ended; the turn advances once per simulator tick whether or not anyone reads the sensor, so the angle is a
    function of the frame: the first tick after ``start_frame`` (the frame the sensor was attached at) starts at
    horizontal angle 0, like a freshly spawned CARLA LiDAR. A ray's azimuth is its horizontal angle mapped to
    [−fov/2, fov/2) (CARLA's ``fmod(angle, fov) − fov/2``), turning towards +y. Random draws are seeded by ``seed``,
    the frame and ``index``.
    """

    def __init__(
        self,
        spec: LidarSpec,
        dropoff: DropOff = DropOff(),
        horizontal_fov: float = 360.0,
        index: int = 0,
        seed: int = 0,
        start_frame: int = 0,
        delta_seconds: float = FIXED_DELTA_SECONDS,
    ) -> None:
        self.spec = spec
        self.dropoff = dropoff
        self.horizontal_fov = horizontal_fov
        self.index = index
        self.seed = seed
        self.start_frame = start_frame
        self.points_per_channel = round_half_away_from_zero(spec.points_per_second * delta_seconds / spec.channels)
        self.tick_angle = spec.rotation_frequency * horizontal_fov * delta_seconds
        self._elevations = channel_elevations(spec)

    def start_angle(self, frame: int) -> float:
        """Horizontal angle (degrees, in [0, fov)) at which the tick that led to ``frame`` began."""
        return ((frame - self.start_frame - 1) * self.tick_angle) % self.horizontal_fov

    def azimuths(self, frame: int) -> np.ndarray:
        """Azimuths (degrees) of one channel's rays in the tick that led to ``frame``, in casting order."""
        step = self.tick_angle / max(self.points_per_channel, 1)
        angles = self.start_angle(frame) + step * np.arange(self.points_per_channel)
        return np.fmod(angles, self.horizontal_fov) - self.horizontal_fov / 2.0

    def scan(self, caster: RayCaster, sensor_to_world: np.ndarray, frame: int) -> np.ndarray:
        """(N, 4) float32 x, y, z (sensor frame) and intensity of the tick that led to ``frame``, channel-major."""
        dirs = _directions(self._elevations, np.radians(self.azimuths(frame)))
        rng = np.random.default_rng([self.seed, frame, 4001 + self.index])
        # One draw per ray for each decision, whatever the hits: the stream does not depend on the scene.
        general, intensity_draw = rng.random(len(dirs)), rng.random(len(dirs))
        cast = general >= self.dropoff.general_rate
        dirs, intensity_draw = dirs[cast], intensity_draw[cast]
        hits = cast_from(caster, sensor_to_world, dirs, self.spec.range_m)
        distance = hits.t[hits.hit]
        intensity = np.exp(-self.spec.atmosphere_attenuation_rate * distance.astype(np.float64))
        kept = intensity_draw[hits.hit] < self.dropoff.keep_probability(intensity)
        if self.dropoff.noise_stddev > 0.0:
            distance = distance + rng.normal(0.0, self.dropoff.noise_stddev, len(distance)).astype(np.float32)
        out = np.empty((int(kept.sum()), 4), np.float32)
        out[:, :3] = dirs[hits.hit][kept] * distance[kept, None]
        out[:, 3] = intensity[kept]
        return out
