"""RGB images that are views of an RGBA array (as the renderer hands them over)."""

from __future__ import annotations

import numpy as np


def rgba_parent(rgb: np.ndarray) -> np.ndarray | None:
    """The contiguous (H, W, 4) uint8 array whose first three channels ``rgb`` is a view of, or ``None``.

    The renderer hands over RGB as such a view of the RGBA it read back: an encoder that can take RGBA drops the
    alpha in the conversion it makes anyway (OpenCV's RGBA → BGR, the GPU for nvJPEG) instead of after a copy.
    """
    base = rgb.base
    if (
        isinstance(base, np.ndarray)
        and base.dtype == np.uint8
        and base.shape == (*rgb.shape[:2], 4)
        and base.flags.c_contiguous
        and rgb.strides == base.strides
        and rgb.__array_interface__["data"][0] == base.__array_interface__["data"][0]
    ):
        return base
    return None
