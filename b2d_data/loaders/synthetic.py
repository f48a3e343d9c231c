"""Synthetic Bench2Drive clips and indexes with known ground truth, for tests and loader benchmarks.

A synthetic clip has an ego driving straight at constant speed and heading, and one object of every kind whose
annotation carries a released-data quirk: a lead vehicle, a walker with stored speed 0, a static vehicle whose
prop rotation is wrong (its ``world2vehicle`` is right), a traffic light and a stop sign with trigger volumes,
and a dirt-debris prop with swapped extents. Images are smooth gradients with a bright marker drawn where each
box centre projects (through ``world2cam`` and K, as Bench2Drive's tools/utils.py projects), so a loader's
intrinsics/extrinsics can be checked against pixels.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa

from b2d_data.format.names import ClipName
from b2d_data.format.record import CameraFrame, FrameRecord
from b2d_data.format.rig import (
    ALL_CAMERAS,
    CAMERAS,
    EGO_HALF_EXTENT,
    EGO_TYPE_ID,
    LIDAR,
    RADARS_V0,
    RADARS_V004,
    camera,
)
from b2d_data.format.scenario_types import SCENARIO_TYPES
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform
from b2d_data.format.version import DEFAULT_FORMAT, FormatVersion
from b2d_data.format.weather import PRESETS, WEATHER_IDS

SURROUND = tuple(c.folder for c in CAMERAS)
#: A released static-vehicle ``type_id``: the prop's mesh path.
PARKED_MESH = "/Game/Carla/Static/Car/4Wheeled/ParkedVehicles/Lincoln/SM_LincolnParked.SM_LincolnParked"
#: GNSS mount behind the ego origin (format.md §2.6): anno x, y are taken there.
GNSS_OFFSET = -1.4


@dataclass(frozen=True)
class SyntheticObject:
    """One annotated object: pose relative to the ego's start pose (CARLA ego axes) and its motion."""

    kind: str  # lead | walker | static | light | stop | debris
    actor_id: str
    rel_xy: tuple[float, float]
    rel_yaw_deg: float
    half_extent: tuple[float, float, float]
    z_centre: float
    velocity_ego: tuple[float, float] = (0.0, 0.0)  # world velocity in the start-ego axes (m/s)


DEFAULT_OBJECTS: tuple[SyntheticObject, ...] = (
    SyntheticObject("lead", "1001", (12.0, 0.0), 0.0, (2.4, 1.0, 0.75), 0.75),
    SyntheticObject("walker", "2001", (8.0, -4.0), 90.0, (0.3, 0.3, 0.9), 0.9, (0.0, 1.5)),
    SyntheticObject("static", "3001", (20.0, 3.5), 90.0, (2.2, 0.95, 0.8), 0.8),
    SyntheticObject("light", "4001", (40.0, 5.0), 180.0, (0.5, 0.5, 3.0), 3.0),
    SyntheticObject("stop", "5001", (30.0, -6.0), 180.0, (0.4, 0.05, 1.2), 1.2),
    SyntheticObject("debris", "6001", (15.0, -1.5), 0.0, (0.5, 2.0, 0.05), 0.05),
)


@dataclass(frozen=True)
class SyntheticClipSpec:
    """What to fabricate: clip name, frame count, image size, modalities and the ego motion."""

    name: ClipName
    frames: int = 5
    width: int = 64
    height: int = 36
    cameras: tuple[str, ...] = SURROUND
    dense: bool = True
    lidar_points: int = 256
    radar: bool = True
    expert: bool = True
    ego_start: tuple[float, float] = (100.0, 200.0)
    ego_yaw_deg: float = 30.0
    speed: float = 5.0
    seed: int = 0
    format_version: FormatVersion = DEFAULT_FORMAT
    objects: tuple[SyntheticObject, ...] = DEFAULT_OBJECTS
    markers: bool = True
    texture: float = 0.0  # amplitude of band-limited noise added to the images (camera-like JPEG sizes at ~40)
    traffic: int = 0  # extra dynamic vehicles around the ego (released frames hold tens of boxes)
    extra: dict = field(default_factory=dict, compare=False)

    def all_objects(self) -> tuple[SyntheticObject, ...]:
        """The quirk objects plus ``traffic`` vehicles on a deterministic ring around the ego's start."""
        ring = tuple(
            SyntheticObject("lead", str(7000 + i), (30.0 * math.cos(2.4 * i) + 10.0, 30.0 * math.sin(2.4 * i)),
                            (37.0 * i) % 360.0, (2.3, 1.0, 0.8), 0.8)
            for i in range(self.traffic)
        )  # fmt: skip
        return self.objects + ring


