"""uint8 depth rounded on the GPU: the same bytes as OpenCV's conversion of the float depth the renderer reads back."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from b2d_data.codecs.depth import depth_to_png_pixels, encode_depth_png, read_depth_png
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, box_prop, flat_scene, snapshot_of

from .conftest import SMALL


@pytest.fixture(scope="module")
def suites():
    """The same 160×90 rig twice: float depth, and uint8 depth packed on the GPU."""
    float_suite = SensorSuite.from_scene(flat_scene(), SMALL, seed=0)
    byte_suite = SensorSuite.from_scene(flat_scene(), replace(SMALL, float_depth=False), seed=0)
    yield float_suite, byte_suite
    float_suite.close()
    byte_suite.close()


@pytest.mark.parametrize("yaw", [0.0, 37.0])
def test_depth8_is_opencv_rounding_of_float_depth(suites, noon, yaw):
    float_suite, byte_suite = suites
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, yaw, role_name="hero")
    # Near faces at x = 6.3 and 11.3 m: CAM_FRONT (x = 0.8 m) sees planar depths of 5.5 and 10.5 m, ties that
    # round half to even (to 6 and 10); the ground and the sky (1000 m → 255) fill the rest.
    boxes = [box_prop(77, 7.3, -2.0, (1.0, 1.5, 1.0), tag=20), box_prop(78, 12.3, 2.5, (1.0, 1.5, 1.0), tag=20)]
    snap = snapshot_of([ego, *boxes], noon)
    want = float_suite.capture(snap, ego.id).cameras
    got = byte_suite.capture(snap, ego.id).cameras
    assert set(got) == set(want)
    labelled = [cam for cam, f in want.items() if f.depth is not None]
    assert len(labelled) == 6
    for cam in labelled:
        d = want[cam].depth
        assert d.dtype == np.float32 and got[cam].depth.dtype == np.uint8
        expected = cv2.add(d, 0.0, dtype=cv2.CV_8U)  # what cv2.imwrite stored for the float image
        np.testing.assert_array_equal(got[cam].depth, expected, err_msg=cam)
        # Everything else in the frame is unchanged (colour within one level where a GPU draws uint8 depth into the
        # packed target, whose colour the shader rounds: test_gpu_paths).
        colour_diff = np.abs(got[cam].rgb.astype(int) - want[cam].rgb.astype(int))
        assert colour_diff.max() <= (1 if byte_suite.renderer.packed else 0), cam
        np.testing.assert_array_equal(got[cam].semantic, want[cam].semantic)
        np.testing.assert_array_equal(got[cam].instance, want[cam].instance)
        # The PNG written from either is the same file.
        assert encode_depth_png(got[cam].depth) == encode_depth_png(d)
    front = want["front"].depth
    assert (front == 1000.0).any() and (got["front"].depth[front == 1000.0] == 255).all()  # sky
    if yaw == 0.0:  # the boxes face the camera squarely: their faces are the x.5 ties
        near = np.abs(front - 5.5) < 1e-3
        far = np.abs(front - 10.5) < 1e-3
        assert near.sum() > 50 and far.sum() > 50
        assert set(np.unique(got["front"].depth[near])) <= {5, 6}
        assert set(np.unique(got["front"].depth[far])) <= {10, 11}


def test_uint8_depth_passes_through_the_png_encoder():
    depth = np.array([[0, 1, 254, 255]], np.uint8)
    assert depth_to_png_pixels(depth) is depth
    np.testing.assert_array_equal(read_depth_png(encode_depth_png(depth)), [[0.0, 1.0, 254.0, 255.0]])
