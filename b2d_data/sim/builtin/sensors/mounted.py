"""An agent's own sensors on the builtin simulator, read as CARLA 0.9.15 hands them to a Leaderboard 2.0 agent.

A Leaderboard agent lists its sensors (:class:`~b2d_data.sim.api.SensorMount`: CARLA blueprint id, pose on the ego,
blueprint attributes) and reads them every tick through the sensor interface. :class:`MountedSensors` produces
exactly those values from a :class:`Snapshot`, over the same scene as the Bench2Drive rig (``SensorScene``):

- ``sensor.camera.rgb``: uint8 (H, W, 4) BGRA, alpha 255 (CARLA's raw image);
- ``sensor.lidar.ray_cast``: float32 (N, 4) x, y, z, intensity in the sensor frame (:class:`SpinningLidar`);
- ``sensor.other.radar``: float32 (N, 4) depth, altitude, azimuth, velocity (the Leaderboard flips CARLA's
  [velocity, azimuth, altitude, depth] columns);
- ``sensor.other.gnss``: float64 (3,) latitude, longitude, altitude at the mount location;
- ``sensor.other.imu``: float64 (7,) accelerometer, gyroscope, compass at the mount pose.

Missing attributes take CARLA's blueprint defaults. All cameras of a tick render as one batch on a hardware GPU while
the LiDAR and radar rays are cast on the worker thread.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from b2d_data.codecs._rgba import rgba_parent
from b2d_data.format.rig import LidarSpec, Mount, RadarSpec
from b2d_data.format.transform import Transform
from b2d_data.sim.api import (
    CAMERA_RGB,
    GNSS,
    IMU,
    LIDAR_RAY_CAST,
    MOUNTABLE_SENSORS,
    RADAR,
    SensorMount,
    SimulatorError,
    Snapshot,
)
from b2d_data.sim.builtin.sensors.imu_gnss import GnssNoise, ImuNoise, geolocator_of, gnss_reading, imu_reading
from b2d_data.sim.builtin.sensors.lidar import DropOff, SpinningLidar
from b2d_data.sim.builtin.sensors.map_mesh import StaticScene
from b2d_data.sim.builtin.sensors.radar import Radar
from b2d_data.sim.builtin.sensors.renderer import CameraView, Renderer
from b2d_data.sim.builtin.sensors.scene_mesh import TriangleMesh
from b2d_data.sim.builtin.sensors.suite import CaptureTimings, Geolocator, SensorScene, TickScene, scene_of_map

if TYPE_CHECKING:
    from b2d_data.maps import Map

#: Random streams of the IMU and GNSS noise (the LiDAR and radar seed their own), apart from the rig's.
_IMU_STREAM = 7001
_GNSS_STREAM = 7507
#: The scene of a rig that sees no geometry (IMU and GNSS only).
_NO_SCENE = StaticScene(TriangleMesh.empty(), np.zeros((0, 3)), np.zeros(3), np.zeros(3))


def rig_mount(transform: Transform) -> Mount:
    """The rig ``Mount`` of a sensor pose relative to the ego."""
    loc, rot = transform.location, transform.rotation
    return Mount(loc.x, loc.y, loc.z, roll=rot.roll, pitch=rot.pitch, yaw=rot.yaw)


def _xyz(mount: SensorMount, pattern: str) -> tuple[float, float, float]:
    """The attributes ``pattern`` % x, y, z (CARLA's per-axis noise attributes), 0 when unset."""
    return (mount.attribute(pattern % "x", 0.0), mount.attribute(pattern % "y", 0.0), mount.attribute(pattern % "z", 0.0))


@dataclass(frozen=True)
class MountedCamera:
    """A ``sensor.camera.rgb``: its pose on the ego (4×4 sensor → ego), horizontal FOV (degrees) and image size."""

    sensor_id: str
    to_ego: np.ndarray
    fov: float
    width: int
    height: int

    @classmethod
    def of(cls, mount: SensorMount) -> MountedCamera:
        """The camera of a mount (CARLA's defaults: 800×600, 90°)."""
        width, height = int(mount.attribute("image_size_x", 800)), int(mount.attribute("image_size_y", 600))
        fov = mount.attribute("fov", 90.0)
        if width <= 0 or height <= 0 or not 0.0 < fov < 180.0:
            raise SimulatorError(f"sensor {mount.sensor_id!r}: camera needs a positive size and 0 < fov < 180, "
                                 f"got {width}×{height}, fov {fov}")  # fmt: skip
        return cls(mount.sensor_id, mount.transform.matrix(), fov, width, height)


def spinning_lidar_of(mount: SensorMount, index: int, seed: int, start_frame: int) -> SpinningLidar:
    """The ``sensor.lidar.ray_cast`` of a mount (CARLA's blueprint defaults for unset attributes)."""
    spec = LidarSpec(
        sensor_id=mount.sensor_id,
        mount=rig_mount(mount.transform),
        range_m=mount.attribute("range", 10.0),
        channels=int(mount.attribute("channels", 32)),
        rotation_frequency=mount.attribute("rotation_frequency", 10.0),
        points_per_second=int(mount.attribute("points_per_second", 56000)),
        upper_fov=mount.attribute("upper_fov", 10.0),
        lower_fov=mount.attribute("lower_fov", -30.0),
        atmosphere_attenuation_rate=mount.attribute("atmosphere_attenuation_rate", 0.004),
    )
    fov = mount.attribute("horizontal_fov", 360.0)
    if spec.channels < 1 or spec.points_per_second < 0 or spec.range_m <= 0.0 or fov <= 0.0:
        raise SimulatorError(f"sensor {mount.sensor_id!r}: LiDAR needs channels ≥ 1, points_per_second ≥ 0, a "
                             f"positive range and a positive horizontal_fov")  # fmt: skip
    dropoff = DropOff(
        general_rate=mount.attribute("dropoff_general_rate", 0.45),
        intensity_limit=mount.attribute("dropoff_intensity_limit", 0.8),
        zero_intensity=mount.attribute("dropoff_zero_intensity", 0.4),
        noise_stddev=mount.attribute("noise_stddev", 0.0),
    )
    return SpinningLidar(spec, dropoff, fov, index=index, seed=seed, start_frame=start_frame)


def radar_of(mount: SensorMount, index: int, seed: int) -> Radar:
    """The ``sensor.other.radar`` of a mount (CARLA's defaults: 30°×30°, 1500 points/s, 100 m)."""
    spec = RadarSpec(
        sensor_id=mount.sensor_id,
        dataset=mount.sensor_id,
        mount=rig_mount(mount.transform),
        range_m=mount.attribute("range", 100.0),
        horizontal_fov=mount.attribute("horizontal_fov", 30.0),
        vertical_fov=mount.attribute("vertical_fov", 30.0),
        points_per_second=int(mount.attribute("points_per_second", 1500)),
    )
    return Radar(spec, index, seed)


def imu_noise_of(mount: SensorMount) -> ImuNoise:
    """CARLA's IMU noise attributes of a mount (0 when unset)."""
    return ImuNoise(_xyz(mount, "noise_accel_stddev_%s"), _xyz(mount, "noise_gyro_stddev_%s"),
                    _xyz(mount, "noise_gyro_bias_%s"))  # fmt: skip


def gnss_noise_of(mount: SensorMount) -> GnssNoise:
    """CARLA's GNSS noise attributes of a mount (0 when unset)."""
    keys = ("lat", "lon", "alt")
    return GnssNoise(
        tuple(mount.attribute(f"noise_{k}_stddev", 0.0) for k in keys),  # type: ignore[arg-type]
        tuple(mount.attribute(f"noise_{k}_bias", 0.0) for k in keys),  # type: ignore[arg-type]
    )


def bgra_in_place(rgb: np.ndarray) -> np.ndarray:
    """The renderer's RGB image as CARLA's BGRA, swapped in one pass in the RGBA read-back it is a view of.

    The renderer hands RGB over as the first three channels of the RGBA pixels it read back (alpha 255).
    """
    rgba = rgba_parent(rgb)
    if rgba is not None:
        return cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA, dst=rgba)
    # Not a view of RGBA pixels (never from the renderer): convert into a new image.
    return cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGRA)


