"""The renderer's GPU paths give the pixels of the plain path: cameras drawn into one packed target and unpacked by a
compute pass, read-backs through one pixel-pack buffer."""

from __future__ import annotations

import functools
from dataclasses import replace

import cv2
import numpy as np
import pytest

from b2d_data.codecs.depth import encode_depth_png
from b2d_data.codecs.labels_png import encode_instance_png, encode_semantic_png, read_instance_png
from b2d_data.codecs.png import png_rows
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.builtin.sensors import suite as suite_module
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.renderer import Renderer
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.texture_pack import TexturePacker
from b2d_data.sim.builtin.sensors.synthetic import crossroads_layout, snapshot_of

from .test_determinism_weather import CONFIG, NOON, _actors

#: Every shader variant the packed output is spliced into: day, wet (puddles), night (lamps, lit windows), fog.
WEATHERS = {
    "noon": NOON,
    "wet night": WeatherParameters(cloudiness=90.0, precipitation=60.0, wetness=80.0, precipitation_deposits=70.0,
                                   sun_altitude_angle=-30.0),  # fmt: skip
    "fog": WeatherParameters(fog_density=60.0, fog_distance=10.0, sun_altitude_angle=20.0),
}


def _suite(monkeypatch: pytest.MonkeyPatch, packed: bool, planes: str, pixel_buffer: bool = False,
           png_rows: bool = False, pack_reads: bool = False) -> SensorSuite:  # fmt: skip
    monkeypatch.setattr(suite_module, "Renderer", functools.partial(Renderer, packed=packed, pixel_buffer=pixel_buffer,
                                                                    pack_reads=pack_reads))  # fmt: skip
    config = replace(CONFIG, jpeg_planes=planes, float_depth=False, png_rows=png_rows)
    suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3), config, seed=11)
    assert suite.renderer.packed is packed and suite.renderer.pixel_buffer is pixel_buffer
    assert suite.renderer.png_rows is (png_rows and packed) and suite.renderer.pack_reads is pack_reads
    return suite


def _capture(monkeypatch: pytest.MonkeyPatch, packed: bool, planes: str, pixel_buffer: bool = False,
             png_rows: bool = False) -> dict[str, dict]:  # fmt: skip
    suite = _suite(monkeypatch, packed, planes, pixel_buffer, png_rows)
    try:
        return {name: suite.capture(snapshot_of(_actors(), weather, frame=3), 1).cameras
                for name, weather in WEATHERS.items()}  # fmt: skip
    finally:
        suite.close()


@pytest.mark.parametrize(("planes", "packed", "pixel_buffer"), [("off", True, False), ("on", True, False),
                                                               ("off", False, True), ("on", True, True)])
def test_gpu_paths_give_the_same_pixels(monkeypatch, planes, packed, pixel_buffer):
    four = _capture(monkeypatch, False, planes)
    one = _capture(monkeypatch, packed, planes, pixel_buffer)
    for weather, cameras in four.items():
        assert set(cameras) == {"front", "back", "top_down"}
        for cam, frame in cameras.items():
            other = one[weather][cam]
            for field in ("depth", "semantic", "instance", "labels"):
                a, b = getattr(frame, field), getattr(other, field)
                assert (a is None) == (b is None), (weather, cam, field)
                if a is not None:
                    np.testing.assert_array_equal(a, b, err_msg=f"{weather} {cam} {field}")
            colour = [(frame.rgb, other.rgb)] if frame.rgb is not None else list(zip(frame.jpeg_planes, other.jpeg_planes))
            for a, b in colour:
                diff = np.abs(a.astype(int) - b.astype(int))
                if not packed:  # the same draw, read another way: every byte the same
                    assert diff.max() == 0, (weather, cam)
                # Packed, the shader rounds colour to bytes itself, where an RGBA8 target left the rounding to the
                # implementation (GL allows either neighbour): one level apart on 1 of 62208 values on llvmpipe,
                # on 3–5 % of values on an H100 (chroma of small images). Far below JPEG noise at quality 20 (next test).
                assert diff.max() <= 1 and np.count_nonzero(diff) <= diff.size // 10, (weather, cam)
        # The scene is really there: sky, road and the cars' ids all appear in the front camera.
        front = cameras["front"]
        assert {11, 1, 14} <= set(np.unique(front.semantic).tolist()), weather
        assert len(np.unique(front.instance)) >= 3, weather


