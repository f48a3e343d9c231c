"""Colour handed over as the JPEG's planes, computed on the GPU, equals libjpeg's conversion of the RGB image."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from b2d_data.codecs.jpeg import encode_jpeg, encode_jpeg_planes, jpeg_planes, read_jpeg
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, crossroads_layout, snapshot_of

from .conftest import SMALL
from .test_determinism_weather import NOON


def _capture(jpeg_planes: str):
    suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3),
                                   replace(SMALL, jpeg_planes=jpeg_planes), seed=11)  # fmt: skip
    try:
        ego = actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero")
        other = actor_state(2, "vehicle.tesla.model3", -15.0, 5.25, 0.0)
        return suite.renderer, suite.capture(snapshot_of([ego, other], NOON), 1).cameras
    finally:
        suite.close()


@pytest.fixture(scope="module")
def both():
    return _capture("off")[1], _capture("on")[1]


def test_gpu_planes_are_libjpegs_planes_of_the_rgb(both):
    rgb_frames, plane_frames = both
    assert len(plane_frames) == 7
    for name, frame in plane_frames.items():
        assert frame.rgb is None and frame.size == (90, 160)
        reference = jpeg_planes(np.ascontiguousarray(rgb_frames[name].rgb))
        for label, got, want in zip(("Y", "Cb", "Cr"), frame.jpeg_planes, reference):
            np.testing.assert_array_equal(got, want, err_msg=f"{name} {label}")
        # libjpeg-turbo as bundled with simplejpeg and with OpenCV rounds a few DCT coefficients differently, so
        # the files are not byte-identical; they are equally far from the image (codec noise only). On these
        # 160×90 images: mean |OpenCV − planes| 0.01–0.55 levels, error to the image equal to 3 digits.
        source = rgb_frames[name].rgb.astype(int)
        a = read_jpeg(encode_jpeg(rgb_frames[name].rgb)).astype(int)
        b = read_jpeg(encode_jpeg_planes(frame.jpeg_planes)).astype(int)
        err_a, err_b = np.abs(a - source).mean(), np.abs(b - source).mean()
        assert np.abs(a - b).mean() < 1.0 and abs(err_a - err_b) < 0.05 * err_a, name


def test_labels_do_not_change_with_planes(both):
    rgb_frames, plane_frames = both
    for name, frame in plane_frames.items():
        for field in ("depth", "semantic", "instance", "labels"):
            a, b = getattr(rgb_frames[name], field), getattr(frame, field)
            if a is None:
                assert b is None
            else:
                np.testing.assert_array_equal(a, b, err_msg=f"{name} {field}")


def test_gpu_mode_converts_on_hardware_only():
    renderer, frames = _capture("gpu")
    front = frames["front"]
    if renderer.hardware:
        assert front.rgb is None and front.jpeg_planes is not None
    else:  # llvmpipe: the conversion pass costs more CPU than libjpeg's own
        assert front.rgb is not None and front.jpeg_planes is None


def test_one_batch_on_a_gpu_renders_what_two_batches_render():
    """On a hardware GPU the top-down camera joins the six cameras' batch; the pixels must not change."""
    suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3), SMALL, seed=11)
    try:
        ego = actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero")
        snapshot = snapshot_of([ego, actor_state(2, "vehicle.tesla.model3", -15.0, 5.25, 0.0)], NOON)
        if suite.renderer.hardware:
            pytest.skip("needs the software renderer's two-batch path to compare with")
        two = suite.capture(snapshot, 1).cameras
        suite.renderer.hardware = True
        one = suite.capture(snapshot, 1).cameras
    finally:
        suite.close()
    assert list(one) == list(two) and "top_down" in one
    for name in one:
        for field in ("rgb", "depth", "semantic", "instance"):
            a, b = getattr(one[name], field), getattr(two[name], field)
            assert (a is None) == (b is None), (name, field)
            if a is not None:
                np.testing.assert_array_equal(a, b, err_msg=f"{name} {field}")
