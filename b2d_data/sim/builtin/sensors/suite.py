"""The Bench2Drive sensor rig of the builtin simulator: one capture per tick from a :class:`Snapshot`.

The static scene (map mesh, then traffic-light and sign fixtures once the snapshot shows them) is uploaded to the
renderer and to the ray caster (Embree, or on a hardware GPU the compute shader of ``gpu_raycast.py``) once; each
capture meshes the actors, renders the cameras, casts the LiDAR and radar rays into the same triangles, and reads
IMU, GNSS and speedometer from the ego state. :class:`SensorScene` is that scene
machinery, shared with the agent rigs of ``mounted.py``.
"""

from __future__ import annotations

import hashlib
import math
import os
import pickle
import time
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.format.record import CameraFrame
from b2d_data.format.rig import CAMERA_BY_FOLDER, CAMERAS, LIDAR, NOISE, RADARS_V0, RADARS_V004, TOP_DOWN
from b2d_data.format.transform import Location, Transform
from b2d_data.sim.api import ActorState, RigConfig, SensorData, Snapshot, TrafficLightState
from b2d_data.sim.builtin.sensors.actor_mesh import ActorMeshBuilder
from b2d_data.sim.builtin.sensors.fixture_mesh import (
    Fixture,
    fixture_key,
    fixture_static_mesh,
    fixtures_of_snapshot,
    lamp_mesh,
)
from b2d_data.sim.builtin.sensors import kept_rig
from b2d_data.sim.builtin.sensors.imu_gnss import ImuGnss, geolocator_of
from b2d_data.sim.builtin.sensors.lidar import Lidar, LidarSweep
from b2d_data.sim.builtin.sensors.lighting import Lighting
from b2d_data.sim.builtin.sensors.map_mesh import RoadLayout, StaticScene, build_static_scene, layout_from_map
from b2d_data.sim.builtin.sensors.radar import Radar, RadarPose
from b2d_data.sim.builtin.sensors.gpu_raycast import GpuRayCaster, PendingCast, make_ray_caster
from b2d_data.sim.builtin.sensors.raycast import RayCaster, RayHits
from b2d_data.sim.builtin.sensors.renderer import CameraView, Renderer
from b2d_data.sim.builtin.sensors.scene_mesh import TriangleMesh, merge
from b2d_data.sim.builtin.sensors.vehicle_lights import SpotLights, vehicle_lights

if TYPE_CHECKING:
    from b2d_data.maps import Map

Geolocator = Callable[[Location], tuple[float, float, float]]

#: Static scenes this process has built, by road layout (least recently used first). A route process runs route
#: after route on the same few towns, and a town's scenery stays where it is from route to route, as a CARLA town's
#: does: meshing it took half of a route's set-up.
_SCENES: OrderedDict[bytes, StaticScene] = OrderedDict()
_SCENES_KEPT = 2


def town_scene(layout: RoadLayout) -> StaticScene:
    """The static scene of a road layout, built once per process (the scenery is the town's, not the route's)."""
    key = hashlib.blake2b(pickle.dumps(layout, protocol=5), digest_size=16).digest()
    scene = _SCENES.get(key)
    if scene is None:
        scene = build_static_scene(layout, seed=0)
        _SCENES[key] = scene
        while len(_SCENES) > _SCENES_KEPT:
            _SCENES.popitem(last=False)
    _SCENES.move_to_end(key)
    return scene


@dataclass
class CaptureTimings:
    """Seconds spent in each part of the last capture.

    With Embree, LiDAR and radar run on a worker thread while the cameras render, so ``wall`` (the whole capture) is
    less than the sum of the parts when both overlap. With the GPU caster they are the host's part only: starting
    the casts and turning their hits into points and detections.
    """

    actors: float = 0.0
    cameras: float = 0.0  # every camera of the rig (six and the top-down camera for Bench2Drive's)
    lidar: float = 0.0
    radar: float = 0.0
    imu_gnss: float = 0.0
    wall: float = 0.0


def scene_of_map(map: Map | None) -> StaticScene:
    """The town's static scene of a map (``town_scene``; an empty layout without a map)."""
    return town_scene(layout_from_map(map) if map is not None else RoadLayout([]))


