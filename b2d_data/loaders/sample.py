"""Turn one frame's annotation (plus the clip's pose track) into sample fields; every conversion goes via coords."""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from b2d_data import coords
from b2d_data.coords import Frame, PoseSource
from b2d_data.format.rig import CAMERAS, camera

#: ``box_classes`` values index this tuple (the annotation's ``class``).
BOX_CLASSES: tuple[str, ...] = ("vehicle", "walker", "traffic_light", "traffic_sign")
_BOX_CLASS_ID = {name: i for i, name in enumerate(BOX_CLASSES)}
#: ``trigger_types`` values index this tuple.
TRIGGER_TYPES: tuple[str, ...] = ("traffic_light", "stop_sign", "other_sign")

SURROUND: tuple[str, ...] = tuple(c.folder for c in CAMERAS)

OnError = Literal["raise", "skip"]


@dataclass(frozen=True)
class SampleOptions:
    """What a sample holds and in which frame (see ``ClipDataset`` for the keys each option adds)."""

    cameras: tuple[str, ...] = SURROUND  # camera folder names (``front`` …) or sensor ids (``CAM_FRONT``)
    lidar: bool = True
    radar: bool = False
    boxes: bool = True
    depth: bool = False
    semantic: bool = False
    instance: bool = False
    expert: bool = False
    expert_bev: bool = False  # reshape the expert feature to (6, 16, 16); only for clips whose record says so
    map_radius: float | None = None  # metres; None = no map elements
    future_steps: int = 6
    past_steps: int = 4
    waypoint_stride: int = 5  # frames between waypoints (5 = 0.5 s at 10 Hz)
    frame: Frame = "iso"  # "iso": right-handed ISO 8855 ego frame; "carla": CARLA's left-handed ego frame
    pose_source: PoseSource = "exact"  # ego pose for waypoints/targets: exact ego box, or GNSS + compass
    keep_anno: bool = False  # add the raw annotation dict under ``anno``
    box_max_distance: float | None = None  # drop boxes farther (2-D) than this
    box_max_dz: float | None = 10.0  # drop boxes whose centre is this far above/below the ego (sky/underground)
    walker_velocity: bool = True  # finite differences for walkers (reads the neighbouring annotation)
    trigger_add_parent_rotation: bool = False  # see coords fix 7
    float_depth: bool = True  # prefer ``depth_<cam>/NNNNN.npz`` (v0.0.4) over the uint8 PNG when present
    extra: dict = field(default_factory=dict, compare=False)

    def camera_folders(self) -> tuple[str, ...]:
        """The chosen cameras as folder names."""
        return tuple(camera(c).folder for c in self.cameras)


def actor_id(value: object) -> int:
    """A box ``id`` (a string in the annotation) as an int64; non-numeric ids get a stable CRC32."""
    try:
        return int(str(value))
    except ValueError:
        return zlib.crc32(str(value).encode()) & 0x7FFFFFFF


def ego_fields(anno: dict, frame: Frame) -> dict[str, np.ndarray]:
    """Ego state: exact pose, speed, IMU vectors, size, compass yaw, GNSS offset and controls."""
    ego2world = coords.exact_ego_to_world(anno)
    ego_box = anno["bounding_boxes"][0]
    compass_yaw = (
        coords.compass_to_iso_yaw(anno.get("theta"))
        if frame == "iso"
        else coords.compass_to_carla_yaw(anno.get("theta"))
    )
    return {
        "ego_pose": coords.to_frame_matrix(ego2world, frame),
        "ego_speed": np.float32(coords.fix_speed(anno.get("speed"))),
        "ego_accel": coords.to_frame_points(np.asarray(anno.get("acceleration", (0, 0, 0)), np.float64), frame).astype(
            np.float32
        ),
        "ego_angular_velocity": coords.angular_velocity_to_frame(anno.get("angular_velocity", (0, 0, 0)), frame).astype(
            np.float32
        ),
        "ego_size": coords.box_size(ego_box).astype(np.float32),
        "ego_compass_yaw": np.float32(compass_yaw),
        "ego_gnss_xy": coords.gnss_xy_in_ego(anno, frame).astype(np.float32),
        "control": np.array(
            [
                float(anno.get("throttle") or 0.0),
                float(anno.get("steer") or 0.0),
                float(anno.get("brake") or 0.0),
                float(bool(anno.get("reverse"))),
            ],
            np.float32,
        ),  # fmt: skip
        "should_brake": np.bool_(bool(anno.get("should_brake"))),
        "only_ap_brake": np.bool_(bool(anno.get("only_ap_brake"))),
    }


