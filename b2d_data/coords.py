"""Every frame conversion and every known Bench2Drive data fix, in one tested module.

Frames (format.md §4)
---------------------
``carla-world``  left-handed: x east, y south, z up (metres); yaw in degrees, clockwise seen from above.
                 Annotation ``x, y``, ``location``, ``center``, ``world_cord``, HD map, route XML.
``carla-ego``    left-handed: x forward, y right, z up; origin = ego actor location (near the ground).
                 LAZ points, ``cam2ego`` / ``lidar2ego`` / ``radar2ego`` targets, IMU vectors.
``carla-sensor`` left-handed UE axes (x forward, y right, z up) at a sensor mount; raw radar detections.
``opencv``       camera frame: x right, y down, z forward; pixel = K · p / p_z.
``iso``          ISO 8855 ego frame, right-handed: x forward, y left, z up = ``carla-ego`` with y negated.
                 Yaw is counter-clockwise seen from above, i.e. iso yaw = −(CARLA yaw). This is the frame
                 ``ClipDataset`` returns by default.
``iso-world``    ``carla-world`` with y negated (x east, y north, z up): the right-handed world of MCAP export.
``zoo-lidar``    Bench2DriveZoo's nuScenes-like LiDAR frame (UniAD/VAD training data): x right, y forward,
                 z up at the LiDAR mount (ego (−0.39, 0, 1.84)). See the ``zoo_*`` functions.

A point converts between a left-handed CARLA frame and its right-handed twin as ``F p`` with
``F = diag(1, −1, 1)``; a transform between two CARLA-convention frames converts as ``F M F``
(both its source and its target are flipped). Vectors (velocity, acceleration) convert like points;
the angular velocity is a pseudo-vector, so it converts as ``−F ω`` = (−ωx, ωy, −ωz).

Fixes (format.md §5), each implemented here and nowhere else
-----------------------------------------------------------
1. Compass → yaw: CARLA's compass is ``yaw + π/2`` (0 = north = −y). CARLA yaw = θ − π/2, iso yaw = π/2 − θ.
   A NaN (or null) θ is a heading due south whose arccos rounded past −1: its true value is π.
2. Handedness: ``carla-*`` → ``iso`` by negating y (points, vectors) and yaw; ``F M F`` for transforms.
3. Extents are half sizes: full size = 2 · extent (``trigger_volume_extent`` too).
4. Walker speed is stored as 0: velocity from finite differences of consecutive ``center`` s
   (backward difference, forward difference on a clip's first frame), 10 Hz ⇒ dt = 0.1 s.
5. Static vehicles' ``location`` / ``rotation`` come from the prop, not the box: the box is built from
   ``center`` + ``extent`` with its orientation from inverse(``world2vehicle``) (all classes use ``center``
   and the inverse of their ``world2*`` matrix when present).
6. Dirt-debris props (``static.prop.dirtdebris*``) have x/y extents swapped: size = 2 · (ey, ex, ez).
7. Trigger volumes (stop signs lying on the ground have only these): a rectangle centred at
   ``trigger_volume_location`` with yaw ``trigger_volume_rotation[2]`` (already summed with the parent
   rotation by the released script; ``add_parent_rotation=True`` adds ``rotation[2]`` for data following
   docs/anno.md) and half extents ``trigger_volume_extent``.
8. Radar mounts: the released v0 collector mounted RADAR_BACK_RIGHT at yaw −90 (bug); always use the
   per-frame ``radar2ego`` of the annotation (falling back to the rig table only when it is missing).
9. GNSS ``x, y`` are noisy and taken at the GNSS mount: the exact ego pose is
   ``bounding_boxes[0].world2ego``. ``ego_to_world(anno, source="exact" | "gnss")`` offers both.
10. ``speed`` may be null: treated as 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from b2d_data.format.rig import RADARS_V0, camera
from b2d_data.format.transform import Location, Rotation, Transform, rotation_matrix

Frame = Literal["iso", "carla"]
PoseSource = Literal["exact", "gnss"]

#: Annotation frames are 10 Hz (format.md §1.3).
FRAME_DT = 0.1

#: diag(1, −1, 1, 1): the y flip between a left-handed CARLA frame and its right-handed twin (Zoo ``left2right``).
FLIP_Y = np.diag([1.0, -1.0, 1.0, 1.0])
#: OpenCV camera → UE camera axes (UE_x = cv_z, UE_y = cv_x, UE_z = −cv_y); Zoo ``stand_to_ue4_rotate``.
UE_FROM_OPENCV = np.array([[0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
#: UE camera → OpenCV camera axes.
OPENCV_FROM_UE = UE_FROM_OPENCV.T.copy()


# --------------------------------------------------------------------------------------------- handedness


def flip_y(points: np.ndarray) -> np.ndarray:
    """Negate the y column of (..., 2) or (..., 3) points/vectors: CARLA ↔ right-handed (a new array)."""
    arr = np.asarray(points)
    out = arr.astype(arr.dtype if arr.dtype.kind == "f" else np.float64, copy=True)
    out[..., 1] *= -1.0
    return out


def flip_y_matrix(m: np.ndarray) -> np.ndarray:
    """``F · M · F``: a 4×4 transform between CARLA-convention frames as one between right-handed frames."""
    return FLIP_Y @ np.asarray(m, dtype=np.float64) @ FLIP_Y


def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """Wrap radians to [−π, π)."""
    if isinstance(angle, np.ndarray):
        return np.mod(angle + math.pi, 2.0 * math.pi) - math.pi
    return float((angle + math.pi) % (2.0 * math.pi) - math.pi)


def carla_yaw_to_iso(yaw_rad: float | np.ndarray) -> float | np.ndarray:
    """A CARLA (clockwise) yaw in radians as an ISO (counter-clockwise) yaw: its negation, wrapped."""
    return wrap_angle(-yaw_rad)


def to_frame_points(points_carla: np.ndarray, frame: Frame) -> np.ndarray:
    """CARLA-convention points/vectors in the requested handedness (``carla`` returns them as float arrays)."""
    if frame == "iso":
        return flip_y(points_carla)
    arr = np.asarray(points_carla)
    return arr if arr.dtype.kind == "f" else arr.astype(np.float64)


def to_frame_matrix(m_carla: np.ndarray, frame: Frame) -> np.ndarray:
    """A 4×4 CARLA-convention transform in the requested handedness."""
    return flip_y_matrix(m_carla) if frame == "iso" else np.asarray(m_carla, dtype=np.float64)


def to_frame_yaw(yaw_carla: float | np.ndarray, frame: Frame) -> float | np.ndarray:
    """A CARLA yaw (radians) in the requested handedness, wrapped to [−π, π)."""
    return carla_yaw_to_iso(yaw_carla) if frame == "iso" else wrap_angle(yaw_carla)


def angular_velocity_to_frame(omega_carla: Sequence[float], frame: Frame) -> np.ndarray:
    """IMU angular velocity (rad/s) in the requested handedness: a pseudo-vector, so iso = (−ωx, ωy, −ωz)."""
    w = np.asarray(omega_carla, dtype=np.float64)
    return np.array([-w[0], w[1], -w[2]]) if frame == "iso" else w.copy()


# ------------------------------------------------------------------------------------------ compass, speed


def fix_theta(theta: float | None) -> float:
    """The IMU compass with its defect fixed: NaN or null ⇒ π (a heading due south, format.md §4.1)."""
    if theta is None:
        return math.pi
    theta = float(theta)
    return math.pi if math.isnan(theta) else theta


def compass_to_carla_yaw(theta: float | None) -> float:
    """CARLA (left-handed, clockwise) yaw in radians from the compass: θ − π/2, NaN θ counted as π."""
    return float(wrap_angle(fix_theta(theta) - math.pi / 2.0))


def compass_to_iso_yaw(theta: float | None) -> float:
    """ISO (right-handed, counter-clockwise) yaw in radians from the compass: π/2 − θ, NaN θ counted as π."""
    return float(wrap_angle(math.pi / 2.0 - fix_theta(theta)))


def fix_speed(speed: float | None) -> float:
    """The speedometer value with its defect fixed: null (or NaN) ⇒ 0 m/s."""
    if speed is None:
        return 0.0
    speed = float(speed)
    return 0.0 if math.isnan(speed) else speed


# -------------------------------------------------------------------------------------------------- poses


def exact_ego_to_world(anno: dict) -> np.ndarray:
    """Exact ego → CARLA-world 4×4 pose: inverse of ``bounding_boxes[0].world2ego``."""
    return np.linalg.inv(np.asarray(anno["bounding_boxes"][0]["world2ego"], dtype=np.float64))


def gnss_ego_to_world(anno: dict) -> np.ndarray:
    """Ego → CARLA-world pose as a test-time agent sees it: GNSS ``x, y`` and compass yaw (roll = pitch = 0).

    z is taken from the ego box when present (the annotation has no GNSS altitude), else 0.
    """
    yaw_deg = math.degrees(compass_to_carla_yaw(anno.get("theta")))
    z = 0.0
    boxes = anno.get("bounding_boxes") or []
    if boxes and "location" in boxes[0]:
        z = float(boxes[0]["location"][2])
    return Transform(Location(float(anno["x"]), float(anno["y"]), z), Rotation(yaw=yaw_deg)).matrix()


def ego_to_world(anno: dict, source: PoseSource = "exact") -> np.ndarray:
    """Ego → CARLA-world 4×4 pose from the exact ego box (``exact``) or from GNSS + compass (``gnss``)."""
    if source == "exact":
        return exact_ego_to_world(anno)
    if source == "gnss":
        return gnss_ego_to_world(anno)
    raise ValueError(f"unknown pose source {source!r}; use 'exact' or 'gnss'")


def yaw_of(m: np.ndarray) -> float:
    """Heading (radians, in the matrix's own convention) of a 4×4 or 3×3 rotation: atan2(R10, R00)."""
    m = np.asarray(m, dtype=np.float64)
    return math.atan2(m[1, 0], m[0, 0])


def world_points_to_ego(points_world: np.ndarray, world2ego: np.ndarray, frame: Frame = "iso") -> np.ndarray:
    """(N, 2|3) CARLA-world points into the ego frame (2-D points are taken at the ego's height)."""
    pts = np.asarray(points_world, dtype=np.float64)
    if pts.size == 0:
        return np.zeros(pts.shape, dtype=np.float64)
    world2ego = np.asarray(world2ego, dtype=np.float64)
    two_d = pts.shape[-1] == 2
    if two_d:
        ego_z = np.linalg.inv(world2ego)[2, 3]
        pts = np.concatenate([pts, np.full(pts.shape[:-1] + (1,), ego_z)], axis=-1)
    out = pts @ world2ego[:3, :3].T + world2ego[:3, 3]
    out = to_frame_points(out, frame)
    return out[..., :2] if two_d else out


def world_vectors_to_ego(vectors_world: np.ndarray, world2ego: np.ndarray, frame: Frame = "iso") -> np.ndarray:
    """(N, 2|3) CARLA-world vectors (velocities) rotated into the ego frame (no translation)."""
    v = np.asarray(vectors_world, dtype=np.float64)
    if v.size == 0:
        return np.zeros(v.shape, dtype=np.float64)
    r = np.asarray(world2ego, dtype=np.float64)[:3, :3]
    two_d = v.shape[-1] == 2
    if two_d:
        v = np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], axis=-1)
    out = to_frame_points(v @ r.T, frame)
    return out[..., :2] if two_d else out


