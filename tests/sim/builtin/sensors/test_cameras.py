"""Camera consistency: a box covers the pixels its projection predicts, with its tag, id and planar depth."""

from __future__ import annotations

import math

import numpy as np

from b2d_data.format.rig import TOP_DOWN, camera
from b2d_data.sim.builtin.sensors.lighting import Lighting
from b2d_data.sim.builtin.sensors.renderer import CameraView
from b2d_data.sim.builtin.sensors.synthetic import actor_state, box_prop, snapshot_of

BOX_ID = 77
BOX_TAG = 20


def _ego(yaw: float = 0.0):
    return actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, yaw, role_name="hero")


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def _check_box(suite, geometry, noon, folder: str, box, near_face_depth: float) -> None:
    ego = _ego()
    data = suite.capture(snapshot_of([ego, box], noon), ego.id)
    frame = data.cameras[folder]
    spec = camera(folder)
    w, h = geometry.small.width, geometry.small.height
    pose = suite.sensor_poses(ego)[spec.sensor_id]
    corners = box.bounding_box.world_corners(box.transform)
    pix, z = geometry.project(spec, pose, corners, w, h)
    assert (z > 0).all()
    expected = geometry.convex_mask(pix, w, h)
    rendered = frame.instance == BOX_ID
    assert expected.sum() > 300  # the box is large in the image: the IoU below is meaningful
    assert _iou(expected, rendered) > 0.97
    assert (frame.semantic[rendered] == BOX_TAG).all()
    # Only the near face (a plane at constant distance along the optical axis) is visible.
    np.testing.assert_allclose(frame.depth[rendered], near_face_depth, atol=2e-3)
    # The pose the suite reports is the one it rendered with.
    t = data.sensor_transforms[spec.sensor_id]
    np.testing.assert_allclose(t.matrix(), pose, atol=1e-9)


def test_box_in_front_camera(small_suite, geometry, noon):
    # Box spans x 11..13 m, y −1..2 m, z 0..2 m; CAM_FRONT sits at x = 0.8 m: planar depth 11 − 0.8 = 10.2 m.
    box = box_prop(BOX_ID, 12.0, 0.5, (1.0, 1.5, 1.0), tag=BOX_TAG)
    _check_box(small_suite, geometry, noon, "front", box, 10.2)


def test_box_in_back_camera_110_degrees(small_suite, geometry, noon):
    # CAM_BACK at x = −2.0 m looks backwards with a 110° FOV; near face at x = −8 m: depth 6.0 m.
    box = box_prop(BOX_ID, -9.0, -0.5, (1.0, 1.5, 1.0), tag=BOX_TAG)
    _check_box(small_suite, geometry, noon, "back", box, 6.0)


def test_ground_depth_and_sky(small_suite, geometry, noon):
    ego = _ego()
    frame = small_suite.capture(snapshot_of([ego], noon), ego.id).cameras["front"]
    f = camera("front").intrinsic(160, 90)[0, 0]
    # Flat ground 1.6 m below the camera: a pixel row v below the horizon sees it at depth 1.6·f / (v + 0.5 − 45).
    for v in (60, 75, 89):
        assert math.isclose(float(frame.depth[v, 5]), 1.6 * f / (v + 0.5 - 45.0), rel_tol=1e-4)
        assert frame.semantic[v, 5] == 10 and frame.instance[v, 5] == 0
    assert frame.depth[0, 80] == 1000.0 and frame.semantic[0, 80] == 11 and frame.instance[0, 80] == 0
    assert frame.rgb.shape == (90, 160, 3) and frame.rgb.dtype == np.uint8
    assert frame.depth.dtype == np.float32 and frame.semantic.dtype == np.uint8 and frame.instance.dtype == np.uint16


def test_top_down_follows_ego_yaw(small_suite, geometry, noon):
    # Ego heading south (+y); a box 10 m ahead of it must appear above the image centre (image up = ego forward).
    ego = _ego(yaw=90.0)
    box = box_prop(BOX_ID, 0.0, 10.0, (1.0, 1.0, 1.0), tag=BOX_TAG)
    top = small_suite.capture(snapshot_of([ego, box], noon), ego.id).cameras["top_down"]
    assert top.depth is None and top.semantic is None  # RGB only, as Bench2Drive stores it
    pose = small_suite.sensor_poses(ego)[TOP_DOWN.sensor_id]
    view = CameraView(pose, TOP_DOWN.fov, 160, 90, labels=True)
    frame = small_suite.renderer.render([view], Lighting.from_weather(noon))[0]
    # The RGB-only target and the labelled one give the same picture.
    np.testing.assert_array_equal(top.rgb, frame.rgb)
    assert top.rgb.mean() > 40.0
    pix, _ = geometry.project(TOP_DOWN, pose, np.array([[0.0, 10.0, 2.0]]), 160, 90)
    u, v = pix[0]
    assert math.isclose(u, 80.0, abs_tol=1e-6) and v < 45.0
    assert frame.instance[int(v), int(u)] == BOX_ID
    # 10 m ahead of the ego at 50 m height: v = 45 − f·10/(50 − 2) with the top-down camera's focal length.
    f = TOP_DOWN.intrinsic(160, 90)[0, 0]
    assert math.isclose(v, 45.0 - f * 10.0 / 48.0, rel_tol=1e-9)


def test_dynamic_buffer_grows_with_the_actor_count(small_suite, geometry, noon):
    # The per-frame vertex buffer starts at 1 MiB; 80 cars (far behind the ego, out of the front camera's view)
    # need several MiB, so the second capture must regrow it and still draw the box where it did before.
    box = box_prop(BOX_ID, 12.0, 0.5, (1.0, 1.5, 1.0), tag=BOX_TAG)
    _check_box(small_suite, geometry, noon, "front", box, 10.2)
    before = small_suite.renderer._dyn_vbo.size
    cars = [actor_state(100 + i, "vehicle.tesla.model3", -60.0 - 6.0 * (i % 10), -20.0 + 5.0 * (i // 10))
            for i in range(80)]  # fmt: skip
    ego = _ego()
    small_suite.capture(snapshot_of([ego, box, *cars], noon), ego.id)
    assert small_suite.renderer._dyn_vbo.size > before
    _check_box(small_suite, geometry, noon, "front", box, 10.2)