@dataclass
class TickScene:
    """What every sensor of a rig sees at one tick: the ego, the actors' meshes, the lamps and the lighting (the
    weather's and the vehicles' lit lamps)."""

    snapshot: Snapshot
    ego: ActorState
    actor_parts: list[tuple[int, TriangleMesh]]
    lamps: TriangleMesh
    light: Lighting
    vehicle_lights: SpotLights = SpotLights.empty()
    #: The renderer's dynamic mesh (every actor part, then the lamps) when ``_prepare`` merged it already.
    dynamic: TriangleMesh | None = None


def _rows_of(parts: list[tuple[int, TriangleMesh]], actor_id: int) -> slice:
    """The triangle rows of ``actor_id``'s part in the merge of ``parts`` (empty when it has none)."""
    start = 0
    for i, mesh in parts:
        if i == actor_id:
            return slice(start, start + len(mesh))
        start += len(mesh)
    return slice(start, start)


def _without_rows(mesh: TriangleMesh, rows: slice) -> TriangleMesh:
    """``mesh`` less a run of triangle rows: the merge of the parts around them, without merging them again."""
    if rows.start == rows.stop:
        return mesh
    cut = [
        np.concatenate([a[: rows.start], a[rows.stop :]])
        for a in (mesh.vertices, mesh.normals, mesh.colors, mesh.tags, mesh.instance_ids, mesh.materials)
    ]
    return TriangleMesh(*cut)


@dataclass
class _RadarRays:
    """One radar's rays of a tick: its key, the radar, its pose and the directions (radar frame and world)."""

    key: str
    radar: Radar
    pose: RadarPose
    local: np.ndarray
    world: np.ndarray


@dataclass
class _RadarsInFlight:
    """The radar casts of a tick submitted to the GPU caster (keys in the rig's order)."""

    keys: list[str]
    casts: list[tuple[PendingCast, list[_RadarRays]]]


@dataclass
class _RaysInFlight:
    """A capture's LiDAR and radar casts on the GPU, and the host seconds spent starting each."""

    lidar: PendingCast | None
    radars: _RadarsInFlight | None
    lidar_s: float
    radar_s: float


