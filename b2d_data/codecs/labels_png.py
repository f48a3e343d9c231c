"""Semantic and instance label PNGs (format.md §2.3).

Semantic: 1-channel uint8 PNG of CARLA tag ids. Instance: OpenCV writes the BGRA array
(B = id high byte, G = id low byte, R = semantic tag, A = 255), so the file is an RGBA PNG (colour type 6)
whose R, G, B, A samples are tag, id low, id high, 255. ``cv2.IMREAD_UNCHANGED`` returns it as BGRA, PIL as
RGBA; ``split_instance`` takes either order. Both are encoded by ``png.encode_png`` (same pixels as OpenCV's
encoder wrote, several times faster).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from b2d_data.codecs._source import Source, read_source, write_bytes
from b2d_data.codecs.png import encode_png
from b2d_data.format.errors import B2DFormatError

ChannelOrder = Literal["BGRA", "RGBA", "BGR", "RGB"]

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _check_2d(arr: np.ndarray, what: str) -> None:
    if not isinstance(arr, np.ndarray) or arr.ndim != 2:
        got = f"{arr.dtype} {arr.shape}" if isinstance(arr, np.ndarray) else type(arr).__name__
        raise ValueError(f"{what} must be an (H, W) array, got {got}")


def _decode_png(source: Source, name: str | os.PathLike[str] | None) -> tuple[np.ndarray, Path]:
    data, label = read_source(source, name)
    if bytes(data[:8]) != _PNG_MAGIC:
        raise B2DFormatError(label, "not a PNG file")
    img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise B2DFormatError(label, "corrupt or truncated PNG: OpenCV could not decode it")
    return img, label


def encode_semantic_png(tags: np.ndarray) -> bytes:
    """Encode (H, W) uint8 CARLA semantic tag ids as a 1-channel PNG."""
    _check_2d(tags, "semantic tags")
    if tags.dtype != np.uint8:
        raise ValueError(f"semantic tags must be uint8, got {tags.dtype}")
    return encode_png(tags)


def write_semantic_png(path: str | os.PathLike[str], tags: np.ndarray) -> int:
    """Write a semantic PNG; returns the number of bytes written."""
    return write_bytes(path, encode_semantic_png(tags))


def read_semantic_png(source: Source, *, name: str | os.PathLike[str] | None = None) -> np.ndarray:
    """Decode a semantic PNG to (H, W) uint8 tag ids."""
    img, label = _decode_png(source, name)
    if img.ndim != 2 or img.dtype != np.uint8:
        raise B2DFormatError(label, f"semantic PNG must be 1-channel uint8 tag ids, got {img.dtype} shape {img.shape}")
    return img


def _instance_pixels(tags: np.ndarray, ids: np.ndarray, order: tuple[int, int, int, int]) -> np.ndarray:
    """(H, W, 4) uint8 of tag, id low byte, id high byte and 255, placed in the output channels ``order``."""
    _check_2d(tags, "instance tags")
    _check_2d(ids, "instance ids")
    if tags.shape != ids.shape:
        raise ValueError(f"instance tags {tags.shape} and ids {ids.shape} differ in shape")
    if tags.dtype != np.uint8:
        raise ValueError(f"instance tags must be uint8, got {tags.dtype}")
    if ids.dtype.kind not in "iu":
        raise ValueError(f"instance ids must be integers, got {ids.dtype}")
    if ids.dtype != np.uint16:
        if ids.size and (ids.min() < 0 or ids.max() > 0xFFFF):
            raise ValueError("instance ids must lie in [0, 65535] (two bytes on disk)")
        ids = ids.astype(np.uint16)
    if order == (0, 1, 2, 3):
        # File order is one little-endian word per pixel, tag | id << 8 | 255 << 24: three whole-array integer
        # operations, 2.5x faster than the channel shuffle below.
        word = ids.astype("<u4")
        word <<= 8
        word |= tags
        word |= np.uint32(0xFF000000)
        return word.view(np.uint8).reshape(tags.shape + (4,))
    id_bytes = np.ascontiguousarray(ids, dtype="<u2").view(np.uint8).reshape(ids.shape + (2,))  # low, high
    out = np.empty(tags.shape + (4,), np.uint8)
    tag, low, high, alpha = order
    # One pass of OpenCV's channel shuffle: ~5x faster than shifting and merging the planes.
    cv2.mixChannels([np.ascontiguousarray(tags), id_bytes, np.full_like(tags, 255)], [out],
                    [0, tag, 1, low, 2, high, 3, alpha])  # fmt: skip
    return out


def instance_bgra(tags: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """The (H, W, 4) uint8 BGRA array the collector hands to OpenCV: B = id >> 8, G = id & 255, R = tag, A = 255."""
    return _instance_pixels(tags, ids, (2, 1, 0, 3))


def instance_rgba(tags: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """The instance image in file order (R = tag, G = id & 255, B = id >> 8, A = 255), as PIL decodes it."""
    return _instance_pixels(tags, ids, (0, 1, 2, 3))


def encode_instance_png(tags: np.ndarray, ids: np.ndarray, *, packed: np.ndarray | None = None) -> bytes:
    """Encode semantic tags (uint8) and instance ids (uint16) as Bench2Drive's RGBA instance PNG.

    ``packed``: the same labels already in the file's pixel layout (``CameraFrame.labels``), encoded as they are.
    """
    if packed is None:
        return encode_png(instance_rgba(tags, ids))
    if packed.dtype != np.uint8 or packed.shape != (*np.shape(tags), 4):
        raise ValueError(f"packed labels must be (H, W, 4) uint8 like the tags {np.shape(tags)}, got "
                         f"{packed.dtype} {packed.shape}")  # fmt: skip
    return encode_png(packed)


def write_instance_png(
    path: str | os.PathLike[str], tags: np.ndarray, ids: np.ndarray, *, packed: np.ndarray | None = None
) -> int:
    """Write an instance PNG; returns the number of bytes written."""
    return write_bytes(path, encode_instance_png(tags, ids, packed=packed))


def split_instance(image: np.ndarray, order: ChannelOrder = "BGRA") -> tuple[np.ndarray, np.ndarray]:
    """Split an already decoded instance image into (tags uint8, ids uint16).

    ``order`` names the channel order of ``image``: ``BGRA``/``BGR`` as OpenCV returns it, ``RGBA``/``RGB``
    as PIL, imageio and most other readers return it. Alpha, when present, is ignored.
    """
    if image.ndim != 3 or image.shape[2] != len(order) or image.dtype != np.uint8:
        raise ValueError(f"{order} instance image must be (H, W, {len(order)}) uint8, got {image.dtype} {image.shape}")
    r, g, b = order.index("R"), order.index("G"), order.index("B")
    tags = np.ascontiguousarray(image[..., r])
    ids = (image[..., b].astype(np.uint16) << 8) | image[..., g]
    return tags, ids


def read_instance_png(source: Source, *, name: str | os.PathLike[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Decode an instance PNG (RGBA, or RGB without alpha) to (tags (H, W) uint8, ids (H, W) uint16)."""
    img, label = _decode_png(source, name)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (3, 4):
        raise B2DFormatError(label, f"instance PNG must be 8-bit RGB(A), got {img.dtype} shape {img.shape}")
    # Whoever wrote the file, OpenCV returns colour PNGs in B, G, R(, A) order.
    return split_instance(img, "BGRA" if img.shape[2] == 4 else "BGR")
