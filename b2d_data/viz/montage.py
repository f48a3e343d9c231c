"""PNG montages of one frame: the six cameras (nuScenes arrangement), the top-down view and a LiDAR bird's-eye view,
with 3D boxes drawn into every camera and onto the LiDAR view. Pure numpy / OpenCV drawing.

Frames follow Bench2Drive (format.md §4): boxes and LiDAR points in the left-handed CARLA ego frame (x forward,
y right, z up); ``cam2ego`` maps the camera's UE axes (x forward, y right, z up) to the ego frame and K projects
OpenCV camera coordinates, which are the UE axes reordered as (y, −z, x).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from b2d_data.format.weather import WeatherParameters

#: Camera order of the montage: front row, then back row (nuScenes arrangement).
CAMERA_GRID: tuple[tuple[str, ...], tuple[str, ...]] = (
    ("front_left", "front", "front_right"),
    ("back_left", "back", "back_right"),
)
#: The 12 box edges of format.md §3.3 over the ``world_cord`` corner order.
BOX_EDGES: tuple[tuple[int, int], ...] = (
    (0, 1), (1, 3), (3, 2), (2, 0), (0, 4), (4, 5), (5, 1), (5, 7), (7, 6), (6, 4), (6, 2), (7, 3),
)  # fmt: skip
_BOX_COLOR = (255, 160, 0)
_EGO_COLOR = (0, 200, 255)
_NEAR = 0.1


def _label(img: np.ndarray, text: str) -> None:
    cv2.putText(img, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(img, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)


def project_boxes(
    image: np.ndarray,
    boxes_ego: np.ndarray,
    k: np.ndarray,
    cam2ego: np.ndarray,
    scale: float = 1.0,
    colors: Sequence[tuple[int, int, int]] | None = None,
) -> None:
    """Draw (M, 8, 3) ego-frame boxes into ``image`` (in place); edges are clipped at the camera's near plane.

    ``scale`` maps the pixel coordinates K gives to the (resized) image.
    """
    if len(boxes_ego) == 0:
        return
    ego2cam = np.linalg.inv(np.asarray(cam2ego, np.float64))
    pts = np.asarray(boxes_ego, np.float64).reshape(-1, 3)
    ue = pts @ ego2cam[:3, :3].T + ego2cam[:3, 3]
    cv = np.stack([ue[:, 1], -ue[:, 2], ue[:, 0]], axis=1).reshape(-1, 8, 3)
    h, w = image.shape[:2]
    for m, corners in enumerate(cv):
        color = colors[m] if colors is not None else _BOX_COLOR
        for a, b in BOX_EDGES:
            p, q = corners[a].copy(), corners[b].copy()
            if p[2] < _NEAR and q[2] < _NEAR:
                continue
            # Clip the edge where it crosses the near plane so half-visible boxes still draw.
            if p[2] < _NEAR:
                p = q + (p - q) * (q[2] - _NEAR) / (q[2] - p[2])
            elif q[2] < _NEAR:
                q = p + (q - p) * (p[2] - _NEAR) / (p[2] - q[2])
            uv = []
            for c in (p, q):
                pix = k @ c
                uv.append(pix[:2] / pix[2] * scale)
            (x0, y0), (x1, y1) = uv
            if max(abs(x0), abs(y0), abs(x1), abs(y1)) > 1e5:
                continue
            ok, p0, p1 = cv2.clipLine((0, 0, w, h), (int(round(x0)), int(round(y0))), (int(round(x1)), int(round(y1))))
            if ok:
                cv2.line(image, p0, p1, color, 2, cv2.LINE_AA)


def lidar_bev(
    points_ego: np.ndarray,
    boxes_ego: np.ndarray,
    size: int = 640,
    half_range: float = 50.0,
    colors: Sequence[tuple[int, int, int]] | None = None,
    ego_half_extent: tuple[float, float] = (2.45, 1.06),
) -> np.ndarray:
    """Bird's-eye view of ego-frame points (forward up, right to the right) with box footprints, RGB uint8."""
    img = np.zeros((size, size, 3), np.uint8)
    res = 2.0 * half_range / size
    c = size / 2.0
    p = np.asarray(points_ego, np.float64).reshape(-1, 3)
    col = (c + p[:, 1] / res).astype(np.int64)
    row = (c - p[:, 0] / res).astype(np.int64)
    ok = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    # Colour by height above the ego origin: ground blue-green, cars yellow-red, tall things red.
    if ok.any():
        z = np.clip((p[ok, 2] + 0.3) / 3.5, 0.0, 1.0) * 0.75 + 0.2
        shade = cv2.applyColorMap((z * 255).astype(np.uint8).reshape(-1, 1), cv2.COLORMAP_TURBO).reshape(-1, 3)
        img[row[ok], col[ok]] = shade[:, ::-1]
    for r in range(10, int(half_range) + 1, 10):
        cv2.circle(img, (int(c), int(c)), int(r / res), (60, 60, 60), 1, cv2.LINE_AA)

    def to_px(xy: np.ndarray) -> np.ndarray:
        return np.stack([c + xy[:, 1] / res, c - xy[:, 0] / res], axis=1).round().astype(np.int32)

    for m, corners in enumerate(np.asarray(boxes_ego, np.float64).reshape(-1, 8, 3)):
        color = colors[m] if colors is not None else _BOX_COLOR
        # Bottom face in order (+,+), (+,−), (−,−), (−,+); the first edge is the front.
        foot = to_px(corners[[1, 3, 7, 5], :2])
        cv2.polylines(img, [foot], True, color, 1, cv2.LINE_AA)
        cv2.line(img, tuple(foot[0]), tuple(foot[1]), (255, 255, 255), 2, cv2.LINE_AA)
    ex, ey = ego_half_extent
    ego = to_px(np.array([[ex, ey], [ex, -ey], [-ex, -ey], [-ex, ey]]))
    cv2.polylines(img, [ego], True, _EGO_COLOR, 2, cv2.LINE_AA)
    return img