def relative_pose(ego2world_from: np.ndarray, ego2world_to: np.ndarray, frame: Frame = "iso") -> np.ndarray:
    """The pose of ego ``to`` seen from ego ``from`` (4×4), in the requested handedness."""
    rel = np.linalg.inv(np.asarray(ego2world_from, dtype=np.float64)) @ np.asarray(ego2world_to, dtype=np.float64)
    return to_frame_matrix(rel, frame)


def gnss_xy_in_ego(anno: dict, frame: Frame = "iso") -> np.ndarray:
    """Where the GNSS ``x, y`` lies in the exact ego frame (2,): shows the GNSS mount offset and noise."""
    world2ego = np.asarray(anno["bounding_boxes"][0]["world2ego"], dtype=np.float64)
    return world_points_to_ego(np.array([[float(anno["x"]), float(anno["y"])]]), world2ego, frame)[0]


# ------------------------------------------------------------------------------------------------ sensors


def cam_to_ego(cam2ego_ue: np.ndarray, frame: Frame = "iso") -> np.ndarray:
    """OpenCV camera → ego 4×4 from an annotation ``cam2ego`` (UE camera → CARLA ego)."""
    m = np.asarray(cam2ego_ue, dtype=np.float64) @ UE_FROM_OPENCV
    return FLIP_Y @ m if frame == "iso" else m


