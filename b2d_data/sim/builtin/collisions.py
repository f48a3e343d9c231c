"""Oriented-box overlap between actors: a distance broad phase and a separating-axis narrow phase.

Actors stand upright (pitch and roll are small on roads), so two boxes overlap when their footprints
overlap — a 2-D separating-axis test on the four edge normals — and their height intervals overlap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

# Above this many boxes a k-d tree finds the candidate pairs; below it the all-pairs test is cheaper.
_KDTREE_MIN_BOXES = 96


@dataclass
class Boxes:
    """n upright oriented boxes in the world: footprint centre, yaw (rad), half extents, height interval."""

    cx: np.ndarray
    cy: np.ndarray
    yaw: np.ndarray
    hx: np.ndarray
    hy: np.ndarray
    z_low: np.ndarray
    z_high: np.ndarray

    def __len__(self) -> int:
        return int(self.cx.shape[0])

    @property
    def radius(self) -> np.ndarray:
        """Radius of each footprint's circumscribed circle."""
        return np.hypot(self.hx, self.hy)

    @classmethod
    def from_rows(cls, rows: list[tuple[float, float, float, float, float, float, float]]) -> Boxes:
        """Build from (cx, cy, yaw, hx, hy, z_low, z_high) tuples."""
        a = np.asarray(rows, dtype=np.float64).reshape(-1, 7)
        return cls(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], a[:, 5], a[:, 6])


def candidate_pairs(boxes: Boxes) -> np.ndarray:
    """(m, 2) index pairs i < j whose circumscribed circles intersect (the broad phase)."""
    n = len(boxes)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    radius = boxes.radius
    if n >= _KDTREE_MIN_BOXES:
        tree = cKDTree(np.column_stack([boxes.cx, boxes.cy]))
        pairs = tree.query_pairs(r=2.0 * float(radius.max()), output_type="ndarray")
        if pairs.size == 0:
            return np.zeros((0, 2), dtype=np.int64)
        i, j = pairs[:, 0], pairs[:, 1]
    else:
        i, j = np.triu_indices(n, k=1)
    d2 = (boxes.cx[i] - boxes.cx[j]) ** 2 + (boxes.cy[i] - boxes.cy[j]) ** 2
    keep = d2 <= (radius[i] + radius[j]) ** 2
    out = np.column_stack([i[keep], j[keep]]).astype(np.int64)
    # a stable order keeps event lists deterministic whatever the broad phase returned
    return out[np.lexsort((out[:, 1], out[:, 0]))] if out.size else out


def overlap(a: Boxes, ia: np.ndarray, b: Boxes, ib: np.ndarray) -> np.ndarray:
    """Boolean mask: does box ``a[ia[k]]`` overlap box ``b[ib[k]]`` (separating-axis test + heights)."""
    if ia.size == 0:
        return np.zeros(0, dtype=bool)
    ca, sa = np.cos(a.yaw[ia]), np.sin(a.yaw[ia])
    cb, sb = np.cos(b.yaw[ib]), np.sin(b.yaw[ib])
    dx, dy = b.cx[ib] - a.cx[ia], b.cy[ib] - a.cy[ia]
    hxa, hya, hxb, hyb = a.hx[ia], a.hy[ia], b.hx[ib], b.hy[ib]
    separated = np.zeros(ia.shape[0], dtype=bool)
    # axes: a's x (ca, sa), a's y (−sa, ca), b's x (cb, sb), b's y (−sb, cb)
    for ux, uy in ((ca, sa), (-sa, ca), (cb, sb), (-sb, cb)):
        ra = hxa * np.abs(ux * ca + uy * sa) + hya * np.abs(-ux * sa + uy * ca)
        rb = hxb * np.abs(ux * cb + uy * sb) + hyb * np.abs(-ux * sb + uy * cb)
        separated |= np.abs(ux * dx + uy * dy) > ra + rb
    heights_apart = (a.z_high[ia] < b.z_low[ib]) | (b.z_high[ib] < a.z_low[ia])
    return ~(separated | heights_apart)


def overlapping_pairs(boxes: Boxes, pair_allowed: np.ndarray | None = None) -> np.ndarray:
    """(m, 2) pairs i < j of overlapping boxes; ``pair_allowed(i, j)`` masks may drop pairs first.

    ``pair_allowed`` is a boolean (n, n) matrix (True where the pair may collide), or None for all pairs.
    """
    pairs = candidate_pairs(boxes)
    if pairs.size == 0:
        return pairs
    if pair_allowed is not None:
        pairs = pairs[pair_allowed[pairs[:, 0], pairs[:, 1]]]
    hit = overlap(boxes, pairs[:, 0], boxes, pairs[:, 1])
    return pairs[hit]


def overlaps_any(box: Boxes, others: Boxes) -> np.ndarray:
    """Indices of ``others`` that the single box ``box`` overlaps."""
    n = len(others)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    d2 = (others.cx - box.cx[0]) ** 2 + (others.cy - box.cy[0]) ** 2
    near = np.nonzero(d2 <= (others.radius + box.radius[0]) ** 2)[0]
    hit = overlap(box, np.zeros(near.shape[0], dtype=np.int64), others, near)
    return near[hit]
