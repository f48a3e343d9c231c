"""Bounding-volume hierarchies of triangle meshes as flat arrays, for the GPU ray caster (``gpu_raycast.py``).

The tree is implicit: a complete binary tree over a power-of-two number of leaves, stored heap-style (node k has
children 2k + 1 and 2k + 2; the leaves are the last ``leaves`` nodes). Each leaf holds a run of consecutive
triangle rows. Leaves are ordered along a Morton curve so that neighbouring leaves are near each other and the boxes
of inner nodes stay small. Built in a few numpy passes: the static town once, the actors every tick.

Boxes are padded by a millimetre (plus a relative margin), so a ray that hits a triangle on its very border also
enters every box around it whatever the rounding; the triangle test alone decides the hit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Triangles per leaf at most.
LEAF_SIZE = 4
#: Box padding: absolute (m) and relative to the coordinates' magnitude.
PAD_ABS = 1e-3
PAD_REL = 1e-6
#: Corner of the boxes of empty nodes: far outside any scene, so every slab test rejects them.
FAR = np.float32(1e30)


@dataclass
class Bvh:
    """A flattened tree over a mesh.

    ``nodes`` (2 · leaves − 1, 2, 4) float32: per node the box minimum (xyz) and maximum (xyz); in a leaf the
    minimum's w holds its first triangle row and the maximum's w its triangle count (uint32 bits).
    ``triangles`` (T, 3, 4) float32 rows: vertex 0 and the edges v1 − v0, v2 − v0 of each triangle.
    ``order`` (T,) int64: the mesh triangle of each row.
    """

    nodes: np.ndarray
    triangles: np.ndarray
    order: np.ndarray

    @property
    def leaves(self) -> int:
        """Leaf count (a power of two; 0 for an empty tree)."""
        return (len(self.nodes) + 1) // 2 if len(self.nodes) else 0


def _morton(points: np.ndarray) -> np.ndarray:
    """30-bit Morton codes of points (10 bits per axis over their bounding box)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    cells = ((points - lo) / np.maximum(hi - lo, 1e-9) * 1023.0).astype(np.uint32)
    code = np.zeros(len(points), np.uint32)
    for axis in range(3):
        code |= _spread(cells[:, axis]) << np.uint32(axis)
    return code


#: (shift, mask) steps moving bit b of a 10-bit number to bit 3·b (the "part 1 by 2" of Morton codes).
_SPREAD = ((16, 0x030000FF), (8, 0x0300F00F), (4, 0x030C30C3), (2, 0x09249249))


def _spread(x: np.ndarray) -> np.ndarray:
    """The low 10 bits of uint32 ``x`` spread two zero bits apart (four shifts, not a pass per bit)."""
    x = x & np.uint32(0x3FF)
    for shift, mask in _SPREAD:
        x = (x | (x << np.uint32(shift))) & np.uint32(mask)
    return x


def _runs(keys: np.ndarray, limit: int) -> np.ndarray:
    """Start rows of runs of equal consecutive ``keys``, each run cut into pieces of at most ``limit`` rows."""
    n = len(keys)
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    ends = np.r_[starts[1:], n]
    pieces = -(-(ends - starts) // limit)
    offset = np.arange(int(pieces.sum())) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    return np.repeat(starts, pieces) + offset * limit


def build_bvh(vertices: np.ndarray, groups: np.ndarray | None = None, leaf_size: int = LEAF_SIZE) -> Bvh:
    """The tree over (T, 3, 3) triangles.

    Without ``groups`` the triangles are sorted along a Morton curve of their centroids and cut into leaves of
    ``leaf_size`` (the static town, built once). With ``groups`` (one key per triangle, e.g. the actor id) the
    triangles keep their order and each leaf takes a piece of a run of equal keys, so that no leaf spans two actors;
    only the leaves are then sorted (cheap enough for every tick).
    """
    v = np.ascontiguousarray(vertices, np.float32).reshape(-1, 3, 3)
    t = len(v)
    if t == 0:
        return Bvh(np.zeros((0, 2, 4), np.float32), np.zeros((0, 3, 4), np.float32), np.zeros(0, np.int64))
    if groups is None:
        order = np.argsort(_morton(v.mean(axis=1)), kind="stable")
        v = v[order]
        starts = np.arange(0, t, leaf_size)
    else:
        order = np.arange(t)
        starts = _runs(np.asarray(groups), leaf_size)
    counts = np.diff(np.r_[starts, t])
    # Element-wise over the three vertices: a reduction over the short middle axis costs several times more.
    lo = np.minimum.reduceat(np.minimum(np.minimum(v[:, 0], v[:, 1]), v[:, 2]), starts, axis=0)
    hi = np.maximum.reduceat(np.maximum(np.maximum(v[:, 0], v[:, 1]), v[:, 2]), starts, axis=0)
    if groups is not None and len(starts) > 1:
        leaf_order = np.argsort(_morton((lo + hi) * 0.5), kind="stable")
        starts, counts, lo, hi = starts[leaf_order], counts[leaf_order], lo[leaf_order], hi[leaf_order]
    pad = PAD_ABS + PAD_REL * np.maximum(np.abs(lo), np.abs(hi))
    lo, hi = lo - pad, hi + pad

    n_leaves = len(starts)
    size = 1 << max(0, int(n_leaves - 1).bit_length())
    level_lo = np.full((size, 3), np.inf, np.float32)
    level_hi = np.full((size, 3), -np.inf, np.float32)
    level_lo[:n_leaves], level_hi[:n_leaves] = lo, hi
    nodes = np.zeros((2 * size - 1, 2, 4), np.float32)
    leaf_data = np.zeros((size, 2), np.uint32)
    leaf_data[:n_leaves, 0], leaf_data[:n_leaves, 1] = starts, counts
    nodes[size - 1 :, :, 3] = leaf_data.view(np.float32)
    first = size - 1
    while True:
        nodes[first : first + len(level_lo), 0, :3] = level_lo
        nodes[first : first + len(level_lo), 1, :3] = level_hi
        if first == 0:
            break
        level_lo = np.minimum(level_lo[0::2], level_lo[1::2])
        level_hi = np.maximum(level_hi[0::2], level_hi[1::2])
        first = (first - 1) // 2
    empty = ~np.isfinite(nodes[:, 0, 0])
    nodes[empty, :, :3] = FAR

    tris = np.zeros((t, 3, 4), np.float32)
    tris[:, :, :3] = v
    tris[:, 1:, :3] -= v[:, :1]
    return Bvh(nodes, tris, order)
