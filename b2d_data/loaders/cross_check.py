"""Cross-sensor consistency of a clip: do the annotation's boxes agree with the LiDAR and the cameras' labels?

Per frame (``b2d-verify ROOT --deep``):

- ``num_points``: Bench2Drive's rule (:func:`b2d_data.collection.annotations.anno_points_in_box`) applied to the
  frame's LAZ file must give every stored value exactly;
- vehicle and walker boxes, projected into each camera with the annotation's own ``cam2ego`` and ``intrinsic``:
  a box whose region is mostly visible (depth image not nearer than the box by ≥ 1 m over half of it) must hold
  some of its instance pixels, and an actor's instance pixels must lie in its box's region;
- traffic-light and traffic-sign boxes (``center``, ``extent``, ``rotation``: the level box): the head (tag 7) /
  plate (tag 8) pixels of that id must lie in the box's region, and a visible box must hold some.

Thresholds leave room for rasterisation (1 px slack around the projected region), the 1 m steps of the depth PNG
and the empty corners of a car's box; on clean clips every object's pixels lie in its region (share 1.0), while a
box moved off its object is reported.
"""

from __future__ import annotations

import math
import tarfile
import tempfile
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from b2d_data import coords
from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import read_anno
from b2d_data.codecs.depth import read_depth_npz, read_depth_png
from b2d_data.codecs.labels_png import read_instance_png
from b2d_data.codecs.laz import read_laz
from b2d_data.collection.annotations import anno_points_in_box
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.rig import CAMERAS, LIDAR, CameraSpec
from b2d_data.format.semantic import SemanticTag
from b2d_data.format.transform import rotation_matrix

#: Closest camera depth (m) a box corner is projected from; the box is clipped there.
NEAR = 0.1
#: A region pixel counts as visible (not occluded) when the depth image there is no nearer than the box's nearest
#: corner minus this (m): the depth PNG holds whole metres.
OCCLUSION_MARGIN = 1.0
#: A box needs this many visible pixels, this share of its region visible and this share of its outline in the
#: image before a missing instance is reported: a car's mesh leaves the corners of its box's outline empty, and
#: those may show what lies behind.
MIN_VISIBLE = 30
MIN_VISIBLE_SHARE = 0.5
MIN_IN_IMAGE = 0.25
#: An object needs this many pixels before their share outside its box is judged.
MIN_PIXELS = 30
#: Share of an object's pixels that must lie in its (dilated) projected box.
MIN_INSIDE = 0.9


@dataclass(frozen=True)
class Disagreement:
    """One box that does not agree with one sensor in one frame."""

    frame: int
    kind: str  # num_points | actor_pixels | sign_pixels | light_pixels | unreadable
    box_id: str
    sensor: str
    detail: str