def sensor_to_ego(x2ego: np.ndarray, frame: Frame = "iso") -> np.ndarray:
    """A LiDAR/radar ``X2ego`` (UE sensor → CARLA ego) with both frames in the requested handedness."""
    return to_frame_matrix(x2ego, frame)


def camera_intrinsic(anno: dict, sensor_id: str, width: int | None = None, height: int | None = None) -> np.ndarray:
    """3×3 K of a camera from the annotation (``sensors[id].intrinsic``), else from the rig table."""
    entry = (anno.get("sensors") or {}).get(sensor_id)
    if entry is not None and entry.get("intrinsic") is not None:
        return np.asarray(entry["intrinsic"], dtype=np.float64)
    return camera(sensor_id).intrinsic(width, height)


def camera_cam2ego(anno: dict, sensor_id: str, frame: Frame = "iso") -> np.ndarray:
    """OpenCV camera → ego 4×4 of a camera, from the annotation's ``cam2ego`` (else the rig mount)."""
    entry = (anno.get("sensors") or {}).get(sensor_id)
    if entry is not None and entry.get("cam2ego") is not None:
        cam2ego = np.asarray(entry["cam2ego"], dtype=np.float64)
    else:
        mount = camera(sensor_id).mount
        cam2ego = Transform(
            Location(mount.x, mount.y, mount.z), Rotation(pitch=mount.pitch, yaw=mount.yaw, roll=mount.roll)
        ).matrix()
    return cam_to_ego(cam2ego, frame)