def _fwd_right(yaw_deg: float) -> tuple[np.ndarray, np.ndarray]:
    r = Rotation(yaw=yaw_deg)
    return r.forward_vector().to_array()[:2], r.right_vector().to_array()[:2]


def ego_transform(spec: SyntheticClipSpec, frame: int) -> Transform:
    """The exact ego pose at a frame (straight line at constant speed)."""
    fwd, _ = _fwd_right(spec.ego_yaw_deg)
    xy = np.array(spec.ego_start) + fwd * spec.speed * 0.1 * frame
    return Transform(Location(float(xy[0]), float(xy[1]), 0.0), Rotation(yaw=spec.ego_yaw_deg))


def object_transform(spec: SyntheticClipSpec, obj: SyntheticObject, frame: int) -> Transform:
    """An object's actor transform (origin on the ground) at a frame."""
    fwd, right = _fwd_right(spec.ego_yaw_deg)
    start = np.array(spec.ego_start)
    t = 0.1 * frame
    xy = start + fwd * obj.rel_xy[0] + right * obj.rel_xy[1]
    if obj.kind == "lead":
        xy = xy + fwd * spec.speed * t
    xy = xy + (fwd * obj.velocity_ego[0] + right * obj.velocity_ego[1]) * t
    return Transform(Location(float(xy[0]), float(xy[1]), 0.0), Rotation(yaw=spec.ego_yaw_deg + obj.rel_yaw_deg))


def _m(t: Transform) -> list[list[float]]:
    return t.matrix().tolist()


def _inv(t: Transform) -> list[list[float]]:
    return t.inverse_matrix().tolist()


def _sensor_pose(ego: Transform, mount_matrix: np.ndarray) -> tuple[list[float], list[float], list[list[float]]]:
    world = ego.matrix() @ mount_matrix
    t = Transform.from_matrix(world)
    return t.location.to_list(), t.rotation.to_anno(), np.linalg.inv(world).tolist()


def _sensors(spec: SyntheticClipSpec, ego: Transform) -> dict:
    sensors: dict[str, dict] = {}
    for cam in ALL_CAMERAS:
        cam2ego = cam.mount.matrix()
        loc, rot, world2cam = _sensor_pose(ego, cam2ego)
        sensors[cam.sensor_id] = {
            "location": loc, "rotation": rot, "intrinsic": cam.intrinsic(spec.width, spec.height).tolist(),
            "world2cam": world2cam, "cam2ego": cam2ego.tolist(), "fov": cam.fov,
            "image_size_x": spec.width, "image_size_y": spec.height,
        }  # fmt: skip
    radars = RADARS_V004 if spec.format_version is FormatVersion.V004 else RADARS_V0
    for radar in radars:
        radar2ego = radar.mount.matrix()
        loc, rot, world2radar = _sensor_pose(ego, radar2ego)
        sensors[radar.sensor_id] = {
            "location": loc,
            "rotation": rot,
            "world2radar": world2radar,
            "radar2ego": radar2ego.tolist(),
        }
    lidar2ego = LIDAR.mount.matrix()
    loc, rot, world2lidar = _sensor_pose(ego, lidar2ego)
    sensors["LIDAR_TOP"] = {
        "location": loc,
        "rotation": rot,
        "world2lidar": world2lidar,
        "lidar2ego": lidar2ego.tolist(),
    }
    return sensors