def reference_world2ego(anno: dict, source: PoseSource) -> np.ndarray:
    """World → ego (CARLA) for route targets: exact pose, or GNSS + compass as at test time."""
    return np.linalg.inv(coords.ego_to_world(anno, source))


def command_fields(anno: dict, world2ego: np.ndarray, frame: Frame) -> dict[str, np.ndarray]:
    """Route commands (RoadOption ints) and their target points in the ego frame."""

    def xy(kx: str, ky: str) -> np.ndarray:
        if anno.get(kx) is None or anno.get(ky) is None:
            return np.full(2, np.nan, np.float32)
        pt = np.array([[float(anno[kx]), float(anno[ky])]])
        return coords.world_points_to_ego(pt, world2ego, frame)[0].astype(np.float32)

    def cmd(key: str) -> np.int64:
        value = anno.get(key)
        return np.int64(-1 if value is None else int(value))

    return {
        "command": cmd("next_command"),
        "target_point": xy("x_target", "y_target"),
        "command_near": cmd("command_near"),
        "command_near_xy": xy("x_command_near", "y_command_near"),
        "command_far": cmd("command_far"),
        "command_far_xy": xy("x_command_far", "y_command_far"),
    }


def pose_track(poses: dict[str, np.ndarray], source: PoseSource) -> np.ndarray:
    """(F, 3) [x, y, yaw] CARLA-world ego track of a clip from the index pose columns."""
    if source == "exact":
        return np.stack([poses["ego_x"], poses["ego_y"], poses["ego_yaw"]], axis=1)
    theta = np.where(np.isnan(poses["theta"]), math.pi, poses["theta"])  # coords fix 1, vectorised
    return np.stack([poses["gnss_x"], poses["gnss_y"], theta - math.pi / 2.0], axis=1)


def waypoint_fields(track: np.ndarray, pos: int, opts: SampleOptions) -> dict[str, np.ndarray]:
    """Past and future ego waypoints (K, 2) and yaws (K,) in the current ego frame, with validity masks.

    ``track`` is the clip's (F, 3) [x, y, yaw] CARLA-world track, ``pos`` the current frame's position in it.
    Future waypoint k (1-based) is ``pos + k·stride``; past ones are ``pos − k·stride``, listed oldest first.
    Positions beyond the clip repeat the last valid pose and are flagged invalid.
    """
    n = len(track)
    x0, y0, yaw0 = track[pos]
    c, s = math.cos(yaw0), math.sin(yaw0)

    def block(offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        idx = pos + offsets
        valid = (idx >= 0) & (idx < n)
        idx = np.clip(idx, 0, n - 1)
        pts = track[idx]
        valid &= np.isfinite(pts).all(axis=1)
        dx, dy = pts[:, 0] - x0, pts[:, 1] - y0
        local = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=1)  # CARLA ego axes (x fwd, y right)
        yaw = coords.wrap_angle(pts[:, 2] - yaw0)
        if opts.frame == "iso":
            local[:, 1] *= -1.0
            yaw = -yaw
        return local.astype(np.float32), np.asarray(yaw, np.float32), valid

    stride = opts.waypoint_stride
    fut = np.arange(1, opts.future_steps + 1) * stride
    past = -np.arange(opts.past_steps, 0, -1) * stride
    f_xy, f_yaw, f_ok = block(fut)
    p_xy, p_yaw, p_ok = block(past)
    return {
        "future_waypoints": f_xy, "future_yaw": f_yaw, "future_valid": f_ok,
        "past_waypoints": p_xy, "past_yaw": p_yaw, "past_valid": p_ok,
    }  # fmt: skip


def _light_state(box: dict) -> int:
    state = box.get("state")
    if isinstance(state, (int, float)) and not isinstance(state, bool):
        return int(state)
    return -1


def _trigger_type(box: dict) -> int:
    if box.get("class") == "traffic_light":
        return 0
    return 1 if "stop" in str(box.get("type_id", "")).lower() else 2


