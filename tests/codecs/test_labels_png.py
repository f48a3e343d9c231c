"""Semantic and instance PNGs: channel meaning checked byte-level with an independent decoder (PIL)."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from b2d_data.codecs.labels_png import (
    encode_instance_png,
    encode_semantic_png,
    read_instance_png,
    read_semantic_png,
    split_instance,
    write_instance_png,
    write_semantic_png,
)
from b2d_data.format.errors import B2DFormatError


def ihdr(data: bytes) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) from a PNG's IHDR chunk."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">IIBB", data[16:26])


def test_semantic_round_trip(tmp_path: Path) -> None:
    tags = np.random.default_rng(0).integers(0, 29, (36, 64)).astype(np.uint8)
    path = tmp_path / "00000.png"
    write_semantic_png(path, tags)
    assert ihdr(path.read_bytes()) == (64, 36, 8, 0)
    assert np.array_equal(read_semantic_png(path), tags)
    assert np.array_equal(np.asarray(Image.open(path)), tags)


def test_instance_channels_on_disk(tmp_path: Path) -> None:
    # One pixel per case, values chosen so that every byte differs: tag 14, id 0x1234 → R 14, G 0x34, B 0x12.
    tags = np.array([[14, 4]], np.uint8)
    ids = np.array([[0x1234, 0x00FF]], np.uint16)
    path = tmp_path / "00000.png"
    write_instance_png(path, tags, ids)
    assert ihdr(path.read_bytes()) == (2, 1, 8, 6)  # RGBA, colour type 6
    rgba = np.asarray(Image.open(path))  # PIL decodes independently of OpenCV, in R, G, B, A order
    assert rgba.tolist() == [[[14, 0x34, 0x12, 255], [4, 0xFF, 0x00, 255]]]
    bgra = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert bgra.tolist() == [[[0x12, 0x34, 14, 255], [0x00, 0xFF, 4, 255]]]
    t, i = read_instance_png(path)
    assert t.tolist() == [[14, 4]] and i.tolist() == [[0x1234, 0x00FF]] and i.dtype == np.uint16


def test_instance_round_trip_and_files_from_other_writers() -> None:
    rng = np.random.default_rng(1)
    tags = rng.integers(0, 29, (36, 64)).astype(np.uint8)
    ids = rng.integers(0, 65536, (36, 64)).astype(np.uint16)
    t, i = read_instance_png(encode_instance_png(tags, ids))
    assert np.array_equal(t, tags) and np.array_equal(i, ids)
    # A file written by PIL from an RGBA array, and one without alpha.
    rgba = np.stack([tags, (ids & 0xFF).astype(np.uint8), (ids >> 8).astype(np.uint8), np.full_like(tags, 255)], -1)
    for image in (Image.fromarray(rgba, "RGBA"), Image.fromarray(rgba[..., :3], "RGB")):
        bio = io.BytesIO()
        image.save(bio, format="PNG")
        t, i = read_instance_png(bio.getvalue())
        assert np.array_equal(t, tags) and np.array_equal(i, ids)
    t, i = split_instance(rgba, "RGBA")
    assert np.array_equal(t, tags) and np.array_equal(i, ids)


def test_label_errors(tmp_path: Path) -> None:
    rgb_png = cv2.imencode(".png", np.zeros((4, 4, 3), np.uint8))[1].tobytes()
    with pytest.raises(B2DFormatError, match="sem.png.*1-channel"):
        read_semantic_png(rgb_png, name="sem.png")
    gray = encode_semantic_png(np.zeros((4, 4), np.uint8))
    with pytest.raises(B2DFormatError, match="RGB"):
        read_instance_png(gray)
    whole = encode_instance_png(np.zeros((36, 64), np.uint8), np.zeros((36, 64), np.uint16))
    (tmp_path / "cut.png").write_bytes(whole[:60])
    with pytest.raises(B2DFormatError, match="cut.png"):
        read_instance_png(tmp_path / "cut.png")
    with pytest.raises(ValueError):
        encode_instance_png(np.zeros((2, 2), np.uint8), np.full((2, 2), 70000, np.int64))