class SensorScene:
    """The town as a rig's sensors see it: the static scene in the renderer and the ray caster (either optional),
    traffic-light and sign fixtures, lamps, actor meshes, lighting and the vehicles' lamps.

    Subclasses call :meth:`_setup_scene`, then per capture :meth:`_prepare` (which also hands the tick's actors to the
    ray caster, so rays may be cast on ``_pool`` from then on) and :meth:`_render_views`.
    """

    scene: StaticScene
    renderer: Renderer | None
    caster: RayCaster | GpuRayCaster | None

    def _setup_scene(self, scene: StaticScene, renderer: Renderer | None, rays: bool, gpu_rays: str = "off",
                     caster: RayCaster | GpuRayCaster | None = None) -> None:  # fmt: skip
        """Take ``renderer`` (and ``caster``: an earlier suite's, see kept_rig.py) for ``scene``."""
        self.scene = scene
        self.renderer = renderer
        if self.renderer is not None:
            # Without lamps, the blank light-map a new renderer starts with (a kept one may hold another town's).
            lightmap = scene.lightmap() if len(scene.lamps) else (np.zeros((1, 1), np.float32), (0.0, 0.0), (1.0, 1.0))
            self.renderer.set_lightmap(*lightmap)
        # Building Embree's scenes costs time per tick: a rig without LiDAR or radar has no caster. With ``gpu_rays``
        # the rays are cast by a compute shader in the renderer's context: the same hits for a fraction of the CPU.
        if caster is None and rays:
            caster = make_ray_caster(gpu_rays, renderer.ctx if renderer is not None else None)
        self.caster = caster
        self.actor_meshes = ActorMeshBuilder()
        self.fixtures: list[Fixture] = []
        self._fixture_key: tuple | None = None
        self._lamp_cache: dict[tuple[int, TrafficLightState], TriangleMesh] = {}
        self._lamps_merged: tuple[tuple, TriangleMesh] | None = None  # the last states' key and merged lamps
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="b2d-rays")
        self._set_static(scene.mesh)

    def _set_static(self, mesh: TriangleMesh) -> None:
        if self.renderer is not None:
            self.renderer.set_static(mesh)
        if self.caster is not None:
            self.caster.set_static(mesh)

    def _update_fixtures(self, snapshot: Snapshot) -> None:
        key = fixture_key(snapshot)
        if key == self._fixture_key:
            return
        self._fixture_key = key
        self.fixtures = fixtures_of_snapshot(snapshot)
        self._lamp_cache.clear()
        self._lamps_merged = None
        self._set_static(merge([self.scene.mesh, fixture_static_mesh(self.fixtures)]))

    def _lamps(self, states: dict[int, TrafficLightState]) -> TriangleMesh:
        """Lamp meshes of every light in its current state (each (light, state) meshed once)."""
        keys = tuple(
            (f.instance_id, states.get(f.instance_id, TrafficLightState.OFF))
            for f in self.fixtures
            if f.kind == "traffic_light"
        )
        # The lights change state every few seconds: most ticks merge the same lamps as the last one.
        if self._lamps_merged is not None and self._lamps_merged[0] == keys:
            return self._lamps_merged[1]
        parts = []
        for f, key in zip((f for f in self.fixtures if f.kind == "traffic_light"), keys):
            mesh = self._lamp_cache.get(key)
            if mesh is None:
                mesh = self._lamp_cache[key] = lamp_mesh([f], {f.instance_id: key[1]})
            parts.append(mesh)
        merged = merge(parts)
        self._lamps_merged = (keys, merged)
        return merged

    def _prepare(self, snapshot: Snapshot, ego_id: int) -> TickScene:
        """Mesh the tick's actors and lamps and hand them to the ray caster; the renderer gets them in
        :meth:`_render_views`."""
        ego = snapshot.actors.get(ego_id)
        if ego is None:
            raise KeyError(f"ego actor {ego_id} is not in snapshot frame {snapshot.frame}")
        light = Lighting.from_weather(snapshot.weather)
        if self.renderer is None and self.caster is None:
            return TickScene(snapshot, ego, [], TriangleMesh.empty(), light)  # IMU and GNSS need no geometry
        self._update_fixtures(snapshot)
        lit = light.vehicle_lights_on
        actor_parts = self.actor_meshes.build_parts(snapshot.actors, lit, snapshot.timestamp)
        lamps = self._lamps({i: t.state for i, t in snapshot.traffic_lights.items()})
        dynamic = merge([m for _, m in actor_parts] + [lamps]) if self.renderer is not None else None
        if self.caster is not None:
            # The LiDAR and radars see everything but the ego (their rays start inside or next to its body).
            if dynamic is None:
                self.caster.set_dynamic(merge([m for i, m in actor_parts if i != ego_id] + [lamps]))
            else:
                self.caster.set_dynamic(_without_rows(dynamic, _rows_of(actor_parts, ego_id)))
        spots = SpotLights.empty()
        if self.renderer is not None and light.beams > 0.0:
            # The lamps the actor meshes show lit light the scene (the same rule: light_flags).
            spots = vehicle_lights(snapshot.actors.values(), ego, lit, snapshot.timestamp)
        return TickScene(snapshot, ego, actor_parts, lamps, light, spots, dynamic)

    def _render_views(self, tick: TickScene, batches: list[list[CameraView]]) -> list[CameraFrame]:
        """Render every view of ``batches``, in order.

        On a hardware GPU all views are one batch, so a frame waits for the GPU once: with many route processes
        sharing a GPU, each wait lasts until the processes ahead had their turn. On llvmpipe each batch is rendered on
        its own (the surround and top-down cameras in one batch measured 3–8 % fewer frames/s on the 2-core
        machine).
        """
        assert self.renderer is not None and tick.dynamic is not None  # _prepare merges it wherever there is a renderer
        self.renderer.set_dynamic(tick.dynamic)
        # The sun's shadows are drawn around the ego, once per tick whichever batch comes first.
        lights, centre = tick.vehicle_lights, tick.ego.transform.location.to_array()
        if self.renderer.hardware:
            return self.renderer.render([v for batch in batches for v in batch], tick.light, lights, centre)
        return [frame for batch in batches if batch for frame in self.renderer.render(batch, tick.light, lights, centre)]

    @staticmethod
    def _point_velocity(ego: ActorState, point: np.ndarray) -> np.ndarray:
        """World velocity of a point rigidly attached to the ego (yaw rate only)."""
        v = ego.velocity.to_array()
        yaw_rate = math.radians(ego.angular_velocity.z)
        r = point - ego.transform.location.to_array()
        return v + yaw_rate * np.array([-r[1], r[0], 0.0])

    def _scan_radars(self, tick: TickScene, radars: list[tuple[str, np.ndarray, Radar]]) -> dict[str, np.ndarray]:
        """Detections of each (key, sensor → world, radar), relative to the radar's own motion with the ego."""
        assert self.caster is not None
        velocities = {a.id: a.velocity.to_array() for a in tick.snapshot.actors.values()}
        out = {}
        for key, pose, radar in radars:
            own = RadarPose(pose, self._point_velocity(tick.ego, pose[:3, 3]))
            out[key] = radar.scan(self.caster, own, tick.snapshot.frame, velocities)
        return out

    def _submit_radars(self, tick: TickScene, radars: list[tuple[str, np.ndarray, Radar]]) -> _RadarsInFlight:
        """Start the rays of every (key, sensor → world, radar) on the GPU caster: one cast per range, the radars'
        rays one after the other, each from its radar (the rays of :meth:`_scan_radars`)."""
        assert isinstance(self.caster, GpuRayCaster)
        flight = _RadarsInFlight([key for key, _, _ in radars], [])
        groups: dict[float, list[_RadarRays]] = {}
        for key, pose, radar in radars:
            own = RadarPose(pose, self._point_velocity(tick.ego, pose[:3, 3]))
            local, world = radar.rays(own, tick.snapshot.frame)
            groups.setdefault(radar.spec.range_m, []).append(_RadarRays(key, radar, own, local, world))
        for range_m, group in groups.items():
            origins = np.concatenate([np.broadcast_to(r.pose.sensor_to_world[:3, 3], r.world.shape) for r in group])
            directions = np.concatenate([r.world for r in group])
            flight.casts.append((self.caster.submit(origins, directions, range_m), group))
        return flight

    def _collect_radars(self, tick: TickScene, flight: _RadarsInFlight) -> dict[str, np.ndarray]:
        """The detections of :meth:`_submit_radars`' casts, by key in the order they were given."""
        assert isinstance(self.caster, GpuRayCaster)
        velocities = {a.id: a.velocity.to_array() for a in tick.snapshot.actors.values()}
        out: dict[str, np.ndarray] = {}
        for pending, group in flight.casts:
            hits = self.caster.collect(pending)
            start = 0
            for r in group:
                rows = slice(start, start + len(r.world))
                start = rows.stop
                part = RayHits(hits.hit[rows], hits.t[rows], hits.tags[rows], hits.actor_ids[rows])
                out[r.key] = r.radar.detections(r.local, r.world, part, r.pose, velocities)
        return {key: out[key] for key in flight.keys}

    def close(self) -> None:
        """Release the GL contexts and the ray-casting thread."""
        self._pool.shutdown(wait=True)
        if self.caster is not None:
            self.caster.close()
            self.caster = None
        if self.renderer is not None:
            self.renderer.close()
            self.renderer = None