def _box_common(spec: SyntheticClipSpec, obj: SyntheticObject, frame: int, ego: Transform) -> dict:
    actor = object_transform(spec, obj, frame)
    bbox = BoundingBox(Location(0.0, 0.0, obj.z_centre), Location(*obj.half_extent))
    centre = actor.transform_point(bbox.location)
    return {
        "actor": actor,
        "location": actor.location.to_list(),
        "rotation": actor.rotation.to_anno(),
        "bbx_loc": bbox.location.to_list(),
        "center": centre.to_list(),
        "extent": list(obj.half_extent),
        "world_cord": bbox.world_corners(actor).tolist(),
        "distance": actor.location.distance_2d(ego.location),
    }


def _object_box(spec: SyntheticClipSpec, obj: SyntheticObject, frame: int, ego: Transform) -> dict:
    c = _box_common(spec, obj, frame, ego)
    actor: Transform = c["actor"]
    road = {"road_id": 1, "lane_id": -1, "section_id": 0}
    if obj.kind == "lead":
        return {
            "class": "vehicle", "state": "dynamic", "id": obj.actor_id, "location": c["location"],
            "rotation": c["rotation"], "bbx_loc": c["bbx_loc"], "center": c["center"], "extent": c["extent"],
            "world_cord": c["world_cord"], "semantic_tags": [14], "type_id": "vehicle.tesla.model3",
            "color": "0,0,0", "base_type": "car", "num_points": 42, "distance": c["distance"], "speed": spec.speed,
            "brake": 0.0, "light_state": "NONE", **road, "world2vehicle": _inv(actor),
        }  # fmt: skip
    if obj.kind == "static":
        # The released quirk: location/rotation of the prop are off, the box comes from center/extent/world2vehicle.
        return {
            "class": "vehicle", "state": "static", "id": obj.actor_id,
            "location": (actor.location + Location(1.5, -0.7, 0.0)).to_list(), "rotation": [0.0, 0.0, 0.0],
            "bbx_loc": c["bbx_loc"], "center": c["center"], "extent": c["extent"], "world_cord": c["world_cord"],
            "semantic_tags": [14], "type_id": PARKED_MESH,
            "num_points": 7, "distance": c["distance"], "speed": 0.0, "brake": 1.0, "light_state": "NONE", **road,
            "world2vehicle": _inv(actor),
        }  # fmt: skip
    if obj.kind == "walker":
        return {
            "class": "walker", "id": obj.actor_id, "location": c["location"], "rotation": c["rotation"],
            "bbx_loc": c["bbx_loc"], "center": c["center"], "extent": c["extent"], "world_cord": c["world_cord"],
            "semantic_tags": [12], "type_id": "walker.pedestrian.0001", "gender": "female", "age": "adult",
            "num_points": 5, "distance": c["distance"], "speed": 0.0, "bone": [], **road, "world2ped": _inv(actor),
        }  # fmt: skip
    if obj.kind in ("light", "stop"):
        fwd, right = _fwd_right(spec.ego_yaw_deg)
        tv_xy = np.array(actor.location.to_list()[:2]) - fwd * 5.0 - right * 3.0
        trigger = {
            "trigger_volume_location": [float(tv_xy[0]), float(tv_xy[1]), 0.5],
            "trigger_volume_rotation": [0.0, 0.0, (spec.ego_yaw_deg + 90.0) % 360.0],
            "trigger_volume_extent": [1.5, 2.0, 1.0],
        }
        if obj.kind == "light":
            return {
                "class": "traffic_light", "id": obj.actor_id, "location": c["location"], "rotation": c["rotation"],
                "center": c["center"], "extent": c["extent"], "semantic_tags": [7], "type_id": "traffic.traffic_light",
                "distance": c["distance"], "state": 0, "affects_ego": True, **trigger, **road,
            }  # fmt: skip
        return {
            "class": "traffic_sign", "id": obj.actor_id, "location": c["location"], "rotation": c["rotation"],
            "center": c["center"], "extent": c["extent"], "semantic_tags": [8], "type_id": "traffic.stop",
            "distance": c["distance"], "affects_ego": False, **trigger, **road, "world2sign": _inv(actor),
        }  # fmt: skip
    if obj.kind == "debris":
        return {
            "class": "traffic_sign", "id": obj.actor_id, "location": c["location"], "rotation": c["rotation"],
            "bbx_loc": c["bbx_loc"], "center": c["center"], "extent": c["extent"], "world_cord": c["world_cord"],
            "semantic_tags": [20], "type_id": "static.prop.dirtdebris01", "distance": c["distance"],
            "affects_ego": False, **road, "world2sign": _inv(actor),
        }  # fmt: skip
    raise ValueError(f"unknown synthetic object kind {obj.kind!r}")