def radar_to_ego_matrix(anno: dict, sensor_id: str) -> np.ndarray:
    """CARLA ``radar2ego`` of a radar from the annotation (fix 8); the v0 rig mount only when it is missing."""
    entry = (anno.get("sensors") or {}).get(sensor_id)
    if entry is not None and entry.get("radar2ego") is not None:
        return np.asarray(entry["radar2ego"], dtype=np.float64)
    for spec in RADARS_V0:
        if spec.sensor_id == sensor_id:
            m = spec.mount
            return Transform(Location(m.x, m.y, m.z), Rotation(pitch=m.pitch, yaw=m.yaw, roll=m.roll)).matrix()
    raise KeyError(f"unknown radar {sensor_id!r}")


def radar_detections_to_points(detections: np.ndarray) -> np.ndarray:
    """(N, 4) radar rows [depth m, altitude rad, azimuth rad, velocity] → (N, 3) points in the radar's UE frame.

    A detection lies along the radar's forward axis rotated by pitch = altitude and yaw = azimuth (CARLA's
    own radar example), so x = d·cos(alt)·cos(az), y = d·cos(alt)·sin(az), z = d·sin(alt).
    """
    det = np.asarray(detections, dtype=np.float64).reshape(-1, 4)
    depth, alt, az = det[:, 0], det[:, 1], det[:, 2]
    return np.stack([depth * np.cos(alt) * np.cos(az), depth * np.cos(alt) * np.sin(az), depth * np.sin(alt)], axis=1)


def radar_detections_to_ego(detections: np.ndarray, radar2ego: np.ndarray, frame: Frame = "iso") -> np.ndarray:
    """(N, 4) radar rows → (N, 3) points in the ego frame through the per-frame ``radar2ego``."""
    pts = radar_detections_to_points(detections)
    m = np.asarray(radar2ego, dtype=np.float64)
    return to_frame_points(pts @ m[:3, :3].T + m[:3, 3], frame)


# -------------------------------------------------------------------------------------------------- boxes

#: Keys holding an object's world → object matrix, by annotation class.
_WORLD2OBJECT_KEYS = ("world2vehicle", "world2ped", "world2sign", "world2ego")


def half_to_full(extent: Sequence[float]) -> np.ndarray:
    """Full sizes from CARLA half extents (fix 3): 2 · extent."""
    return 2.0 * np.asarray(extent, dtype=np.float64)


def is_dirt_debris(box: dict) -> bool:
    """True for the ``static.prop.dirtdebris*`` props whose x/y extents are swapped (fix 6)."""
    return "dirtdebris" in str(box.get("type_id", "")).lower()


