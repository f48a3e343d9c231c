"""Depth: the uint8-metre PNG quirk (checked against OpenCV itself) and the float npz."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest

from b2d_data.codecs.depth import (
    DEPTH_NPZ_KEY,
    depth_to_png_pixels,
    encode_depth_npz,
    encode_depth_png,
    read_depth_npz,
    read_depth_png,
    write_depth_npz,
    write_depth_png,
)
from b2d_data.format.errors import B2DFormatError

TRICKY = np.array([[0.4, 0.5, 1.5, 2.5, 12.5, 13.5, 12.6, -3.0, 254.5, 255.5, 300.0, 1000.0,
                    np.nan, np.inf, -np.inf, 3e9]])  # fmt: skip
# Worked out by hand: round half to even (0.5→0, 2.5→2, 12.5→12, 13.5→14, 254.5→254), clip to [0, 255];
# NaN, ±inf and values beyond the int32 range become 0 in OpenCV's cvRound + saturate_cast.
EXPECTED = [0, 0, 2, 2, 12, 14, 13, 0, 254, 255, 255, 255, 0, 0, 0, 0]


def test_pixels_follow_opencv_rounding() -> None:
    assert depth_to_png_pixels(TRICKY).tolist() == [EXPECTED]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_png_equals_what_cv2_writes_for_a_float_array(dtype: type) -> None:
    # What the collector did: hand the float64 depth straight to OpenCV's PNG encoder.
    ok, buf = cv2.imencode(".png", TRICKY.astype(dtype))
    assert ok
    assert cv2.imdecode(buf, cv2.IMREAD_UNCHANGED).tolist() == [EXPECTED]
    assert depth_to_png_pixels(TRICKY.astype(dtype)).tolist() == [EXPECTED]
    random = np.random.default_rng(0).uniform(-10, 300, (36, 64)).astype(dtype)
    ok, buf = cv2.imencode(".png", random)
    assert np.array_equal(cv2.imdecode(buf, cv2.IMREAD_UNCHANGED), depth_to_png_pixels(random))
    assert read_depth_png(encode_depth_png(TRICKY)).tolist() == [[float(v) for v in EXPECTED]]


def test_png_is_one_channel_uint8(tmp_path: Path) -> None:
    path = tmp_path / "00000.png"
    write_depth_png(path, np.full((36, 64), 10.2))
    data = path.read_bytes()
    width, height, bit_depth, colour_type = struct.unpack(">IIBB", data[16:26])
    assert (width, height, bit_depth, colour_type) == (64, 36, 8, 0)  # greyscale, 8 bit


def test_round_trip_to_the_metre() -> None:
    depth = np.random.default_rng(1).uniform(0.0, 254.0, (36, 64))
    back = read_depth_png(encode_depth_png(depth))
    assert back.dtype == np.float32 and back.shape == (36, 64)
    assert np.abs(back - depth).max() <= 0.5


def test_npz_round_trip_and_key(tmp_path: Path) -> None:
    depth = np.random.default_rng(2).uniform(0.0, 1000.0, (36, 64)).astype(np.float32)
    path = tmp_path / "00000.npz"
    write_depth_npz(path, depth)
    with np.load(path) as npz:
        assert npz.files == [DEPTH_NPZ_KEY]
    assert np.array_equal(read_depth_npz(path), depth)
    compressed = encode_depth_npz(depth, dtype="float16", compress=True)
    assert np.allclose(read_depth_npz(compressed), depth, rtol=1e-3)


def test_npz_decoder_takes_the_first_array_whatever_its_key() -> None:
    depth = np.arange(12, dtype=np.float64).reshape(3, 4)
    bio = io.BytesIO()
    np.savez(bio, data=depth, other=np.zeros(2))
    assert np.array_equal(read_depth_npz(bio.getvalue()), depth)
    bio = io.BytesIO()
    np.savez(bio, depth)  # unnamed: arr_0
    assert read_depth_npz(bio.getvalue()).dtype == np.float32


def test_corrupt_depth_files(tmp_path: Path) -> None:
    good = encode_depth_png(np.full((36, 64), 5.0))
    (tmp_path / "trunc.png").write_bytes(good[: len(good) // 2])
    with pytest.raises(B2DFormatError, match="trunc.png"):
        read_depth_png(tmp_path / "trunc.png")
    rgb_png = cv2.imencode(".png", np.zeros((4, 4, 3), np.uint8))[1].tobytes()
    with pytest.raises(B2DFormatError, match="1-channel"):
        read_depth_png(rgb_png, name="rgb.png")
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04garbage")
    with pytest.raises(B2DFormatError, match="bad.npz"):
        read_depth_npz(tmp_path / "bad.npz")
    with pytest.raises(B2DFormatError, match="not an npz"):
        read_depth_npz(b"\x93NUMPY")