def scene_anno(spec: SyntheticClipSpec, frame: int) -> dict:
    """The complete annotation of a frame, in Bench2Drive's key orders."""
    ego = ego_transform(spec, frame)
    yaw = math.radians(spec.ego_yaw_deg)
    fwd, _ = _fwd_right(spec.ego_yaw_deg)
    ego_xy = np.array([ego.location.x, ego.location.y])
    gnss = ego_xy + fwd * GNSS_OFFSET

    def ahead(d: float) -> tuple[float, float]:
        p = ego_xy + fwd * d
        return float(p[0]), float(p[1])

    ego_bbox = BoundingBox(Location(0.0, 0.0, EGO_HALF_EXTENT[2]), Location(*EGO_HALF_EXTENT))
    ego_box = {
        "class": "ego_vehicle", "id": "0", "type_id": EGO_TYPE_ID, "base_type": "car",
        "location": ego.location.to_list(), "rotation": ego.rotation.to_anno(), "bbx_loc": ego_bbox.location.to_list(),
        "center": ego.transform_point(ego_bbox.location).to_list(), "extent": list(EGO_HALF_EXTENT),
        "world_cord": ego_bbox.world_corners(ego).tolist(), "semantic_tags": [[14]], "color": "0,0,0",
        "speed": spec.speed, "brake": 0.0, "road_id": 1, "lane_id": -1, "section_id": 0, "world2ego": _inv(ego),
    }  # fmt: skip
    boxes = [ego_box] + [_object_box(spec, obj, frame, ego) for obj in spec.all_objects()]
    far, near, target = ahead(50.0), ahead(20.0), ahead(10.0)
    weather = PRESETS[spec.name.weather_id if spec.name.weather_id in PRESETS else 0].to_anno()
    return {
        "x": float(gnss[0]), "y": float(gnss[1]), "throttle": 0.5, "steer": 0.1, "brake": 0.0, "reverse": False,
        "theta": (yaw + math.pi / 2.0) % (2.0 * math.pi), "speed": spec.speed,
        "x_command_far": far[0], "y_command_far": far[1], "command_far": 4,
        "x_command_near": near[0], "y_command_near": near[1], "command_near": 4,
        "should_brake": False, "x_target": target[0], "y_target": target[1], "next_command": 4,
        "weather": weather, "acceleration": [0.5, 0.25, 9.81], "angular_velocity": [0.01, 0.02, 0.03],
        "bounding_boxes": boxes, "sensors": _sensors(spec, ego), "only_ap_brake": False,
    }  # fmt: skip


def project_world_point(anno: dict, sensor_id: str, point: np.ndarray) -> tuple[float, float, float]:
    """Pixel (u, v) and depth of a CARLA-world point, as tools/utils.py ``get_image_point`` computes it."""
    entry = anno["sensors"][sensor_id]
    p = np.asarray(entry["world2cam"]) @ np.array([point[0], point[1], point[2], 1.0])
    cv = np.array([p[1], -p[2], p[0]])  # UE (x fwd, y right, z up) → OpenCV (x right, y down, z fwd)
    uvw = np.asarray(entry["intrinsic"]) @ cv
    return float(uvw[0] / uvw[2]), float(uvw[1] / uvw[2]), float(cv[2])


