"""The PNG encoder of the label and depth images: valid files, decoded bit-exactly by OpenCV and PIL."""

from __future__ import annotations

import io
import zlib

import cv2
import numpy as np
import pytest
from PIL import Image

from b2d_data.codecs import (
    depth_to_png_pixels,
    encode_depth_png,
    encode_instance_png,
    encode_semantic_png,
    instance_bgra,
    instance_rgba,
    read_depth_png,
    read_instance_png,
    read_semantic_png,
)
from b2d_data.codecs.png import encode_png, png_rows, sub_filtered


def _label_like(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Boxes of constant value on a constant background, plus a noisy strip: runs and high entropy together."""
    img = np.full(shape, 7, np.uint8)
    for _ in range(12):
        y, x = rng.integers(0, shape[0] - 8), rng.integers(0, shape[1] - 8)
        img[y : y + rng.integers(2, 9), x : x + rng.integers(2, 9)] = rng.integers(0, 256, shape[2:] or None)
    img[-3:] = rng.integers(0, 256, img[-3:].shape)
    return img


@pytest.mark.parametrize("shape", [(37, 53), (37, 53, 3), (37, 53, 4), (1, 1), (1, 9, 4)])
def test_opencv_and_pil_decode_the_encoded_pixels(shape):
    rng = np.random.default_rng(len(shape) * 100 + shape[0])
    img = _label_like(rng, shape) if min(shape[:2]) > 8 else rng.integers(0, 256, shape, dtype=np.uint8)
    data = encode_png(img)
    via_cv = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img.ndim == 3:  # OpenCV returns colour PNGs in B, G, R(, A) order
        via_cv = via_cv[..., [2, 1, 0, 3][: img.shape[2]]]
    assert np.array_equal(via_cv.reshape(img.shape), img)
    pil = Image.open(io.BytesIO(data))
    assert pil.mode == {2: "L", 3: "RGB", 4: "RGBA"}[img.ndim if img.ndim == 2 else img.shape[2]]
    assert np.array_equal(np.asarray(pil), img)


def test_sub_filter_by_hand():
    # Row [10, 12, 11] (grey): filter byte 1, then 10, 12 - 10 = 2, 11 - 12 = -1 = 255 (mod 256).
    row = np.array([[10, 12, 11]], np.uint8)
    assert sub_filtered(row).tolist() == [[1, 10, 2, 255]]
    # RGBA: the left neighbour is the same channel one pixel (4 bytes) earlier.
    px = np.array([[[1, 2, 3, 255], [4, 2, 1, 255]]], np.uint8)
    assert sub_filtered(px).tolist() == [[1, 1, 2, 3, 255, 3, 0, 254, 0]]


def _idat(data: bytes) -> bytes:
    """The decompressed scanlines of a one-IDAT PNG."""
    start = data.index(b"IDAT")
    length = int.from_bytes(data[start - 4 : start], "big")
    return zlib.decompress(data[start + 4 : start + 4 + length])


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_scanlines_in_memory_are_deflated_as_they_lie(channels):
    """An image whose rows each follow a zero byte is written with filter None from that memory; decoded the same."""
    rng = np.random.default_rng(channels)
    h, w = 6, 5
    block = np.zeros(3 + h * (w * channels + 1), np.uint8)  # the rows start 2 bytes into a larger block
    lines = block[2 : 2 + h * (w * channels + 1)].reshape(h, w * channels + 1)
    lines[:, 1:] = rng.integers(0, 256, (h, w * channels), dtype=np.uint8)
    img = lines[:, 1:] if channels == 1 else lines[:, 1:].reshape(h, w, channels)
    found = png_rows(img)
    assert found is not None and np.shares_memory(found, block) and found.shape == (h, w * channels + 1)
    data = encode_png(img)
    # Filter byte 0 and the pixels as they are: row 0 is [0, p00, p01, ...].
    assert _idat(data) == lines.tobytes()
    via_pil = np.asarray(Image.open(io.BytesIO(data)))
    assert np.array_equal(via_pil.reshape(img.shape), img)
    # One non-zero byte before a row: no longer scanlines; SUB-filtered as any other image, same pixels.
    lines[4, 0] = 9
    assert png_rows(img) is None
    assert _idat(encode_png(img))[0] == 1
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(encode_png(img)))).reshape(img.shape), img)


def test_scanlines_need_a_byte_before_each_row_inside_the_block():
    block = np.zeros((4, 9), np.uint8)
    assert png_rows(block[:, 1:]) is not None  # one byte before every row, all zero
    assert png_rows(block[:, :8]) is None  # the first row starts the block: nothing before it
    assert png_rows(block[:, 2:]) is None  # rows 2 bytes apart
    assert png_rows(np.zeros((4, 8), np.uint8)) is None  # an array of its own
    assert png_rows(block[1:, 1:]) is not None  # the byte before row 1 is the last one of row 0


def test_instance_pixels_by_hand():
    # Tag 7 with id 0x1234 (4660) is R = 7, G = 0x34 (low byte), B = 0x12 (high byte), A = 255 in the file.
    tags = np.array([[7, 0], [255, 11]], np.uint8)
    ids = np.array([[0x1234, 0], [0xFFFF, 0x00FF]], np.uint16)
    want = [[[7, 0x34, 0x12, 255], [0, 0, 0, 255]], [[255, 0xFF, 0xFF, 255], [11, 0xFF, 0x00, 255]]]
    assert instance_rgba(tags, ids).tolist() == want
    assert instance_bgra(tags, ids).tolist() == [[px[2::-1] + [255] for px in row] for row in want]
    # Wider id types holding two-byte values give the same pixels; larger values are refused.
    assert instance_rgba(tags, ids.astype(np.int64)).tolist() == want
    with pytest.raises(ValueError, match="65535"):
        instance_rgba(tags, ids.astype(np.int32) + 1)


def test_instance_file_order_matches_the_channel_shuffle():
    rng = np.random.default_rng(5)
    tags = rng.integers(0, 256, (31, 47), dtype=np.uint8)
    ids = rng.integers(0, 1 << 16, (31, 47), dtype=np.uint16)
    rgba = instance_rgba(tags, ids)
    assert rgba.dtype == np.uint8 and rgba.shape == (31, 47, 4) and rgba.flags.c_contiguous
    assert np.array_equal(rgba, instance_bgra(tags, ids)[..., [2, 1, 0, 3]])


def test_file_structure_is_plain_png():
    data = encode_png(np.zeros((5, 6, 4), np.uint8))
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR" and data[16:29] == bytes([0, 0, 0, 6, 0, 0, 0, 5, 8, 6, 0, 0, 0])
    # Every chunk's CRC holds (PIL's verify() checks them too).
    pos = 8
    while pos < len(data):
        n = int.from_bytes(data[pos : pos + 4], "big")
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        assert int.from_bytes(data[pos + 8 + n : pos + 12 + n], "big") == zlib.crc32(kind + body)
        pos += 12 + n
    assert kind == b"IEND"
    Image.open(io.BytesIO(data)).verify()


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="uint8"):
        encode_png(np.zeros((4, 4), np.uint16))
    with pytest.raises(ValueError, match="channels"):
        encode_png(np.zeros((4, 4, 2), np.uint8))


def test_files_decode_as_opencvs_own_encoder_did():
    """The images written before (OpenCV's imencode) and now decode to the same arrays through the readers."""
    rng = np.random.default_rng(3)
    tags = _label_like(rng, (90, 160))
    ids = (_label_like(rng, (90, 160)).astype(np.uint16) * 257 + rng.integers(0, 3, (90, 160))).astype(np.uint16)
    depth = rng.uniform(0.0, 400.0, (90, 160)).astype(np.float32)
    depth[:10] = 1000.0
    before = {
        "semantic": cv2.imencode(".png", tags)[1].tobytes(),
        "instance": cv2.imencode(".png", instance_bgra(tags, ids))[1].tobytes(),
        "depth": cv2.imencode(".png", depth_to_png_pixels(depth))[1].tobytes(),
    }
    after = {
        "semantic": encode_semantic_png(tags),
        "instance": encode_instance_png(tags, ids),
        "depth": encode_depth_png(depth),
    }
    assert np.array_equal(read_semantic_png(before["semantic"]), read_semantic_png(after["semantic"]))
    (t0, i0), (t1, i1) = read_instance_png(before["instance"]), read_instance_png(after["instance"])
    assert np.array_equal(t0, t1) and np.array_equal(i0, i1) and np.array_equal(i1, ids)
    assert np.array_equal(read_depth_png(before["depth"]), read_depth_png(after["depth"]))
    for kind, old in before.items():  # PIL too (RGBA for instance images, L for the others)
        a, b = Image.open(io.BytesIO(old)), Image.open(io.BytesIO(after[kind]))
        assert a.mode == b.mode and np.array_equal(np.asarray(a), np.asarray(b))
