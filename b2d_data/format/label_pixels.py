"""Semantic tags and instance ids as views of one packed label image (format.md §2.3).

An instance PNG pixel holds the bytes (tag, id low byte, id high byte, 255). A renderer that writes its labels in
that layout reads back one (H, W, 4) uint8 array; :func:`label_views` gives the (H, W) tag and id arrays as views of
it (no copy), and :func:`packed_labels` recognises such a pair, so the instance PNG is encoded from the packed
array directly instead of being assembled again from the two planes.
"""

from __future__ import annotations

import numpy as np

#: The alpha byte of every packed pixel, as in the instance PNG.
OPAQUE = 0xFF


def label_views(packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(tags (H, W) uint8, ids (H, W) little-endian uint16), both views of a contiguous (H, W, 4) uint8 array."""
    if packed.dtype != np.uint8 or packed.ndim != 3 or packed.shape[2] != 4 or not packed.flags.c_contiguous:
        raise ValueError(f"packed labels must be a contiguous (H, W, 4) uint8 array, got {packed.dtype} {packed.shape}")
    h, w = packed.shape[:2]
    tags = packed[..., 0]
    ids = np.ndarray((h, w), dtype="<u2", buffer=packed, offset=1, strides=(4 * w, 4))
    return tags, ids


def packed_labels(tags: np.ndarray, ids: np.ndarray) -> np.ndarray | None:
    """The (H, W, 4) array ``tags`` and ``ids`` are :func:`label_views` of, if its alpha bytes are all 255; else None."""
    parent = tags.base
    if not (
        isinstance(parent, np.ndarray)
        and ids.base is parent
        and parent.dtype == np.uint8
        and parent.ndim == 3
        and parent.shape == (*tags.shape, 4)
        and parent.flags.c_contiguous
        and ids.dtype == np.dtype("<u2")
        and tags.strides == ids.strides == (parent.strides[0], 4)
        and tags.ctypes.data == parent.ctypes.data
        and ids.ctypes.data == parent.ctypes.data + 1
    ):
        return None
    # The views cannot show the alpha byte, so it is checked: one comparison per pixel, as whole 32-bit words.
    if not (parent.view("<u4") >= np.uint32(OPAQUE << 24)).all():
        return None
    return parent
