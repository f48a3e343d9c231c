"""Oriented 3D boxes and the separating-axis overlap test PDM-Lite uses for its forecasts (§1.6).

Two boxes are disjoint when some axis separates their projections; for boxes the 15 candidates are the 3 face
normals of each box and the 9 cross products of their edge directions. Everything is vectorised over pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from b2d_data.format.transform import rotation_matrix


@dataclass(frozen=True)
class OrientedBox:
    """A box: world ``center`` (3,), half ``extent`` (3,), and ``axes`` (3, 3) whose rows are its unit x, y, z."""

    center: np.ndarray
    extent: np.ndarray
    axes: np.ndarray

    @classmethod
    def from_yaw(cls, center: np.ndarray | tuple[float, float, float], extent: np.ndarray | tuple[float, float, float],
                 yaw_deg: float, pitch_deg: float = 0.0, roll_deg: float = 0.0) -> OrientedBox:
        """Box with CARLA angles in degrees (the rotation's columns are the box axes)."""
        r = rotation_matrix(pitch_deg, yaw_deg, roll_deg)
        return cls(np.asarray(center, dtype=np.float64), np.asarray(extent, dtype=np.float64), r.T.copy())

    def corners_2d(self) -> np.ndarray:
        """The 4 footprint corners (x, y), for plots and tests."""
        signs = np.array([(1, 1), (1, -1), (-1, -1), (-1, 1)], dtype=np.float64)
        offsets = signs[:, :1] * self.extent[0] * self.axes[0] + signs[:, 1:] * self.extent[1] * self.axes[1]
        return (self.center + offsets)[:, :2]


def yaw_axes(yaw_rad: np.ndarray) -> np.ndarray:
    """Axes (..., 3, 3) of yaw-only boxes for an array of yaws in radians (rows: forward, right, up)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    zero, one = np.zeros_like(c), np.ones_like(c)
    forward = np.stack([c, s, zero], axis=-1)
    right = np.stack([-s, c, zero], axis=-1)  # CARLA's frame: y is right of x
    up = np.stack([zero, zero, one], axis=-1)
    return np.stack([forward, right, up], axis=-2)


def overlap_many(center_a: np.ndarray, axes_a: np.ndarray, extent_a: np.ndarray,
                 center_b: np.ndarray, axes_b: np.ndarray, extent_b: np.ndarray) -> np.ndarray:
    """Boolean (...,) array: do boxes a[k] and b[k] overlap? Shapes: centers (..., 3), axes (..., 3, 3)."""
    d = center_b - center_a
    cross = np.cross(axes_a[..., :, None, :], axes_b[..., None, :, :])  # (..., 3, 3, 3)
    cross = cross.reshape(cross.shape[:-3] + (9, 3))
    candidates = np.concatenate([axes_a, axes_b, cross], axis=-2)  # (..., 15, 3)
    # projection of d and of each box's half extents onto every candidate axis
    dist = np.abs(np.einsum("...j,...kj->...k", d, candidates))
    proj_a = np.abs(np.einsum("...ij,...kj->...ki", axes_a, candidates)) @ extent_a[..., :, None]
    proj_b = np.abs(np.einsum("...ij,...kj->...ki", axes_b, candidates)) @ extent_b[..., :, None]
    separated = dist > proj_a[..., 0] + proj_b[..., 0]
    return ~np.any(separated, axis=-1)


def boxes_overlap(a: OrientedBox, b: OrientedBox) -> bool:
    """True when the two boxes intersect (touching counts as intersecting)."""
    return bool(overlap_many(a.center, a.axes, a.extent, b.center, b.axes, b.extent))
