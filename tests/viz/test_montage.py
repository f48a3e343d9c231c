"""Montage drawing: boxes land where K and cam2ego put them, LiDAR BEV pixels where the points are, layout sizes."""

from __future__ import annotations

import numpy as np

from b2d_data.format.rig import CAMERAS, camera
from b2d_data.format.transform import BoundingBox, Location
from b2d_data.format.weather import WeatherParameters
from b2d_data.viz.montage import lidar_bev, make_montage, project_boxes, render_town_montage


def _box(cx: float, cy: float, cz: float, hx: float, hy: float, hz: float) -> np.ndarray:
    return BoundingBox(Location(cx, cy, cz), Location(hx, hy, hz)).local_corners()[None]


def test_box_edges_project_where_k_and_cam2ego_put_them():
    spec = camera("front")
    k, cam2ego = spec.intrinsic(160, 90), spec.mount.matrix()
    img = np.zeros((90, 160, 3), np.uint8)
    # Corners 0-1 form the vertical edge x = 11.3, y = 2 (ego); CAM_FRONT is at (0.8, 0, 1.6): 10.5 m ahead,
    # 2 m to the right, so the edge is drawn at u = 80 + f·2/10.5 for v between 45 ∓ f·1/10.5.
    project_boxes(img, _box(10.8, 0.0, 1.6, 0.5, 2.0, 1.0), k, cam2ego)
    f = k[0, 0]
    u = 80.0 + f * 2.0 / 10.5
    assert img[45, int(round(u)) - 1 : int(round(u)) + 2].any()
    assert img[int(45 - f / 10.5) + 2 : int(45 + f / 10.5) - 1, int(round(u))].any(axis=1).all()
    assert not img[:20, :40].any()
    # A box behind the camera draws nothing.
    behind = np.zeros_like(img)
    project_boxes(behind, _box(-10.0, 0.0, 1.0, 1.0, 1.0, 1.0), k, cam2ego)
    assert not behind.any()


def test_lidar_bev_pixels_and_layout():
    bev = lidar_bev(np.array([[10.0, 5.0, 0.0]]), np.zeros((0, 8, 3)), size=200, half_range=50.0)
    # 0.5 m per pixel, forward up, right to the right: (10, 5) → row 100 − 20, column 100 + 10.
    assert bev[80, 110].any()
    assert bev.shape == (200, 200, 3)
    images = {c.folder: np.full((90, 160, 3), 60, np.uint8) for c in CAMERAS}
    calib = {c.folder: (c.intrinsic(160, 90), c.mount.matrix()) for c in CAMERAS}
    top = np.full((90, 160, 3), 120, np.uint8)
    out = make_montage(images, top, np.zeros((0, 3)), np.zeros((0, 8, 3)), calib, tile_width=160)
    # Two rows of 160×90 tiles, then a 1.5 × 90 row (top-down | LiDAR BEV).
    assert out.shape == (90 + 90 + 135, 480, 3) and out.dtype == np.uint8
    assert (out[120:170, 40:150] == 60).all()  # back-left tile content (below its label)
    assert (out[250:300, 40:200] == 120).all()  # top-down


def test_town_montage_renders_a_street(carla_maps_dir):
    from b2d_data.maps import load_opendrive

    town = load_opendrive(carla_maps_dir / "Town10HD.xodr")
    weather = WeatherParameters(sun_altitude_angle=50.0)
    img = render_town_montage(town, None, weather, seed=0, resolution=(160, 90), tile_width=160)
    assert img.shape == (315, 480, 3)
    cams = img[:180]
    assert cams.std() > 20.0  # not a flat image: road, buildings, sky
    # Box overlays are drawn in the box colour somewhere in the camera tiles.
    assert (np.abs(cams.astype(int) - [255, 160, 0]).sum(axis=2) < 30).any()


def test_boxes_and_calibrations_from_an_annotation():
    from b2d_data.format.transform import Rotation, Transform
    from b2d_data.viz.montage import boxes_from_anno, calibrations_from_anno

    front = camera("front")
    ego = Transform(Location(10.0, 20.0, 0.0), Rotation(yaw=90.0))  # heading south (+y)
    car = BoundingBox(Location(0.0, 0.0, 0.7), Location(2.0, 1.0, 0.7))
    car_pose = Transform(Location(10.0, 25.0, 0.0), Rotation(yaw=90.0))  # 5 m ahead, same heading
    anno = {
        "bounding_boxes": [
            {"class": "ego_vehicle", "world2ego": ego.inverse_matrix().tolist()},
            {"class": "vehicle", "world_cord": car.world_corners(car_pose).tolist()},
            {"class": "traffic_light", "center": [10.0, 30.0, 3.0], "extent": [0.25, 0.3, 0.6], "rotation": [0, 0, 90]},
        ],
        "sensors": {
            "CAM_FRONT": {"intrinsic": front.intrinsic().tolist(), "cam2ego": front.mount.matrix().tolist()},
            "LIDAR_TOP": {"lidar2ego": np.eye(4).tolist()},
        },
    }
    boxes = boxes_from_anno(anno)
    assert boxes.shape == (2, 8, 3)
    # The car's corners in the ego frame: x 3..7, y −1..1, z 0..1.4; the light's: centre (10, 0, 3).
    np.testing.assert_allclose(boxes[0].min(axis=0), [3.0, -1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(boxes[0].max(axis=0), [7.0, 1.0, 1.4], atol=1e-9)
    np.testing.assert_allclose(boxes[1].mean(axis=0), [10.0, 0.0, 3.0], atol=1e-9)
    calib = calibrations_from_anno(anno)
    assert list(calib) == ["front"]
    np.testing.assert_allclose(calib["front"][0], camera("front").intrinsic())