def _image(spec: SyntheticClipSpec, anno: dict, cam: str, frame: int) -> np.ndarray:
    h, w = spec.height, spec.width
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.empty((h, w, 3), np.uint8)
    img[..., 0] = (40 + 120 * xx / max(w - 1, 1)).astype(np.uint8)
    img[..., 1] = (40 + 120 * yy / max(h - 1, 1)).astype(np.uint8)
    img[..., 2] = (60 + 7 * (ALL_CAMERAS.index(camera(cam)) + frame)) % 200
    if spec.texture > 0:
        # Band-limited noise at two scales: JPEG sizes and decode times close to rendered street scenes.
        rng = np.random.default_rng(spec.seed * 7919 + frame * 31 + ALL_CAMERAS.index(camera(cam)))
        coarse = cv2.resize(
            rng.normal(0, 1, (h // 16 + 1, w // 16 + 1, 3)).astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC
        )
        fine = cv2.resize(
            rng.normal(0, 1, (h // 3 + 1, w // 3 + 1, 3)).astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR
        )
        img = np.clip(img + spec.texture * (coarse + 0.5 * fine), 0, 255).astype(np.uint8)
    if spec.markers:
        sensor_id = camera(cam).sensor_id
        r = max(1, min(w, h) // 24)
        for box in anno["bounding_boxes"][1:]:
            u, v, depth = project_world_point(anno, sensor_id, np.asarray(box["center"]))
            if depth > 0.5 and 0 <= u < w and 0 <= v < h:
                ui, vi = int(round(u)), int(round(v))
                img[max(0, vi - r) : vi + r + 1, max(0, ui - r) : ui + r + 1] = 255
    return img


def _lidar_sweep(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` ego-frame points ordered like a spinning 64-channel sweep: rings on flat ground, walls 20–60 m away.

    Ordered neighbours are what LAZ's predictive coder sees in real sweeps; uniformly scattered points would
    compress (and decode) far worse than any real LiDAR frame.
    """
    channels = 64
    steps = -(-n // channels)
    elev = np.radians(np.linspace(10.0, -30.0, channels))[None, :]
    azim = np.radians(np.arange(steps) * (360.0 / steps))[:, None]
    height = LIDAR.mount.z
    wall = 40.0 + 20.0 * np.sin(3.0 * azim) * np.cos(5.0 * azim)  # façades at 20–60 m, varying with azimuth
    down = np.sin(-elev)
    ground = np.where(down > 1e-6, height / np.maximum(down, 1e-6), np.inf)
    horizontal = np.minimum(wall, ground * np.cos(elev))
    r = horizontal / np.cos(elev) + rng.normal(0.0, 0.01, (steps, channels))
    pts = np.stack([r * np.cos(elev) * np.cos(azim), r * np.cos(elev) * np.sin(azim),
                    r * np.sin(elev) + height], axis=-1)  # fmt: skip
    return pts.reshape(-1, 3)[:n] + np.array([LIDAR.mount.x, LIDAR.mount.y, 0.0])


def synthetic_record(spec: SyntheticClipSpec, frame: int) -> FrameRecord:
    """The FrameRecord of one synthetic frame (images, dense labels, LiDAR, radar, expert vector)."""
    anno = scene_anno(spec, frame)
    rng = np.random.default_rng(spec.seed * 1000 + frame)
    cams: dict[str, CameraFrame] = {}
    for cam in spec.cameras:
        rgb = _image(spec, anno, cam, frame)
        if spec.dense and camera(cam).has_dense_labels:
            yy, xx = np.mgrid[0 : spec.height, 0 : spec.width]
            depth = (2.0 + 0.37 * yy + 0.11 * xx + frame).astype(np.float32)
            depth[0, :] = 1000.0  # sky row: stored as 255 in the uint8 PNG
            semantic = ((xx // 8 + yy // 8) % 29).astype(np.uint8)
            instance = (xx * 37 + yy * 101 + frame).astype(np.uint16)
            cams[cam] = CameraFrame(rgb, depth, semantic, instance)
        else:
            cams[cam] = CameraFrame(rgb)
    lidar = _lidar_sweep(spec.lidar_points, rng) if spec.lidar_points else None
    radar = None
    if spec.radar:
        radar = {}
        for r in RADARS_V0:
            n = 0 if r.dataset == "radar_back_left" else 3
            det = np.stack(
                [rng.uniform(5, 60, n), rng.uniform(-0.2, 0.2, n), rng.uniform(-0.25, 0.25, n), rng.uniform(-5, 5, n)],
                axis=1,
            )
            radar[r.dataset] = det.astype(np.float16)
    expert = None
    if spec.expert:
        expert = np.concatenate([rng.normal(size=8), [0.5 + frame, float(frame % 39)]]).astype(np.float32)
    return FrameRecord(frame, anno, cams, lidar, radar, expert)


def write_synthetic_clip(
    root: str | os.PathLike[str], spec: SyntheticClipSpec, workers: int = 0, hdmap: str | os.PathLike[str] | None = None
) -> Path:
    """Write a synthetic clip under ``root`` with ``ClipWriter``; returns the clip folder."""
    from b2d_data.writers.clip_writer import ClipWriter

    with ClipWriter(root, spec.name, spec.format_version, hdmap=hdmap, workers=workers, extra=spec.extra) as writer:
        for frame in range(spec.frames):
            writer.write(synthetic_record(spec, frame))
    return Path(root) / str(spec.name)


def synthetic_clip_names(n: int) -> list[ClipName]:
    """``n`` distinct valid clip names cycling through scenarios, towns and weathers."""
    towns = ("Town01", "Town03", "Town04", "Town05", "Town10HD", "Town12", "Town13", "Town15")
    return [
        ClipName(SCENARIO_TYPES[i % len(SCENARIO_TYPES)].clip_prefix, towns[i % len(towns)], 1000 + i,
                 WEATHER_IDS[(i * 5) % len(WEATHER_IDS)])
        for i in range(n)
    ]  # fmt: skip


def fabricate_index(root: str | os.PathLike[str], n_clips: int = 1000, n_frames: int = 200) -> Path:
    """Write a ``.b2d_index`` for ``n_clips`` × ``n_frames`` clips directly (no clip files): for open-time checks."""
    from b2d_data.loaders.clip_scan import MODALITIES, POSE_COLUMNS, ClipScan
    from b2d_data.loaders.index import FRAME_SCHEMA, CorpusIndex, _clip_row

    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    frames = np.arange(n_frames, dtype=np.int32)
    present = {m: np.ones(n_frames, bool) for m in MODALITIES}
    t = frames * 0.1
    parts = []
    for name in synthetic_clip_names(n_clips):
        scan = ClipScan(
            name=str(name), path=str(name), frames=frames, presence=present, format_version=DEFAULT_FORMAT.value
        )
        scan.poses = {
            "ego_x": 5.0 * t, "ego_y": np.zeros(n_frames), "ego_z": np.zeros(n_frames), "ego_yaw": np.zeros(n_frames),
            "gnss_x": 5.0 * t - 1.4, "gnss_y": np.zeros(n_frames), "theta": np.full(n_frames, math.pi / 2),
            "speed": np.full(n_frames, 5.0),
        }  # fmt: skip
        cols = {"clip_id": pa.array(np.zeros(n_frames, np.int32)), "frame": pa.array(frames)}
        cols.update({f"has_{m}": pa.array(present[m]) for m in MODALITIES})
        cols.update({c: pa.array(scan.poses[c]) for c in POSE_COLUMNS})
        parts.append((_clip_row(scan), pa.table(cols, schema=FRAME_SCHEMA)))
    return CorpusIndex.from_scans(root, parts).save()
