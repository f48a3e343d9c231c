"""JPEG q20 codec: round trip, BGR on disk, quality tables, corrupt files."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from b2d_data.codecs._rgba import rgba_parent
from b2d_data.codecs.jpeg import (
    encode_jpeg,
    encode_jpeg_opencv,
    encode_jpeg_planes,
    jpeg_planes,
    planes_to_rgb,
    read_jpeg,
    read_quantization_tables,
    write_jpeg,
)
from b2d_data.format.errors import B2DFormatError


def smooth_rgb(h: int = 36, w: int = 64) -> np.ndarray:
    """A smooth colour ramp: JPEG q20 keeps it within a few grey levels."""
    v, u = np.mgrid[0:h, 0:w]
    return np.stack([u * 255 // (w - 1), v * 255 // (h - 1), np.full_like(u, 128)], axis=-1).astype(np.uint8)


def test_round_trip_within_q20_error(tmp_path: Path) -> None:
    rgb = smooth_rgb()
    path = tmp_path / "00000.jpg"
    size = write_jpeg(path, rgb)
    assert size == path.stat().st_size
    back = read_jpeg(path)
    assert back.shape == rgb.shape and back.dtype == np.uint8
    # q20 on a smooth ramp: mean error of a few levels (measured ~2); 6 leaves room for other libjpeg builds.
    assert np.abs(back.astype(int) - rgb).mean() < 6.0
    assert np.array_equal(read_jpeg(path.read_bytes()), back)


def test_rgb_is_stored_as_bgr() -> None:
    red = np.zeros((16, 16, 3), np.uint8)
    red[..., 0] = 255
    # Decoding with plain OpenCV yields BGR: a red image has its energy in channel 2.
    bgr = cv2.imdecode(np.frombuffer(encode_jpeg(red), np.uint8), cv2.IMREAD_COLOR)
    assert bgr[..., 2].mean() > 200 and bgr[..., 0].mean() < 30
    assert read_jpeg(encode_jpeg(red))[..., 0].mean() > 200


def test_rgb_view_of_rgba_gives_the_same_file() -> None:
    # The renderer's RGB is the first three channels of the RGBA it read back; OpenCV then converts RGBA → BGR in
    # one pass, and the file must be byte for byte the one the contiguous RGB gives.
    rgba = np.dstack([smooth_rgb(), np.full((36, 64), 255, np.uint8)])
    view = rgba[..., :3]
    parent = rgba_parent(view)
    assert parent is not None and parent.shape == (36, 64, 4) and parent.ctypes.data == rgba.ctypes.data
    assert encode_jpeg_opencv(view) == encode_jpeg_opencv(np.ascontiguousarray(view))
    assert encode_jpeg(view) == encode_jpeg(np.ascontiguousarray(view))
    # Rows of it are RGBA pixels too; views whose alpha would lie outside the memory, or that are no view, are not.
    np.testing.assert_array_equal(rgba_parent(rgba[1:, :, :3]), rgba[1:])
    for other in (smooth_rgb(), rgba[:, :, 1:], rgba[..., :3].copy(), rgba[:, 1:, :3]):
        assert rgba_parent(other) is None
    cropped = rgba[1:, :, :3]
    assert encode_jpeg_opencv(cropped) == encode_jpeg_opencv(np.ascontiguousarray(cropped))


def test_cameras_sharing_one_block_of_read_back_memory_keep_their_rgba() -> None:
    # A frame's read-backs are views of one block (renderer._Readback): the second camera's RGBA starts 36·64·4 =
    # 9216 bytes in, and its RGB view's parent must be exactly those bytes, not the block.
    first, second = smooth_rgb(), smooth_rgb()[::-1].copy()
    block = np.zeros(2 * 36 * 64 * 4, np.uint8)
    views = [block[k * 9216 : (k + 1) * 9216].reshape(36, 64, 4) for k in range(2)]
    for target, rgb in zip(views, (first, second)):
        target[..., :3], target[..., 3] = rgb, 255
    parent = rgba_parent(views[1][..., :3])
    assert parent is not None and parent.ctypes.data == block.ctypes.data + 9216
    np.testing.assert_array_equal(parent[..., :3], second)
    assert encode_jpeg_opencv(views[1][..., :3]) == encode_jpeg_opencv(second)


def test_quality_is_20() -> None:
    data = encode_jpeg(smooth_rgb())
    tables = read_quantization_tables(data)
    # IJG scaling for quality 20: factor 5000/20 = 250 %; the first entries of the standard luminance (16) and
    # chrominance (17) tables become (16·250 + 50) // 100 = 40 and (17·250 + 50) // 100 = 43.
    assert tables[0][0] == 40 and tables[1][0] == 43
    bgr = cv2.cvtColor(smooth_rgb(), cv2.COLOR_RGB2BGR)
    reference = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 20])[1].tobytes()
    # Byte for byte OpenCV's file (on a GPU machine encode_jpeg uses nvJPEG: test_jpeg_gpu.py checks that one).
    assert encode_jpeg_opencv(smooth_rgb()) == reference
    default = cv2.imencode(".jpg", bgr)[1].tobytes()  # OpenCV's default quality is 95
    assert read_quantization_tables(default)[0][0] != 40


def test_reduced_decoding() -> None:
    assert read_jpeg(encode_jpeg(smooth_rgb()), reduce=2).shape == (18, 32, 3)
    with pytest.raises(ValueError):
        read_jpeg(encode_jpeg(smooth_rgb()), reduce=3)


@pytest.mark.parametrize("cut", [0.5, 0.9])
def test_truncated_jpeg_names_the_file(tmp_path: Path, cut: float) -> None:
    data = encode_jpeg(smooth_rgb())
    path = tmp_path / "00007.jpg"
    path.write_bytes(data[: int(len(data) * cut)])
    with pytest.raises(B2DFormatError, match="00007.jpg.*truncated"):
        read_jpeg(path)


def test_garbage_and_missing(tmp_path: Path) -> None:
    path = tmp_path / "bad.jpg"
    path.write_bytes(b"not a jpeg at all")
    with pytest.raises(B2DFormatError, match="bad.jpg"):
        read_jpeg(path)
    with pytest.raises(B2DFormatError, match="missing.jpg.*does not exist"):
        read_jpeg(tmp_path / "missing.jpg")
    with pytest.raises(B2DFormatError, match="corrupt"):
        read_jpeg(b"\xff\xd8" + b"\x00" * 50 + b"\xff\xd9", name="x.jpg")
    with pytest.raises(ValueError):
        encode_jpeg(np.zeros((4, 4), np.uint8))


def test_planes_of_primaries_by_hand() -> None:
    # Y = (19595 R + 38470 G + 7471 B + 2^15) >> 16; Cb, Cr = (... + 128·2^16 + 2^15 − 1) >> 16.
    # Red: Y = (4996725 + 32768) >> 16 = 76; Cb = (−2820045 + 8421375) >> 16 = 85; Cr = (8355840 + 8421375) >> 16 = 255.
    # Blue: Y = (1905105 + 32768) >> 16 = 29; Cb = 255; Cr = (−1358895 + 8421375) >> 16 = 107.
    for colour, want in (
        ((255, 0, 0), (76, 85, 255)),
        ((0, 0, 255), (29, 255, 107)),
        ((255, 255, 255), (255, 128, 128)),
    ):
        rgb = np.empty((2, 2, 3), np.uint8)
        rgb[:] = colour
        y, cb, cr = jpeg_planes(rgb)
        assert (y == want[0]).all() and cb[0, 0] == want[1] and cr[0, 0] == want[2], colour


def test_chroma_rounding_bias_alternates_by_column() -> None:
    # Grey (0,0,0) has Cb 128; (0,0,2) has Cb (65536 + 8421375) >> 16 = 129. Each 2×2 block holds two of each:
    # sum 514, so block 0 gives (514 + 1) >> 2 = 128 and block 1 gives (514 + 2) >> 2 = 129.
    rgb = np.zeros((2, 4, 3), np.uint8)
    rgb[:, 1::2, 2] = 2
    _, cb, _ = jpeg_planes(rgb)
    assert cb.tolist() == [[128, 129]]


def test_planes_encode_to_opencvs_file() -> None:
    # Height and width multiples of 16: libjpeg pads nothing, so the file is OpenCV's byte for byte.
    rgb = smooth_rgb(48, 64)
    assert encode_jpeg_planes(jpeg_planes(rgb)) == encode_jpeg(rgb)
    np.testing.assert_array_equal(read_jpeg(encode_jpeg_planes(jpeg_planes(rgb))), read_jpeg(encode_jpeg(rgb)))


def test_planes_shapes_are_checked() -> None:
    y = np.zeros((4, 6), np.uint8)
    with pytest.raises(ValueError, match="H/2, W/2"):
        encode_jpeg_planes((y, np.zeros((2, 2), np.uint8), np.zeros((2, 3), np.uint8)))
    with pytest.raises(ValueError, match="even"):
        jpeg_planes(np.zeros((3, 4, 3), np.uint8))


def test_planes_to_rgb_is_close_to_the_image() -> None:
    rgb = smooth_rgb(32, 48)
    assert np.abs(planes_to_rgb(jpeg_planes(rgb)).astype(int) - rgb).mean() < 3.0