def box_size(box: dict) -> np.ndarray:
    """(length, width, height) of a box entry in metres: doubled half extents, dirt debris unswapped."""
    ex, ey, ez = (float(v) for v in box["extent"])
    if is_dirt_debris(box):
        ex, ey = ey, ex
    return np.array([2.0 * ex, 2.0 * ey, 2.0 * ez])


def _world2object(box: dict) -> Any:
    """The entry's ``world2*`` matrix where it orients the box, else None.

    A sign with a trigger volume takes ``rotation``, ``center`` and ``extent`` from the level bounding box its actor
    was matched to, while ``world2sign`` is the actor's transform, which CARLA's sign actors (and ours: the landmark
    turned 90°) hold at another yaw than their plates: the box is oriented by ``rotation`` there.
    """
    for key in _WORLD2OBJECT_KEYS:
        if box.get(key) is not None:
            if key == "world2sign" and box.get("trigger_volume_extent") is not None:
                return None
            return box[key]
    return None


def object_to_world(box: dict) -> np.ndarray:
    """Object → CARLA-world 4×4 of a box entry: inverse(``world2*``) when present (fix 5), else its rotation
    (always for trigger-volume signs, whose ``world2sign`` is the actor's pose, not the box's).

    The translation is the box ``center`` (the bounding-box centre in the world, not the actor origin).
    """
    m = None
    world2object = _world2object(box)
    if world2object is not None:
        m = np.linalg.inv(np.asarray(world2object, dtype=np.float64))
    if m is None:
        pitch, roll, yaw = (float(v) for v in box.get("rotation", (0.0, 0.0, 0.0)))
        m = np.eye(4)
        m[:3, :3] = rotation_matrix(pitch, yaw, roll)
    out = m.copy()
    center = box.get("center", box.get("location"))
    out[:3, 3] = np.asarray(center, dtype=np.float64)[:3]
    return out


def box_in_ego(box: dict, world2ego: np.ndarray, frame: Frame = "iso") -> np.ndarray:
    """A box entry as (7,) [x, y, z, l, w, h, yaw] in the ego frame: centre, full size, heading about z."""
    obj2world = object_to_world(box)
    rel = np.asarray(world2ego, dtype=np.float64) @ obj2world
    yaw = to_frame_yaw(yaw_of(rel), frame)
    centre = to_frame_points(rel[:3, 3], frame)
    return np.concatenate([centre, box_size(box), [yaw]])


