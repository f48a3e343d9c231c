"""RGB images that are views of an RGBA array (as the renderer hands them over)."""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import as_strided


def rgba_parent(rgb: np.ndarray) -> np.ndarray | None:
    """The contiguous (H, W, 4) uint8 pixels whose first three channels ``rgb`` is a view of, or ``None``.

    The renderer hands over RGB as such a view of the RGBA it read back: an encoder that can take RGBA drops the
    alpha in the conversion it makes anyway (OpenCV's RGBA → BGR, the GPU for nvJPEG) instead of after a copy. A
    frame's cameras share one block of read-back memory, so the view's ``base`` is that block; the camera's RGBA is
    rebuilt from the view's own strides once its extent is checked to lie in the block.
    """
    base = rgb.base
    if not (isinstance(base, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3 and rgb.shape[2] == 3):
        return None
    h, w = rgb.shape[:2]
    start = rgb.__array_interface__["data"][0]
    if (
        base.flags.c_contiguous
        and rgb.strides == (4 * w, 4, 1)
        and base.ctypes.data <= start
        and start + 4 * h * w <= base.ctypes.data + base.nbytes
    ):
        return as_strided(rgb, (h, w, 4), rgb.strides)
    return None