def make_montage(
    images: Mapping[str, np.ndarray],
    top_down: np.ndarray | None,
    lidar_points_ego: np.ndarray,
    boxes_ego: np.ndarray,
    calibrations: Mapping[str, tuple[np.ndarray, np.ndarray]],
    tile_width: int = 640,
    box_colors: Sequence[tuple[int, int, int]] | None = None,
    lidar_range: float = 50.0,
) -> np.ndarray:
    """One RGB image: two rows of three cameras, then the top-down view beside the LiDAR BEV.

    ``images`` are RGB arrays keyed by camera folder (``front`` … ``back_right``); ``calibrations`` gives each
    camera's (K, cam2ego) for the image size the arrays have; ``boxes_ego`` are (M, 8, 3) corners in the
    ``world_cord`` order, in the ego frame. Missing cameras leave a black tile.
    """
    first = next(iter(images.values()), None)
    aspect = first.shape[0] / first.shape[1] if first is not None else 9.0 / 16.0
    tile_h = int(round(tile_width * aspect))
    rows = []
    for names in CAMERA_GRID:
        tiles = []
        for name in names:
            img = images.get(name)
            if img is None:
                tile = np.zeros((tile_h, tile_width, 3), np.uint8)
            else:
                scale = tile_width / img.shape[1]
                rgb = np.ascontiguousarray(img[..., :3])
                tile = cv2.resize(rgb, (tile_width, tile_h), interpolation=cv2.INTER_AREA)
                if name in calibrations:
                    k, cam2ego = calibrations[name]
                    project_boxes(tile, boxes_ego, k, cam2ego, scale, box_colors)
            _label(tile, name.upper())
            tiles.append(tile)
        rows.append(np.hstack(tiles))
    width = 3 * tile_width
    bottom_h = int(round(1.5 * tile_h))
    half_w = width // 2
    if top_down is not None:
        td = cv2.resize(np.ascontiguousarray(top_down[..., :3]), (half_w, bottom_h), interpolation=cv2.INTER_AREA)
    else:
        td = np.zeros((bottom_h, half_w, 3), np.uint8)
    _label(td, "TOP_DOWN")
    bev_size = bottom_h
    bev = lidar_bev(lidar_points_ego, boxes_ego, bev_size, lidar_range, box_colors)
    _label(bev, "LIDAR_TOP")
    right = np.zeros((bottom_h, width - half_w, 3), np.uint8)
    x0 = (right.shape[1] - bev_size) // 2
    right[:, x0 : x0 + bev_size] = bev
    rows.append(np.hstack([td, right]))
    return np.vstack(rows)