@pytest.mark.parametrize("pixel_buffer", [False, True])
def test_png_rows_hand_over_the_same_labels_as_scanlines(monkeypatch, pixel_buffer):
    """With ``png_rows`` depth, semantic, instance and labels are the same values, each a view of its PNG scanlines
    (a zero filter byte before every row), and their PNG files decode to the same pixels."""
    plain = _capture(monkeypatch, True, "on", pixel_buffer)
    rows = _capture(monkeypatch, True, "on", pixel_buffer, png_rows=True)
    for weather, cameras in plain.items():
        for cam, frame in cameras.items():
            other = rows[weather][cam]
            for a, b in zip(frame.jpeg_planes, other.jpeg_planes):
                np.testing.assert_array_equal(a, b)
            if frame.depth is None:  # the top-down camera has colour only
                assert other.depth is None and other.labels is None
                continue
            h, w = frame.depth.shape
            for field, encode in (("depth", encode_depth_png), ("semantic", encode_semantic_png)):
                a, b = getattr(frame, field), getattr(other, field)
                np.testing.assert_array_equal(a, b, err_msg=f"{weather} {cam} {field}")
                assert b.strides == (w + 1, 1) and png_rows(a) is None
                lines = png_rows(b)
                assert lines is not None and lines.shape == (h, w + 1) and not lines[:, 0].any()
                assert encode(b) != encode(a)  # filter None against SUB: other bytes...
                np.testing.assert_array_equal(cv2.imdecode(np.frombuffer(encode(b), np.uint8), cv2.IMREAD_UNCHANGED), a)  # ...the same pixels
            np.testing.assert_array_equal(frame.labels, other.labels)
            np.testing.assert_array_equal(frame.instance, other.instance)
            assert other.labels.strides == (4 * w + 1, 4, 1)
            lines = png_rows(other.labels)
            assert lines is not None and lines.shape == (h, 4 * w + 1)
            tags, ids = read_instance_png(encode_instance_png(other.semantic, other.instance, packed=other.labels))
            np.testing.assert_array_equal(tags, frame.semantic)
            np.testing.assert_array_equal(ids, frame.instance)


@pytest.mark.parametrize(("planes", "rows", "packs", "copies"), [("on", True, 6 + 6 + 3, 2), ("off", False, 2 + 2, 1)])
def test_reads_packed_by_a_compute_pass_are_the_bytes_of_glreadpixels(monkeypatch, planes, rows, packs, copies):
    """``pack_reads``: the one-byte targets go through ``TexturePacker`` (a compute pass and one buffer copy) and the
    frame's arrays hold exactly the bytes glReadPixels gives; other reads (RGBA colour, RGBA labels) still go through
    glReadPixels, into the same GPU buffer. A batch with nothing to pack (here llvmpipe renders the RGBA top-down
    camera on its own) is read straight into the mapped buffer, without the copy."""
    calls, copied = [], []
    pack, copy_to = TexturePacker.pack, TexturePacker.copy_to
    monkeypatch.setattr(TexturePacker, "pack", lambda self, texture, offset: (calls.append(texture.size),
                                                                              pack(self, texture, offset)))  # fmt: skip
    monkeypatch.setattr(TexturePacker, "copy_to", lambda self, *a: (copied.append(a), copy_to(self, *a)))
    plain = _suite(monkeypatch, True, planes, pixel_buffer=True, png_rows=rows)
    packed = _suite(monkeypatch, True, planes, pixel_buffer=True, png_rows=rows, pack_reads=True)
    try:
        for weather in WEATHERS.values():  # one frame at a time: the mapped blocks are free again for the next
            snapshot = snapshot_of(_actors(), weather, frame=3)
            cameras = plain.capture(snapshot, 1).cameras
            assert not calls
            others = packed.capture(snapshot, 1).cameras
            # With planes and scanlines every read (front, back: 3 planes + depth, labels, tags rows; top-down: 3
            # planes); without, only the labelled cameras' depth and tag targets (colour and labels are RGBA).
            assert len(calls) == packs and len(copied) == copies
            calls.clear()
            copied.clear()
            for cam, frame in cameras.items():
                other = others[cam]
                for field in ("rgb", "depth", "semantic", "instance", "labels"):
                    a, b = getattr(frame, field), getattr(other, field)
                    assert (a is None) == (b is None), (weather, cam, field)
                    if a is not None:
                        np.testing.assert_array_equal(a, b, err_msg=f"{weather} {cam} {field}")
                for a, b in zip(frame.jpeg_planes or (), other.jpeg_planes or (), strict=True):
                    np.testing.assert_array_equal(a, b, err_msg=f"{weather} {cam} planes")
                if rows and frame.depth is not None:  # the scanlines' filter bytes came through too
                    assert png_rows(other.depth) is not None and png_rows(other.labels) is not None
            del cameras, others, frame, other, a, b
    finally:
        plain.close()
        packed.close()


def test_pack_reads_need_mapped_buffers():
    with pytest.raises(RuntimeError, match="pack_reads needs mapped read-back buffers"):
        Renderer(depth8=True, pixel_buffer=False, pack_reads=True)


def test_packed_targets_need_uint8_depth():
    with pytest.raises(RuntimeError, match="depth8"):
        Renderer(depth8=False, packed=True)



def test_packed_colour_is_within_jpeg_noise(monkeypatch):
    """The JPEGs of the packed and the four-target draw differ by less than either differs from its image."""
    from b2d_data.codecs.jpeg import encode_jpeg, read_jpeg

    four = _capture(monkeypatch, False, "off")
    one = _capture(monkeypatch, True, "off")
    for weather, cameras in four.items():
        for cam, frame in cameras.items():
            image = frame.rgb.astype(int)
            a = read_jpeg(encode_jpeg(frame.rgb)).astype(int)
            b = read_jpeg(encode_jpeg(one[weather][cam].rgb)).astype(int)
            codec_noise = np.abs(a - image).mean()
            assert codec_noise > 0.5, (weather, cam)  # quality 20 is lossy: the bound below is not vacuous
            assert np.abs(a - b).mean() < 0.5 * codec_noise, (weather, cam)