def box_fields(
    anno: dict,
    world2ego: np.ndarray,
    opts: SampleOptions,
    neighbour: dict | None = None,
    neighbour_dt: float = coords.FRAME_DT,
) -> dict[str, np.ndarray]:
    """3-D boxes (M, 7) [x, y, z, l, w, h, yaw] in the ego frame with classes, ids, velocities and triggers.

    Velocities (M, 2) are ground velocities expressed in the ego axes: vehicles from their stored forward
    speed, walkers by finite differences against ``neighbour`` (the previous annotation with
    ``neighbour_dt = 0.1``, or the next one with ``−0.1``), everything else 0.
    """
    frame = opts.frame
    ego_z = float(coords.rigid_inverse(world2ego)[2, 3])
    neighbour_centres: dict[object, list[float]] = {}
    if neighbour is not None:
        neighbour_centres = {b.get("id"): b["center"] for b in neighbour.get("bounding_boxes", []) if "center" in b}
    triggers, trigger_types, trigger_states, trigger_affects = [], [], [], []
    kept: list[dict] = []
    for box in anno["bounding_boxes"]:
        cls = box.get("class")
        if cls not in _BOX_CLASS_ID:
            continue  # the ego itself
        if "trigger_volume_location" in box:
            triggers.append(coords.trigger_volume_in_ego(box, world2ego, frame, opts.trigger_add_parent_rotation))
            trigger_types.append(_trigger_type(box))
            trigger_states.append(_light_state(box))
            trigger_affects.append(bool(box.get("affects_ego")))
        centre_z = float(box.get("center", box.get("location"))[2])
        if opts.box_max_dz is not None and abs(centre_z - ego_z) > opts.box_max_dz:
            continue
        kept.append(box)
    b7, obj2world = coords.boxes_in_ego(kept, world2ego, frame)
    if opts.box_max_distance is not None and len(kept):
        near = np.hypot(b7[:, 0], b7[:, 1]) <= opts.box_max_distance
        kept = [b for b, ok in zip(kept, near, strict=True) if ok]
        b7, obj2world = b7[near], obj2world[near]
    v_world = np.zeros((len(kept), 3))
    for i, box in enumerate(kept):
        if coords.trusts_stored_speed(box):
            v_world[i] = coords.fix_speed(box.get("speed")) * obj2world[i, :3, 0]  # along the box's forward axis
        elif box.get("class") == "walker" and box.get("id") in neighbour_centres:
            v_world[i] = coords.finite_difference_velocity(
                obj2world[i, :3, 3], neighbour_centres[box.get("id")], neighbour_dt
            )
    boxes = b7
    classes = [_BOX_CLASS_ID[b["class"]] for b in kept]
    ids = [actor_id(b.get("id")) for b in kept]
    vels = coords.world_vectors_to_ego(v_world, world2ego, frame)[:, :2] if len(kept) else np.zeros((0, 2))
    npts = [int(b.get("num_points", -1)) for b in kept]
    states = [_light_state(b) for b in kept]
    statics = [b.get("state") == "static" or b.get("class") in ("traffic_light", "traffic_sign") for b in kept]
    return {
        "boxes": np.array(boxes, np.float32).reshape(-1, 7),
        "box_classes": np.array(classes, np.int64),
        "box_ids": np.array(ids, np.int64),
        "box_velocity": np.array(vels, np.float32).reshape(-1, 2),
        "box_num_points": np.array(npts, np.int32),
        "box_light_state": np.array(states, np.int8),
        "box_static": np.array(statics, bool),
        "trigger_volumes": np.array(triggers, np.float32).reshape(-1, 7),
        "trigger_types": np.array(trigger_types, np.int64),
        "trigger_light_state": np.array(trigger_states, np.int8),
        "trigger_affects_ego": np.array(trigger_affects, bool),
    }


def project_points(points_ego: np.ndarray, cam2ego: np.ndarray, intrinsic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (N, 2) and depths (N,) of ego-frame points in a camera (``cam2ego`` from the same sample)."""
    ego2cam = np.linalg.inv(np.asarray(cam2ego, np.float64))
    pts = np.asarray(points_ego, np.float64) @ ego2cam[:3, :3].T + ego2cam[:3, 3]
    depth = pts[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (pts @ np.asarray(intrinsic, np.float64).T)[:, :2] / depth[:, None]
    return uv, depth
