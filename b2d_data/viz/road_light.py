"""How well a camera image shows the road: luminance of the ego's lane ahead and the depth of sun shadows on it.

Used by ``scripts/weather_gallery.py`` to compare weathers at one place: the lane mask comes from the camera's own
planar depth and semantic image, so it is the same set of pixels under every weather.
"""

from __future__ import annotations

import numpy as np

from b2d_data.format.semantic import SemanticTag

#: Tags counted as road surface.
ROAD_TAGS = (int(SemanticTag.ROAD), int(SemanticTag.ROAD_LINE))


def luma(rgb: np.ndarray) -> np.ndarray:
    """Rec. 601 luma (the JPEG's Y) of 8-bit RGB pixels, as float."""
    return np.asarray(rgb[..., :3], np.float64) @ np.array([0.299, 0.587, 0.114])


def lane_ahead_mask(
    depth: np.ndarray,
    semantic: np.ndarray,
    intrinsic: np.ndarray,
    cam_to_ego: np.ndarray,
    near: float = 5.0,
    far: float = 30.0,
    half_width: float = 1.5,
) -> np.ndarray:
    """Road pixels whose ground point lies ``near``–``far`` m ahead of the ego and within ``half_width`` m of its
    centre line (ego frame: x forward, y right), from planar depth (m) and semantic tags."""
    h, w = depth.shape
    v, u = np.mgrid[0:h, 0:w]
    d = np.asarray(depth, np.float64)
    # OpenCV camera axes (x right, y down, z forward) → the camera's UE axes (x forward, y right, z up) → ego.
    right = (u + 0.5 - intrinsic[0, 2]) / intrinsic[0, 0] * d
    down = (v + 0.5 - intrinsic[1, 2]) / intrinsic[1, 1] * d
    points = np.stack([d, right, -down, np.ones_like(d)], axis=-1) @ np.asarray(cam_to_ego).T
    ahead, side = points[..., 0], points[..., 1]
    return (ahead >= near) & (ahead <= far) & (np.abs(side) <= half_width) & np.isin(semantic, ROAD_TAGS)


def shadow_contrast(lit: np.ndarray, shadowed: np.ndarray, road: np.ndarray, threshold: float = 0.05) -> tuple[float, int]:
    """Relative darkening (L_sun − L_shadow) / L_sun of the road pixels a shadow falls on, and how many there are.

    ``lit`` and ``shadowed`` are the same view rendered without and with shadows; a road pixel is in shadow when
    its luma drops by more than ``threshold`` of its sunlit value.
    """
    a, b = luma(lit), luma(shadowed)
    drop = (a - b) / np.maximum(a, 1.0)
    inside = road & (drop > threshold)
    n = int(inside.sum())
    if n == 0:
        return 0.0, 0
    return float(1.0 - b[inside].mean() / a[inside].mean()), n
