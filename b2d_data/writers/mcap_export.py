"""Export a clip to MCAP with Foxglove schemas, so it opens in Foxglove Studio with everything in place.

Channels (one message per frame each, timestamps at 10 Hz from ``start_ns``):

- ``/camera/<cam>/image`` ``foxglove.CompressedImage``: the clip's JPEG bytes as stored (no re-encoding),
  frame ``<CAM_ID>`` in the optical convention (x right, y down, z forward).
- ``/camera/<cam>/calibration`` ``foxglove.CameraCalibration``: K, P = [K | 0], width/height from the annotation.
- ``/lidar`` ``foxglove.PointCloud``: the LAZ points (float32 x, y, z) in frame ``ego``.
- ``/boxes`` ``foxglove.SceneUpdate``: one entity per annotated object (``CubePrimitive`` with full sizes) in
  frame ``ego``, plus the ego's own box; entities live one frame period and a half.
- ``/tf`` ``foxglove.FrameTransforms``: ``world`` → ``ego`` (exact pose) → every camera, ``LIDAR_TOP`` and radar.

Everything is right-handed: ``world`` is CARLA's world with y negated (x east, y north, z up), ``ego`` is the
ISO 8855 ego frame (x forward, y left, z up); conversions come from ``b2d_data.coords``.
foxglove-sdk is an optional dependency (``pip install b2d-data[viz]``).
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation as ScipyRotation

from b2d_data import coords
from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import read_anno
from b2d_data.codecs.laz import read_laz
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipName
from b2d_data.format.rig import ALL_CAMERAS, RADARS_V0, camera

logger = logging.getLogger(__name__)

SURROUND = tuple(c.folder for c in ALL_CAMERAS if c.has_dense_labels)
FRAME_PERIOD_NS = 100_000_000  # 10 Hz
_CLASS_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "ego_vehicle": (0.2, 0.6, 1.0, 0.5),
    "vehicle": (1.0, 0.6, 0.1, 0.5),
    "walker": (0.9, 0.1, 0.3, 0.6),
    "traffic_light": (0.1, 0.9, 0.2, 0.5),
    "traffic_sign": (0.9, 0.9, 0.1, 0.5),
}


def _foxglove() -> Any:
    try:
        import foxglove
    except ImportError as exc:  # the SDK is the optional ``viz`` extra
        raise ImportError("MCAP export needs foxglove-sdk: pip install 'b2d-data[viz]'") from exc
    return foxglove


@dataclass
class McapExportReport:
    """What was written: the file, its frame count and the message count per topic."""

    path: Path
    frames: int
    messages: dict[str, int] = field(default_factory=dict)


def _clip_frames(clip_dir: Path) -> list[int]:
    anno_dir = clip_dir / layout.ANNO_DIR
    if not anno_dir.is_dir():
        raise B2DFormatError(clip_dir, "not a clip folder (no anno/ folder inside)")
    frames = []
    for entry in os.scandir(anno_dir):
        stem = entry.name.removesuffix(".json.gz")
        if stem != entry.name and stem.lstrip("-").isdigit():
            frames.append(int(stem))
    if not frames:
        raise B2DFormatError(anno_dir, "no annotation files")
    return sorted(frames)


def _quat(m: np.ndarray) -> tuple[float, float, float, float]:
    x, y, z, w = ScipyRotation.from_matrix(np.asarray(m, np.float64)[:3, :3]).as_quat()
    return float(x), float(y), float(z), float(w)


def export_mcap(
    clip_dir: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    cameras: tuple[str, ...] = SURROUND,
    lidar: bool = True,
    boxes: bool = True,
    start_ns: int = 0,
    overwrite: bool = False,
) -> McapExportReport:
    """Write ``clip_dir`` to an MCAP file at ``out_path`` (see the module docstring for channels and frames)."""
    fg = _foxglove()
    from foxglove import channels as ch
    from foxglove import messages as msg

    clip_dir, out_path = Path(clip_dir), Path(out_path)
    if out_path.exists() and not overwrite:
        raise FileExistsError(f"{out_path} exists (pass overwrite=True to replace it)")
    ClipName.parse(clip_dir.name)  # a malformed clip name raises ClipNameError naming it
    frames = _clip_frames(clip_dir)
    folders = tuple(camera(c).folder for c in cameras)
    context = fg.Context()  # a private context: several exports in one process never share channels
    report = McapExportReport(out_path, len(frames))

    with fg.open_mcap(out_path, allow_overwrite=overwrite, context=context):
        image_ch = {c: ch.CompressedImageChannel(f"/camera/{c}/image", context=context) for c in folders}
        calib_ch = {c: ch.CameraCalibrationChannel(f"/camera/{c}/calibration", context=context) for c in folders}
        lidar_ch = ch.PointCloudChannel("/lidar", context=context) if lidar else None
        boxes_ch = ch.SceneUpdateChannel("/boxes", context=context) if boxes else None
        tf_ch = ch.FrameTransformsChannel("/tf", context=context)

        def log(channel: Any, message: Any, t_ns: int) -> None:
            channel.log(message, log_time=t_ns)
            report.messages[channel.topic()] = report.messages.get(channel.topic(), 0) + 1

        for k, frame in enumerate(frames):
            t_ns = start_ns + k * FRAME_PERIOD_NS
            stamp = msg.Timestamp(t_ns // 1_000_000_000, t_ns % 1_000_000_000)
            anno = read_anno(layout.anno_path(clip_dir, frame))
            world2ego = np.asarray(anno["bounding_boxes"][0]["world2ego"], np.float64)
            log(tf_ch, _transforms(msg, anno, world2ego, folders, stamp), t_ns)
            for cam in folders:
                sensor_id = camera(cam).sensor_id
                path = layout.image_path(clip_dir, "rgb", cam, frame)
                try:
                    data = path.read_bytes()
                except FileNotFoundError:
                    raise B2DFormatError(path, "file does not exist") from None
                log(
                    image_ch[cam],
                    msg.CompressedImage(timestamp=stamp, frame_id=sensor_id, data=data, format="jpeg"),
                    t_ns,
                )
                log(calib_ch[cam], _calibration(msg, anno, sensor_id, stamp), t_ns)
            if lidar_ch is not None:
                pts = coords.to_frame_points(read_laz(layout.lidar_path(clip_dir, frame), dtype=np.float32), "iso")
                log(lidar_ch, _point_cloud(msg, pts, stamp), t_ns)
            if boxes_ch is not None:
                log(boxes_ch, _scene_update(msg, anno, world2ego, stamp), t_ns)
    logger.info("wrote %s: %d frames, %s", out_path, len(frames), report.messages)
    return report


def _vec(msg: Any, v: np.ndarray) -> Any:
    return msg.Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _tf(msg: Any, parent: str, child: str, m: np.ndarray, stamp: Any) -> Any:
    x, y, z, w = _quat(m)
    return msg.FrameTransform(
        timestamp=stamp, parent_frame_id=parent, child_frame_id=child, translation=_vec(msg, m[:3, 3]),
        rotation=msg.Quaternion(x=x, y=y, z=z, w=w),
    )  # fmt: skip


def _transforms(msg: Any, anno: dict, world2ego: np.ndarray, folders: tuple[str, ...], stamp: Any) -> Any:
    ego2world = coords.to_frame_matrix(np.linalg.inv(world2ego), "iso")
    out = [_tf(msg, "world", "ego", ego2world, stamp)]
    for cam in folders:
        sensor_id = camera(cam).sensor_id
        out.append(_tf(msg, "ego", sensor_id, coords.camera_cam2ego(anno, sensor_id, "iso"), stamp))
    sensors = anno.get("sensors") or {}
    if sensors.get("LIDAR_TOP", {}).get("lidar2ego") is not None:
        out.append(_tf(msg, "ego", "LIDAR_TOP", coords.sensor_to_ego(sensors["LIDAR_TOP"]["lidar2ego"], "iso"), stamp))
    for radar in RADARS_V0:
        m = coords.radar_to_ego_matrix(anno, radar.sensor_id)
        out.append(_tf(msg, "ego", radar.sensor_id, coords.sensor_to_ego(m, "iso"), stamp))
    return msg.FrameTransforms(transforms=out)


def _calibration(msg: Any, anno: dict, sensor_id: str, stamp: Any) -> Any:
    entry = (anno.get("sensors") or {}).get(sensor_id) or {}
    spec = camera(sensor_id)
    width = int(entry.get("image_size_x") or spec.width)
    height = int(entry.get("image_size_y") or spec.height)
    k = coords.camera_intrinsic(anno, sensor_id, width, height)
    p = np.concatenate([k, np.zeros((3, 1))], axis=1)
    return msg.CameraCalibration(
        timestamp=stamp, frame_id=sensor_id, width=width, height=height, distortion_model="plumb_bob",
        D=[0.0] * 5, K=[float(v) for v in k.ravel()], R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        P=[float(v) for v in p.ravel()],
    )  # fmt: skip


def _point_cloud(msg: Any, pts: np.ndarray, stamp: Any) -> Any:
    f32 = msg.PackedElementFieldNumericType.Float32
    fields = [msg.PackedElementField(name=n, offset=4 * i, type=f32) for i, n in enumerate("xyz")]
    data = np.ascontiguousarray(pts, dtype="<f4").tobytes()
    return msg.PointCloud(
        timestamp=stamp, frame_id="ego", pose=msg.Pose(position=msg.Vector3(), orientation=msg.Quaternion(w=1.0)),
        point_stride=12, fields=fields, data=data,
    )  # fmt: skip


def _scene_update(msg: Any, anno: dict, world2ego: np.ndarray, stamp: Any) -> Any:
    lifetime = msg.Duration(0, int(1.5 * FRAME_PERIOD_NS))
    entities = []
    for box in anno["bounding_boxes"]:
        cls = str(box.get("class"))
        b7 = coords.box_in_ego(box, world2ego, "iso")
        half = b7[6] / 2.0
        r, g, b, a = _CLASS_COLOURS.get(cls, (0.7, 0.7, 0.7, 0.5))
        yaw_quat = msg.Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))
        cube = msg.CubePrimitive(
            pose=msg.Pose(position=_vec(msg, b7[:3]), orientation=yaw_quat),
            size=_vec(msg, b7[3:6]),
            color=msg.Color(r=r, g=g, b=b, a=a),
        )
        entities.append(
            msg.SceneEntity(
                timestamp=stamp,
                frame_id="ego",
                id=f"{cls}/{box.get('id')}",
                lifetime=lifetime,
                cubes=[cube],
                metadata=[msg.KeyValuePair(key="type_id", value=str(box.get("type_id", "")))],
            )
        )
    return msg.SceneUpdate(entities=entities)