@dataclass
class ClipCheck:
    """The result of checking one clip: how many comparisons of each kind ran and what disagreed."""

    clip: str
    frames: int = 0
    checked: Counter = field(default_factory=Counter)
    disagreements: list[Disagreement] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when nothing disagreed."""
        return not self.disagreements


# ------------------------------------------------------------------------------------------------ geometry


def _level_box_to_world(box: dict) -> np.ndarray:
    """Object → world 4×4 of a light/sign level box: its ``center`` and ``rotation`` (the actor's ``world2sign``
    turns differently from its plate)."""
    pitch, roll, yaw = (float(v) for v in box.get("rotation", (0.0, 0.0, 0.0)))
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(pitch, yaw, roll)
    m[:3, 3] = np.asarray(box.get("center", box.get("location")), dtype=np.float64)[:3]
    return m


def box_corners_ego(box: dict, world2ego: np.ndarray) -> np.ndarray:
    """(8, 3) corners of an annotation box in the CARLA ego frame (lights/signs: their level box)."""
    if box.get("class") in ("traffic_light", "traffic_sign") and "trigger_volume_location" in box:
        obj2world = _level_box_to_world(box)
    else:
        obj2world = coords.object_to_world(box)
    half = coords.box_size(box) / 2.0
    signs = np.array([(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)], dtype=np.float64)
    local = signs * half
    m = np.asarray(world2ego, dtype=np.float64) @ obj2world
    return local @ m[:3, :3].T + m[:3, 3]


_EDGES = [(i, j) for i in range(8) for j in range(i + 1, 8) if bin(i ^ j).count("1") == 1]


@dataclass(frozen=True)
class Region:
    """A box's projection over the image rectangle at (x0, y0): its exact ``mask``, the mask grown by a pixel
    all round (``grown``: rasterisation slack for containment), its nearest camera depth and the share of its
    whole outline that falls in the image (``in_image``)."""

    x0: int
    y0: int
    mask: np.ndarray
    grown: np.ndarray
    near: float
    in_image: float

    def window(self, image: np.ndarray) -> np.ndarray:
        """The part of a full image under the mask."""
        h, w = self.grown.shape
        return image[self.y0 : self.y0 + h, self.x0 : self.x0 + w]


def project_box(corners_cam: np.ndarray, k: np.ndarray, width: int, height: int) -> Region | None:
    """The image region of a box given by its (8, 3) OpenCV-camera corners (clipped at :data:`NEAR`), or None."""
    z = corners_cam[:, 2]
    if (z < NEAR).all():
        return None
    pts = [corners_cam[i] for i in range(8) if z[i] >= NEAR]
    for i, j in _EDGES:
        if (z[i] >= NEAR) != (z[j] >= NEAR):
            t = (NEAR - z[i]) / (z[j] - z[i])
            pts.append(corners_cam[i] + t * (corners_cam[j] - corners_cam[i]))
    p = np.array(pts)
    uv = (p @ k.T)[:, :2] / p[:, 2:3]
    # Far outside the image nothing is drawn; clamp so that the integer polygon stays small.
    size = np.array([width, height], dtype=np.float64)
    uv = np.clip(uv, -4.0 * size, 5.0 * size)
    # The window drawn in reaches one pixel beyond the image, so that the slack below also grows inwards from
    # a box that lies just outside it.
    x0, y0 = max(int(math.floor(uv[:, 0].min())) - 1, -1), max(int(math.floor(uv[:, 1].min())) - 1, -1)
    x1, y1 = min(int(math.ceil(uv[:, 0].max())) + 2, width + 1), min(int(math.ceil(uv[:, 1].max())) + 2, height + 1)
    if x0 >= x1 or y0 >= y1:
        return None
    outline = float(cv2.contourArea(cv2.convexHull(uv.astype(np.float32))))
    hull = cv2.convexHull(np.round((uv - [x0, y0]) * 16).astype(np.int32))
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillConvexPoly(mask, hull, 1, lineType=cv2.LINE_8, shift=4)
    # One pixel of slack all round: the renderer and this fill may place pixel centres half a pixel apart and
    # round edges differently.
    grown = cv2.dilate(mask, np.ones((3, 3), np.uint8))
    crop = (slice(-y0 if y0 < 0 else 0, height - y0), slice(-x0 if x0 < 0 else 0, width - x0))
    mask, grown = mask[crop], grown[crop]
    if not grown.any():
        return None
    in_image = min(1.0, float(mask.sum()) / outline) if outline > 0.0 else 1.0
    return Region(max(x0, 0), max(y0, 0), mask.astype(bool), grown.astype(bool), float(p[:, 2].min()), in_image)


# ------------------------------------------------------------------------------------------------ one frame


def _camera_images(clip_dir: Path, cam: CameraSpec, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(tags, ids, depth) of one camera in one frame, or None when the clip has no instance images for it."""
    inst = layout.image_path(clip_dir, "instance", cam.folder, frame)
    if not inst.is_file():
        return None
    tags, ids = read_instance_png(inst)
    depth_png = layout.image_path(clip_dir, "depth", cam.folder, frame)
    npz = layout.depth_npz_path(clip_dir, cam.folder, frame)
    if depth_png.is_file():
        depth = read_depth_png(depth_png)
    elif npz.is_file():
        depth = read_depth_npz(npz)
    else:
        depth = np.full(tags.shape, np.inf, np.float32)  # no depth: every region pixel counts as visible
    return tags, ids, depth


def _pixel_kind(box: dict) -> tuple[str, int | None] | None:
    """(disagreement kind, semantic tag to match or None for any) of a box checked against instance pixels."""
    cls = box.get("class")
    if cls in ("vehicle", "walker"):
        return "actor_pixels", None
    if cls == "traffic_light":
        return "light_pixels", int(SemanticTag.TRAFFIC_LIGHT)
    if cls == "traffic_sign" and "trigger_volume_location" in box:
        return "sign_pixels", int(SemanticTag.TRAFFIC_SIGN)
    return None


def check_camera(
    anno: dict, frame: int, cam: CameraSpec, tags: np.ndarray, ids: np.ndarray, depth: np.ndarray, out: ClipCheck
) -> None:
    """Every box of a frame against one camera's instance and depth images."""
    height, width = ids.shape
    k = coords.camera_intrinsic(anno, cam.sensor_id, width, height)
    stored = (anno.get("sensors") or {}).get(cam.sensor_id) or {}
    sx, sy = stored.get("image_size_x"), stored.get("image_size_y")
    if sx and sy and (int(sx), int(sy)) != (width, height):
        k = np.diag([width / float(sx), height / float(sy), 1.0]) @ k
    ego2cam = np.linalg.inv(coords.camera_cam2ego(anno, cam.sensor_id, "carla"))
    world2ego = np.asarray(anno["bounding_boxes"][0]["world2ego"], dtype=np.float64)
    for box in anno["bounding_boxes"][1:]:
        judged = _pixel_kind(box)
        if judged is None:
            continue
        kind, tag = judged
        try:
            object_id = int(box["id"])
        except (KeyError, TypeError, ValueError):
            continue
        corners = box_corners_ego(box, world2ego)
        region = project_box(corners @ ego2cam[:3, :3].T + ego2cam[:3, 3], k, width, height)
        own = ids == object_id
        if tag is not None:
            own &= tags == tag
        total = int(np.count_nonzero(own))
        if region is None:
            if total >= MIN_PIXELS:
                out.checked[kind] += 1
                detail = f"{total} px of the object but its box projects off the image"
                out.disagreements.append(Disagreement(frame, kind, box["id"], cam.sensor_id, detail))
            continue
        inside = int(np.count_nonzero(region.window(own) & region.grown))
        visible = int(np.count_nonzero(region.mask & (region.window(depth) >= region.near - OCCLUSION_MARGIN)))
        # A box mostly beside the image may show only an empty corner of its outline.
        in_view = region.in_image >= MIN_IN_IMAGE and visible >= max(
            MIN_VISIBLE, MIN_VISIBLE_SHARE * np.count_nonzero(region.mask)
        )
        if not in_view and total < MIN_PIXELS:
            continue
        out.checked[kind] += 1
        if in_view and inside == 0:
            out.disagreements.append(Disagreement(
                frame, kind, box["id"], cam.sensor_id,
                f"box visible ({visible} px not occluded, nearest {region.near:.1f} m) but none of its {total} "
                "instance px inside it",
            ))  # fmt: skip
        elif total >= MIN_PIXELS and inside < MIN_INSIDE * total:
            out.disagreements.append(Disagreement(
                frame, kind, box["id"], cam.sensor_id,
                f"only {inside} of its {total} instance px ({inside / total:.0%}) inside its projected box",
            ))  # fmt: skip


