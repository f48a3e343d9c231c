"""Semantic tags and instance ids as views of one packed label image (format.md §2.3).

An instance PNG pixel holds the bytes (tag, id low byte, id high byte, 255). A renderer that writes its labels in
that layout reads back one (H, W, 4) uint8 array, which the instance PNG encoder takes as it is
(``CameraFrame.labels``); :func:`label_views` gives the (H, W) tag and id arrays as views of it (no copy).
"""

from __future__ import annotations

import numpy as np


def label_views(packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(tags (H, W) uint8, ids (H, W) little-endian uint16), both views of an (H, W, 4) uint8 array.

    Each row of ``packed`` must be contiguous; rows may lie apart (the renderer's PNG scanlines keep a filter byte in
    front of each row).
    """
    if packed.dtype != np.uint8 or packed.ndim != 3 or packed.shape[2] != 4 or packed.strides[1:] != (4, 1):
        raise ValueError(f"packed labels must be an (H, W, 4) uint8 array with contiguous rows, got {packed.dtype} "
                         f"{packed.shape} strides {packed.strides}")  # fmt: skip
    tags = packed[..., 0]
    ids = packed[..., 1:3].view("<u2")[..., 0]
    return tags, ids