def boxes_from_anno(anno: Mapping) -> np.ndarray:
    """(M, 8, 3) ego-frame corners of the boxes of an annotation (format.md §3.3), the ego's own box excluded.

    Entries with ``world_cord`` use it; lights and signs (no corners stored) are rebuilt from centre, half extent
    and rotation. Corners are mapped by the ego's ``world2ego``.
    """
    from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform

    boxes = anno.get("bounding_boxes", [])
    if not boxes:
        return np.zeros((0, 8, 3))
    world2ego = np.asarray(boxes[0]["world2ego"], np.float64)
    out = []
    for entry in boxes[1:]:
        if "world_cord" in entry:
            corners = np.asarray(entry["world_cord"], np.float64)[:, :3]
        elif "center" in entry and "extent" in entry:
            pitch, roll, yaw = entry.get("rotation", [0.0, 0.0, 0.0])
            pose = Transform(Location(*entry["center"]), Rotation(pitch=pitch, yaw=yaw, roll=roll))
            corners = BoundingBox(Location(), Location(*entry["extent"])).world_corners(pose)
        else:
            continue
        out.append(corners @ world2ego[:3, :3].T + world2ego[:3, 3])
    return np.array(out).reshape(-1, 8, 3)


def calibrations_from_anno(anno: Mapping) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Camera folder → (K, cam2ego) from an annotation's ``sensors`` block."""
    from b2d_data.format.rig import CAMERA_BY_ID

    out = {}
    for sensor_id, entry in anno.get("sensors", {}).items():
        spec = CAMERA_BY_ID.get(sensor_id)
        if spec is not None and "intrinsic" in entry and "cam2ego" in entry:
            out[spec.folder] = (np.asarray(entry["intrinsic"], np.float64), np.asarray(entry["cam2ego"], np.float64))
    return out


def render_town_montage(
    town,
    place=None,
    weather: WeatherParameters = WeatherParameters(cloudiness=20.0, sun_altitude_angle=55.0, sun_azimuth_angle=30.0),
    seed: int = 0,
    resolution: tuple[int, int] = (800, 450),
    tile_width: int = 640,
) -> np.ndarray:
    """Render the rig at a place of a town (a few placed vehicles and walkers around) into a montage (RGB)."""
    from b2d_data.format.rig import CAMERAS
    from b2d_data.sim.api import RigConfig
    from b2d_data.sim.builtin.sensors.suite import SensorSuite
    from b2d_data.viz.town_scene import town_snapshot

    snapshot, ego_id = town_snapshot(town, place, weather, seed)
    w, h = resolution
    config = RigConfig(width=w, height=h, top_down_width=w, top_down_height=h)
    suite = SensorSuite(town, config, seed=seed)
    try:
        data = suite.capture(snapshot, ego_id)
    finally:
        suite.close()
    ego = snapshot.actors[ego_id]
    boxes = []
    for actor in snapshot.actors.values():
        if actor.id == ego_id or actor.location.distance(ego.location) > 60.0:
            continue
        corners = actor.bounding_box.world_corners(actor.transform)
        boxes.append(ego.transform.inverse_transform_points(corners))
    images = {name: frame.rgb for name, frame in data.cameras.items() if name != "top_down"}
    calib = {c.folder: (c.intrinsic(w, h), c.mount.matrix()) for c in CAMERAS}
    top = data.cameras.get("top_down")
    return make_montage(
        images, top.rgb if top is not None else None, data.lidar, np.array(boxes).reshape(-1, 8, 3), calib, tile_width
    )