class SensorSuite(SensorScene):
    """Renders and ray-casts the whole rig for an ego in a :class:`Snapshot` of a town."""

    def __init__(self, map: Map | None, config: RigConfig = RigConfig(), seed: int = 0) -> None:  # noqa: A002
        # ``seed`` drives the sensor noise; the scenery is the town's (``town_scene``).
        self._setup(scene_of_map(map), geolocator_of(map), config, seed)
        self.map = map

    @classmethod
    def from_scene(
        cls,
        scene: StaticScene,
        config: RigConfig = RigConfig(),
        seed: int = 0,
        geolocate: Geolocator | None = None,
    ) -> SensorSuite:
        """A suite over an already built static scene (tests, benchmarks, layouts without a map)."""
        suite = cls.__new__(cls)
        suite._setup(scene, geolocate or geolocator_of(None), config, seed)
        suite.map = None
        return suite

    def _setup(self, scene: StaticScene, geolocate: Geolocator, config: RigConfig, seed: int) -> None:
        self.config = config
        self.seed = seed
        self._geolocate = geolocate
        cams = [c for c in config.cameras if c in CAMERA_BY_FOLDER]
        self._camera_specs = [CAMERA_BY_FOLDER[c] for c in cams]
        # B2D_GPU_RAYS=off|on|gpu overrides the config (A/B measurements of a collection without code changes).
        gpu_rays = os.environ.get("B2D_GPU_RAYS", config.gpu_rays)
        rays = config.lidar or config.radar
        # The last closed suite's renderer and caster, where they were made the same way (kept_rig.py). The factory
        # is part of the key: tests and benchmarks swap it for one with other arguments.
        self._kept_key = (Renderer, not config.float_depth, config.jpeg_planes, config.png_rows,
                          bool(self._camera_specs), rays, gpu_rays)  # fmt: skip
        kept = kept_rig.take(self._kept_key)
        if kept is not None:
            renderer, caster = kept
        else:
            renderer = (Renderer(depth8=not config.float_depth, jpeg_planes=config.jpeg_planes,  # type: ignore[arg-type]
                                 png_rows=config.png_rows) if self._camera_specs else None)  # fmt: skip
            caster = None
        self._setup_scene(scene, renderer, rays=rays, gpu_rays=gpu_rays, caster=caster)
        self.lidar = Lidar(LIDAR, config.lidar_azimuth_steps)
        specs = RADARS_V004 if config.radar_v004_mounts else RADARS_V0
        self.radars = [Radar(spec, i, seed) for i, spec in enumerate(specs)]
        self.imu = ImuGnss(NOISE, seed)
        self.timings = CaptureTimings()
        # Sensor → ego 4×4 of every rig sensor, in sensor_poses' order: fixed, so worked out once.
        radar_specs = RADARS_V004 if config.radar_v004_mounts else RADARS_V0
        self._mounts = {c.sensor_id: c.mount.matrix() for c in (*CAMERAS, TOP_DOWN)}
        self._mounts.update({r.sensor_id: r.mount.matrix() for r in radar_specs})
        self._mounts[LIDAR.sensor_id] = LIDAR.mount.matrix()

    def close(self) -> None:
        """Stop the ray-casting thread and keep the renderer and caster for the process's next suite (kept_rig.py;
        ``kept_rig.release()`` closes them)."""
        self._pool.shutdown(wait=True)
        if self.renderer is not None or self.caster is not None:
            kept_rig.keep(self._kept_key, self.renderer, self.caster)
        self.renderer = self.caster = None

    # ------------------------------------------------------------------------------------------ poses
    def sensor_poses(self, ego: ActorState) -> dict[str, np.ndarray]:
        """Sensor → world 4×4 of every rig sensor, keyed by sensor id (CAM_*, TOP_DOWN, RADAR_*, LIDAR_TOP)."""
        ego_m = ego.transform.matrix()
        return {sensor_id: ego_m @ mount for sensor_id, mount in self._mounts.items()}

    # ------------------------------------------------------------------------------------------ capture
    def _cast_rays(self, tick: TickScene, poses: dict[str, np.ndarray]):
        """LiDAR sweep and radar detections (run on the worker thread while the cameras render)."""
        t0 = time.perf_counter()
        if self.config.lidar:
            sweep = self.lidar.scan(self.caster, poses[LIDAR.sensor_id])
        else:
            sweep = LidarSweep.empty()
        t1 = time.perf_counter()
        radar: dict[str, np.ndarray] = {}
        if self.config.radar:
            radar = self._scan_radars(tick, [(r.spec.dataset, poses[r.spec.sensor_id], r) for r in self.radars])
        return sweep, radar, t1 - t0, time.perf_counter() - t1

    def _submit_rays(self, tick: TickScene, poses: dict[str, np.ndarray]) -> _RaysInFlight:
        """Start the LiDAR sweep and the radar rays on the GPU caster (before the cameras are drawn)."""
        assert isinstance(self.caster, GpuRayCaster)
        t0 = time.perf_counter()
        lidar = (self.caster.submit_turned(poses[LIDAR.sensor_id], self.lidar.directions, self.lidar.spec.range_m)
                 if self.config.lidar else None)  # fmt: skip
        t1 = time.perf_counter()
        radars = None
        if self.config.radar:
            radars = self._submit_radars(tick, [(r.spec.dataset, poses[r.spec.sensor_id], r) for r in self.radars])
        return _RaysInFlight(lidar, radars, t1 - t0, time.perf_counter() - t1)

    def _collect_rays(self, tick: TickScene, flight: _RaysInFlight):
        """The LiDAR sweep and radar detections of :meth:`_submit_rays` (what :meth:`_cast_rays` returns)."""
        assert isinstance(self.caster, GpuRayCaster)
        t0 = time.perf_counter()
        if flight.lidar is not None:
            sweep = self.lidar.sweep_of(self.caster.collect(flight.lidar))
        else:
            sweep = LidarSweep.empty()
        t1 = time.perf_counter()
        radar = self._collect_radars(tick, flight.radars) if flight.radars is not None else {}
        return sweep, radar, flight.lidar_s + t1 - t0, flight.radar_s + time.perf_counter() - t1

    def capture(self, snapshot: Snapshot, ego_id: int) -> SensorData:
        """Every sensor of the rig at this snapshot."""
        t0 = time.perf_counter()
        tick = self._prepare(snapshot, ego_id)
        poses = self.sensor_poses(tick.ego)
        timings = CaptureTimings(actors=time.perf_counter() - t0)
        flight, rays = None, None
        if isinstance(self.caster, GpuRayCaster):
            # Queued ahead of the cameras in the renderer's context: done by the time their read-back returns.
            flight = self._submit_rays(tick, poses)
        else:
            # Embree releases the GIL: the rays are cast on a worker thread while the cameras render here.
            rays = self._pool.submit(self._cast_rays, tick, poses)
        t1 = time.perf_counter()

        cameras: dict[str, CameraFrame] = {}
        try:
            if self.renderer is not None:
                cameras = self._render(tick, poses)
                timings.cameras = time.perf_counter() - t1
        finally:
            # Never leave the worker running into the next capture, even when rendering failed.
            if flight is not None:
                sweep, radar, timings.lidar, timings.radar = self._collect_rays(tick, flight)
            else:
                assert rays is not None
                sweep, radar, timings.lidar, timings.radar = rays.result()
        t3 = time.perf_counter()
        imu, gnss, speed = self.imu.read(tick.ego, snapshot.frame, self._geolocate)
        timings.imu_gnss = time.perf_counter() - t3
        timings.wall = time.perf_counter() - t0
        self.timings = timings
        return SensorData(
            frame=snapshot.frame,
            cameras=cameras,
            lidar=sweep.points,
            lidar_tags=sweep.tags,
            lidar_actor_ids=sweep.actor_ids,
            radar=radar,
            imu=imu,
            gnss=gnss,
            speed=speed,
            sensor_transforms={k: Transform.from_matrix(m) for k, m in poses.items()},
        )

    def _render(self, tick: TickScene, poses: dict[str, np.ndarray]) -> dict[str, CameraFrame]:
        """The six cameras (with dense labels when configured) and the top-down camera (a batch of its own on llvmpipe)."""
        cfg = self.config
        surround = [c for c in self._camera_specs if c.folder != TOP_DOWN.folder]
        top = [c for c in self._camera_specs if c.folder == TOP_DOWN.folder]
        views = [CameraView(poses[c.sensor_id], c.fov, cfg.width, cfg.height, cfg.dense_labels) for c in surround]
        top_views = [CameraView(poses[c.sensor_id], c.fov, cfg.top_down_width, cfg.top_down_height, False) for c in top]
        frames = self._render_views(tick, [views, top_views])
        return dict(zip((c.folder for c in surround + top), frames))
