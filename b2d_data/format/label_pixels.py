"""Semantic tags and instance ids as views of one packed label image (format.md §2.3).

An instance PNG pixel holds the bytes (tag, id low byte, id high byte, 255). A renderer that writes its labels in
that layout reads back one (H, W, 4) uint8 array, which the instance PNG encoder takes as it is
(``CameraFrame.labels``); :func:`label_views` gives the (H, W) tag and id arrays as views of it (no copy).
"""

from __future__ import annotations

import numpy as np


def label_views(packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(tags (H, W) uint8, ids (H, W) little-endian uint16), both views of a contiguous (H, W, 4) uint8 array."""
    if packed.dtype != np.uint8 or packed.ndim != 3 or packed.shape[2] != 4 or not packed.flags.c_contiguous:
        raise ValueError(f"packed labels must be a contiguous (H, W, 4) uint8 array, got {packed.dtype} {packed.shape}")
    h, w = packed.shape[:2]
    tags = packed[..., 0]
    ids = np.ndarray((h, w), dtype="<u2", buffer=packed, offset=1, strides=(4 * w, 4))
    return tags, ids