def check_lidar(anno: dict, frame: int, points: np.ndarray, out: ClipCheck) -> None:
    """Every stored ``num_points`` against the frame's LAZ points (read as float64, as stored)."""
    for box in anno["bounding_boxes"][1:]:
        stored = box.get("num_points")
        if stored is None or stored < 0:
            continue
        out.checked["num_points"] += 1
        count = anno_points_in_box(points, anno, box)
        if count != stored:
            out.disagreements.append(Disagreement(frame, "num_points", str(box.get("id")), LIDAR.sensor_id,
                                                  f"num_points {stored}, the LAZ file gives {count}"))  # fmt: skip


def check_frame(clip_dir: Path, frame: int, out: ClipCheck) -> None:
    """All checks of one frame of a clip folder."""
    anno = read_anno(layout.anno_path(clip_dir, frame))
    lidar_path = layout.lidar_path(clip_dir, frame)
    if lidar_path.is_file():
        check_lidar(anno, frame, read_laz(lidar_path), out)
    for cam in CAMERAS:
        images = _camera_images(clip_dir, cam, frame)
        if images is not None:
            check_camera(anno, frame, cam, *images, out)


# ------------------------------------------------------------------------------------------------ clips


def clip_frames(clip_dir: Path) -> list[int]:
    """Frame numbers of a clip folder (from its annotation files)."""
    frames = []
    for path in (clip_dir / layout.ANNO_DIR).glob("*.json.gz"):
        stem = path.name[: -len(".json.gz")]
        if stem.isdigit():
            frames.append(int(stem))
    return sorted(frames)


def check_clip(clip_dir: Path, every: int = 1, name: str | None = None) -> ClipCheck:
    """Check every ``every``-th frame of a clip folder; unreadable frames are reported, not raised."""
    out = ClipCheck(name or clip_dir.name)
    for frame in clip_frames(clip_dir)[:: max(1, every)]:
        try:
            check_frame(clip_dir, frame, out)
        except (B2DFormatError, OSError, KeyError, ValueError, TypeError, IndexError) as exc:
            out.disagreements.append(Disagreement(frame, "unreadable", "", "", f"{type(exc).__name__}: {exc}"))
        out.frames += 1
    return out


def _clip_root(extracted: Path, clip: str) -> Path:
    """The clip folder inside an extracted archive (with or without a ``<clip>/`` top folder)."""
    if (extracted / layout.ANNO_DIR).is_dir():
        return extracted
    for candidate in (extracted / clip, *sorted(p for p in extracted.iterdir() if p.is_dir())):
        if (candidate / layout.ANNO_DIR).is_dir():
            return candidate
    raise B2DFormatError(extracted, f"archive of {clip} holds no anno/ folder")


def check_archive(archive: Path, clip: str, every: int = 1) -> ClipCheck:
    """Check a ``<clip>.tar.gz``, extracted to a temporary folder for the duration of the check."""
    with tempfile.TemporaryDirectory(prefix=".b2d-verify-") as folder:
        try:
            with tarfile.open(archive) as tar:
                tar.extractall(folder, filter="data")
            root = _clip_root(Path(folder), clip)
        except (tarfile.TarError, OSError, B2DFormatError) as exc:
            out = ClipCheck(clip)
            out.disagreements.append(Disagreement(-1, "unreadable", "", "", f"{archive}: {exc}"))
            return out
        return check_clip(root, every, clip)


def iter_checks(root: Path, every: int = 1, names: set[str] | None = None) -> Iterator[ClipCheck]:
    """Check every clip under a corpus root (folders first; archives only where no folder exists)."""
    from b2d_data.loaders.clip_scan import discover_clips

    for loc in discover_clips(root):
        if names and loc.name not in names:
            continue
        if loc.path:
            yield check_clip(root / loc.path, every, loc.name)
        else:
            yield check_archive(root / loc.archive, loc.name, every)