@dataclass(frozen=True)
class _Placed:
    """A ray-casting or inertial sensor with its key, index in the rig and pose on the ego (4×4 sensor → ego)."""

    sensor_id: str
    index: int
    to_ego: np.ndarray


class MountedSensors(SensorScene):
    """Every sensor of an agent's rig (:class:`SensorMount` list) at a :class:`Snapshot`, keyed by sensor id.

    ``start_frame`` is the frame the rig was attached at: the LiDARs' turn counts ticks from it. Noise and drop-off
    are seeded by ``seed``, the frame and each sensor's index in ``mounts``.
    """

    def __init__(self, map: Map | None, mounts: Sequence[SensorMount], seed: int = 0,
                 start_frame: int = 0) -> None:  # fmt: skip
        self._setup(lambda: scene_of_map(map), geolocator_of(map), mounts, seed, start_frame)
        self.map = map

    @classmethod
    def from_scene(
        cls,
        scene: StaticScene,
        mounts: Sequence[SensorMount],
        seed: int = 0,
        geolocate: Geolocator | None = None,
        start_frame: int = 0,
    ) -> MountedSensors:
        """A rig over an already built static scene (tests, benchmarks, layouts without a map)."""
        rig = cls.__new__(cls)
        rig._setup(lambda: scene, geolocate or geolocator_of(None), mounts, seed, start_frame)
        rig.map = None
        return rig

    def _setup(self, scene: Callable[[], StaticScene], geolocate: Geolocator, mounts: Sequence[SensorMount],
               seed: int, start_frame: int) -> None:  # fmt: skip
        self.mounts = tuple(mounts)
        self.seed = seed
        self.start_frame = start_frame
        self._geolocate = geolocate
        seen: set[str] = set()
        for m in self.mounts:
            if m.type_id not in MOUNTABLE_SENSORS:
                raise SimulatorError(f"sensor {m.sensor_id!r}: type {m.type_id!r} is not supported; the builtin "
                                     f"simulator mounts {', '.join(MOUNTABLE_SENSORS)}")  # fmt: skip
            if m.sensor_id in seen:
                raise SimulatorError(f"sensor id {m.sensor_id!r} is used twice")
            seen.add(m.sensor_id)
        placed = [(m, _Placed(m.sensor_id, i, m.transform.matrix())) for i, m in enumerate(self.mounts)]
        self.cameras = [MountedCamera.of(m) for m in self.mounts if m.type_id == CAMERA_RGB]
        self.lidars = [(p, spinning_lidar_of(m, p.index, seed, start_frame)) for m, p in placed
                       if m.type_id == LIDAR_RAY_CAST]  # fmt: skip
        self.radars = [(p, radar_of(m, p.index, seed)) for m, p in placed if m.type_id == RADAR]
        self.imus = [(p, imu_noise_of(m)) for m, p in placed if m.type_id == IMU]
        # GNSS: the wrapper drops the mount's rotation; only its location matters.
        self.gnss = [(p, gnss_noise_of(m)) for m, p in placed if m.type_id == GNSS]
        renderer = Renderer() if self.cameras else None
        rays = bool(self.lidars or self.radars)
        # IMU and GNSS alone see no geometry: the town is not meshed for them.
        self._setup_scene(scene() if renderer is not None or rays else _NO_SCENE, renderer, rays)
        self.timings = CaptureTimings()

    def capture(self, snapshot: Snapshot, ego_id: int) -> dict[str, np.ndarray]:
        """Every mounted sensor at this snapshot, keyed by sensor id in mount order."""
        t0 = time.perf_counter()
        tick = self._prepare(snapshot, ego_id)
        ego_m = tick.ego.transform.matrix()
        # Embree releases the GIL: the rays are cast on the worker thread while the cameras render here.
        rays = self._pool.submit(self._cast_rays, tick, ego_m) if self.caster is not None else None
        t1 = time.perf_counter()
        timings = CaptureTimings(actors=t1 - t0)
        data: dict[str, np.ndarray] = {}
        try:
            if self.renderer is not None:
                data.update(self._render(tick, ego_m))
                timings.cameras = time.perf_counter() - t1
        finally:
            # Never leave the worker running into the next capture, even when rendering failed.
            if rays is not None:
                cast, timings.lidar, timings.radar = rays.result()
                data.update(cast)
        t3 = time.perf_counter()
        data.update(self._inertial(tick, ego_m))
        timings.imu_gnss = time.perf_counter() - t3
        timings.wall = time.perf_counter() - t0
        self.timings = timings
        return {m.sensor_id: data[m.sensor_id] for m in self.mounts}

    def _render(self, tick: TickScene, ego_m: np.ndarray) -> dict[str, np.ndarray]:
        """Every camera as BGRA; one batch per image size on llvmpipe, all in one on a hardware GPU."""
        by_size: dict[tuple[int, int], list[MountedCamera]] = {}
        for cam in self.cameras:
            by_size.setdefault((cam.width, cam.height), []).append(cam)
        ordered = [cam for group in by_size.values() for cam in group]
        batches = [[CameraView(ego_m @ c.to_ego, c.fov, c.width, c.height, False) for c in group]
                   for group in by_size.values()]  # fmt: skip
        frames = self._render_views(tick, batches)
        return {cam.sensor_id: bgra_in_place(frame.rgb) for cam, frame in zip(ordered, frames)}

    def _cast_rays(self, tick: TickScene, ego_m: np.ndarray) -> tuple[dict[str, np.ndarray], float, float]:
        """LiDAR and radar data with the seconds each took (run on the worker thread)."""
        assert self.caster is not None
        t0 = time.perf_counter()
        out = {p.sensor_id: lidar.scan(self.caster, ego_m @ p.to_ego, tick.snapshot.frame) for p, lidar in self.lidars}
        t1 = time.perf_counter()
        if self.radars:
            out.update(self._scan_radars(tick, [(p.sensor_id, ego_m @ p.to_ego, r) for p, r in self.radars]))
        return out, t1 - t0, time.perf_counter() - t1

    def _inertial(self, tick: TickScene, ego_m: np.ndarray) -> dict[str, np.ndarray]:
        """IMU and GNSS readings as the Leaderboard's float64 arrays."""
        frame = tick.snapshot.frame
        out: dict[str, np.ndarray] = {}
        for p, imu_noise in self.imus:
            rng = np.random.default_rng([self.seed, frame, _IMU_STREAM + p.index])
            imu = imu_reading(tick.ego, ego_m @ p.to_ego, rng, imu_noise)
            out[p.sensor_id] = np.array([*imu.accelerometer, *imu.gyroscope, imu.compass], np.float64)
        for p, gnss_noise in self.gnss:
            rng = np.random.default_rng([self.seed, frame, _GNSS_STREAM + p.index])
            fix = gnss_reading(ego_m[:3, :3] @ p.to_ego[:3, 3] + ego_m[:3, 3], self._geolocate, rng, gnss_noise)
            out[p.sensor_id] = np.array([fix.latitude, fix.longitude, fix.altitude], np.float64)
        return out