def rigid_inverse(m: np.ndarray) -> np.ndarray:
    """Inverse of one (4, 4) or a stack of (..., 4, 4) rigid transforms: [Rᵀ, −Rᵀt] (cheaper than a general inverse)."""
    m = np.asarray(m, dtype=np.float64)
    out = np.zeros_like(m)
    rt = np.swapaxes(m[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rt, m[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def objects_to_world(boxes: Sequence[dict]) -> np.ndarray:
    """(M, 4, 4) object → CARLA-world poses of many box entries at once (same rules as :func:`object_to_world`)."""
    out = np.zeros((len(boxes), 4, 4))
    matrices = [_world2object(b) for b in boxes]
    have = [i for i, m in enumerate(matrices) if m is not None]
    if have:
        out[have] = rigid_inverse(np.array([matrices[i] for i in have], np.float64))
    have_set = set(have)
    for i, b in enumerate(boxes):
        if i not in have_set:
            pitch, roll, yaw = (float(v) for v in b.get("rotation", (0.0, 0.0, 0.0)))
            out[i, :3, :3] = rotation_matrix(pitch, yaw, roll)
            out[i, 3, 3] = 1.0
        out[i, :3, 3] = np.asarray(b.get("center", b.get("location")), dtype=np.float64)[:3]
    return out


def boxes_in_ego(boxes: Sequence[dict], world2ego: np.ndarray, frame: Frame = "iso") -> tuple[np.ndarray, np.ndarray]:
    """Many box entries at once: (M, 7) [x, y, z, l, w, h, yaw] in the ego frame and their (M, 4, 4) object → world.

    Equals :func:`box_in_ego` per box (fixes 3, 5, 6); returns the poses too so velocities need no second pass.
    """
    if not boxes:
        return np.zeros((0, 7)), np.zeros((0, 4, 4))
    obj2world = objects_to_world(boxes)
    rel = np.asarray(world2ego, dtype=np.float64) @ obj2world
    yaw = to_frame_yaw(np.arctan2(rel[:, 1, 0], rel[:, 0, 0]), frame)
    centre = to_frame_points(rel[:, :3, 3], frame)
    sizes = np.array([box_size(b) for b in boxes])
    return np.concatenate([centre, sizes, np.asarray(yaw)[:, None]], axis=1), obj2world


def box_corners(box7: np.ndarray) -> np.ndarray:
    """(8, 3) corners of a [x, y, z, l, w, h, yaw] box (yaw about +z of the box's own frame convention)."""
    x, y, z, length, width, height, yaw = (float(v) for v in box7)
    signs = np.array([(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)], dtype=np.float64)
    local = signs * np.array([length, width, height]) / 2.0
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return local @ rot.T + np.array([x, y, z])


def forward_velocity_world(box: dict) -> np.ndarray:
    """CARLA-world velocity (3,) of a vehicle from its signed forward ``speed`` along its heading."""
    forward = object_to_world(box)[:3, 0]
    return fix_speed(box.get("speed")) * forward


def finite_difference_velocity(
    center_now: Sequence[float], center_other: Sequence[float], dt: float = FRAME_DT
) -> np.ndarray:
    """World velocity (3,) from two box centres ``dt`` seconds apart (fix 4): (now − other) / dt.

    Pass the previous frame's centre with ``dt = 0.1``, or the next frame's with ``dt = −0.1``.
    """
    return (np.asarray(center_now, dtype=np.float64) - np.asarray(center_other, dtype=np.float64)) / dt


def trusts_stored_speed(box: dict) -> bool:
    """Whether a box's stored ``speed`` is meaningful: only vehicles (walkers' speed is always 0)."""
    return "vehicle" in str(box.get("class", ""))


# -------------------------------------------------------------------------------------- trigger volumes


def trigger_volume_corners(box: dict, add_parent_rotation: bool = False) -> np.ndarray:
    """(4, 3) CARLA-world corners of a light/sign trigger volume (fix 7), counter-clockwise in CARLA axes.

    Corner order in the volume frame: (+ex, +ey), (−ex, +ey), (−ex, −ey), (+ex, −ey); z = volume centre.
    """
    cx, cy, cz = (float(v) for v in box["trigger_volume_location"])
    ex, ey = (float(v) for v in box["trigger_volume_extent"][:2])
    yaw_deg = float(box["trigger_volume_rotation"][2])
    if add_parent_rotation:
        yaw_deg = (yaw_deg + float(box["rotation"][2])) % 360.0
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    local = np.array([[ex, ey], [-ex, ey], [-ex, -ey], [ex, -ey]])
    xy = local @ np.array([[c, -s], [s, c]]).T + np.array([cx, cy])
    return np.concatenate([xy, np.full((4, 1), cz)], axis=1)


def trigger_volume_in_ego(
    box: dict, world2ego: np.ndarray, frame: Frame = "iso", add_parent_rotation: bool = False
) -> np.ndarray:
    """A trigger volume as (7,) [x, y, z, l, w, h, yaw] in the ego frame (full sizes)."""
    yaw_deg = float(box["trigger_volume_rotation"][2])
    if add_parent_rotation:
        yaw_deg = (yaw_deg + float(box["rotation"][2])) % 360.0
    m = Transform(Location.from_array(box["trigger_volume_location"]), Rotation(yaw=yaw_deg)).matrix()
    rel = np.asarray(world2ego, dtype=np.float64) @ m
    return np.concatenate(
        [
            to_frame_points(rel[:3, 3], frame),
            half_to_full(box["trigger_volume_extent"]),
            [to_frame_yaw(yaw_of(rel), frame)],
        ]
    )


# ------------------------------------------------------------------------ Bench2DriveZoo (UniAD/VAD) frame

#: Zoo ``left2right``.
ZOO_LEFT2RIGHT = FLIP_Y
#: Zoo ``stand_to_ue4_rotate`` (OpenCV → UE camera axes).
ZOO_STAND_TO_UE4 = UE_FROM_OPENCV
#: Zoo ``lidar_to_righthand_ego``: zoo-lidar axes → right-handed ego axes (ego_x = lidar_y, ego_y = −lidar_x).
ZOO_LIDAR_TO_RIGHTHAND_EGO = np.array(
    [[0.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
#: Zoo ``lefthand_ego_to_lidar``: swaps x and y (lidar_x = CARLA-ego right, lidar_y = forward).
ZOO_LEFTHAND_EGO_TO_LIDAR = np.array(
    [[0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)


def zoo_ego_yaw(theta: float | None) -> float:
    """Zoo ``ego_yaw`` = π/2 − nan_to_num(θ, nan=π) (not wrapped, as prepare_B2D stores it)."""
    return math.pi / 2.0 - fix_theta(theta)


def zoo_ego_translation(anno: dict) -> np.ndarray:
    """Zoo ``ego_translation`` = (x, −y, 0) from the GNSS ``x, y``."""
    return np.array([float(anno["x"]), -float(anno["y"]), 0.0])


def zoo_world2ego(world2ego: np.ndarray) -> np.ndarray:
    """Zoo ``world2ego`` = left2right · world2ego · left2right."""
    return flip_y_matrix(world2ego)


def zoo_cam2ego(cam2ego: np.ndarray) -> np.ndarray:
    """Zoo ``cam2ego`` = left2right · cam2ego · stand_to_ue4_rotate (OpenCV camera → right-handed ego)."""
    return FLIP_Y @ np.asarray(cam2ego, dtype=np.float64) @ UE_FROM_OPENCV


def zoo_world2cam(world2cam: np.ndarray) -> np.ndarray:
    """Zoo ``world2cam`` = inverse(stand_to_ue4_rotate) · world2cam · left2right (right-handed world → OpenCV)."""
    return OPENCV_FROM_UE @ np.asarray(world2cam, dtype=np.float64) @ FLIP_Y


def zoo_lidar2ego(lidar2ego: np.ndarray) -> np.ndarray:
    """Zoo ``lidar2ego`` = left2right · lidar2ego · left2right · lidar_to_righthand_ego."""
    return flip_y_matrix(lidar2ego) @ ZOO_LIDAR_TO_RIGHTHAND_EGO


def zoo_world2lidar(world2lidar: np.ndarray) -> np.ndarray:
    """Zoo ``world2lidar`` = lefthand_ego_to_lidar · world2lidar · left2right."""
    return ZOO_LEFTHAND_EGO_TO_LIDAR @ np.asarray(world2lidar, dtype=np.float64) @ FLIP_Y


def zoo_box_size(extent: Sequence[float]) -> np.ndarray:
    """Zoo box size (w, l, h) = 2 · (ey, ex, ez)."""
    ex, ey, ez = (float(v) for v in extent)
    return np.array([2.0 * ey, 2.0 * ex, 2.0 * ez])


def zoo_lidar_box_yaw(yaw_local: float) -> float:
    """Zoo ``yaw_local_in_lidar_box`` = −yaw_local − π/2 (mmdet3d LiDAR-box convention)."""
    return -yaw_local - math.pi / 2.0


def zoo_ego_accel(acceleration: Sequence[float]) -> np.ndarray:
    """Zoo ``ego_accel`` = (ax, −ay, az)."""
    a = np.asarray(acceleration, dtype=np.float64)
    return np.array([a[0], -a[1], a[2]])


def zoo_ego_rotation_rate(angular_velocity: Sequence[float]) -> np.ndarray:
    """Zoo ``ego_rotation_rate`` = −ω (all three negated; :func:`angular_velocity_to_frame` keeps ωy)."""
    return -np.asarray(angular_velocity, dtype=np.float64)


def zoo_walker_speed(center_now: Sequence[float], center_prev: Sequence[float]) -> float:
    """Zoo's speed of a non-vehicle: 2-D displacement between consecutive frames × 10 (m/s, unsigned)."""
    d = np.asarray(center_now, dtype=np.float64)[:2] - np.asarray(center_prev, dtype=np.float64)[:2]
    return float(np.linalg.norm(d) * 10.0)


def iso_to_zoo_lidar(points_iso: np.ndarray, lidar2ego_carla: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) ISO-ego points into Zoo's LiDAR frame (x right, y forward, z up at the mount)."""
    if lidar2ego_carla is None:
        lidar2ego_carla = Transform(Location(-0.39, 0.0, 1.84)).matrix()
    lidar2ego = zoo_lidar2ego(lidar2ego_carla)
    ego2lidar = np.linalg.inv(lidar2ego)
    pts = np.asarray(points_iso, dtype=np.float64)
    return pts @ ego2lidar[:3, :3].T + ego2lidar[:3, 3]
