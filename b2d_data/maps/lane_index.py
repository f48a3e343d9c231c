"""Nearest-lane lookup: one KD-tree of lane-centre samples per lane type, refined by projection.

``nearest`` returns the lane segment and road ``s`` of the point of a lane centre line closest (in 3-D, as CARLA)
to a query location, considering only lanes whose type is in a mask. The KD-tree proposes the nearest samples;
the exact answer is the best projection onto the polyline pieces around them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from b2d_data.maps.lane_types import LaneType
from b2d_data.maps.lanes import LaneSegment

#: Samples proposed by each KD-tree query before the exact projection.
CANDIDATES = 8


@dataclass
class _TypeTree:
    tree: cKDTree
    points: np.ndarray  # (N, 3)
    segment: np.ndarray  # (N,) segment index
    s: np.ndarray  # (N,) road s
    prev: np.ndarray  # (N,) row of the previous sample of the same segment (itself at the start)
    next: np.ndarray  # (N,) row of the next sample of the same segment (itself at the end)


class LaneIndex:
    """KD-trees over lane-centre samples, keyed by lane type."""

    def __init__(self, segments: list[LaneSegment]) -> None:
        by_type: dict[int, list[LaneSegment]] = {}
        for seg in segments:
            by_type.setdefault(int(seg.lane_type), []).append(seg)
        self._trees: dict[int, _TypeTree] = {}
        for lane_type, segs in by_type.items():
            points = np.concatenate([seg.data[:, :3] for seg in segs])
            counts = np.array([len(seg.s) for seg in segs])
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            rows = np.arange(len(points))
            first = np.repeat(starts, counts)
            last = np.repeat(starts + counts - 1, counts)
            self._trees[lane_type] = _TypeTree(
                cKDTree(points),
                points,
                np.repeat(np.array([seg.index for seg in segs]), counts),
                np.concatenate([seg.s for seg in segs]),
                np.maximum(rows - 1, first),
                np.minimum(rows + 1, last),
            )

    def nearest(self, point: np.ndarray, lane_type: int = LaneType.DRIVING) -> tuple[int, float, float] | None:
        """(segment index, road s, 3-D distance) of the closest lane centre of a type in ``lane_type``."""
        best: tuple[int, float, float] | None = None
        for key, t in self._trees.items():
            if not key & int(lane_type):
                continue
            k = min(CANDIDATES, len(t.points))
            _, rows = t.tree.query(point, k=k)
            rows = np.atleast_1d(rows)
            a = np.concatenate([t.prev[rows], rows])
            b = np.concatenate([rows, t.next[rows]])
            pa, pb = t.points[a], t.points[b]
            d = pb - pa
            dd = np.einsum("ij,ij->i", d, d)
            f = np.where(dd > 0, np.einsum("ij,ij->i", point - pa, d) / np.where(dd > 0, dd, 1.0), 0.0)
            f = np.clip(f, 0.0, 1.0)
            proj = pa + d * f[:, None]
            dist2 = np.einsum("ij,ij->i", proj - point, proj - point)
            i = int(np.argmin(dist2))
            dist = float(np.sqrt(dist2[i]))
            if best is None or dist < best[2]:
                s = float(t.s[a[i]] + (t.s[b[i]] - t.s[a[i]]) * f[i])
                best = (int(t.segment[a[i]]), s, dist)
        return best

    def nearest_many(
        self, points: np.ndarray, lane_type: int = LaneType.DRIVING
    ) -> list[tuple[int, float, float] | None]:
        """:meth:`nearest` of every row of an (n, 3) array, with one KD-tree query per lane type.

        The answers are :meth:`nearest`'s to the last bit: the same candidates, and the same element-wise
        arithmetic, with each dot product an ``einsum`` over the rows of an (m, 3) array as there.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = len(pts)
        best: list[tuple[int, float, float] | None] = [None] * n
        if n == 0:
            return best
        for key, t in self._trees.items():
            if not key & int(lane_type):
                continue
            k = min(CANDIDATES, len(t.points))
            _, rows = t.tree.query(pts, k=k)
            rows = np.asarray(rows).reshape(n, k)
            a = np.concatenate([t.prev[rows], rows], axis=1)  # (n, 2k): nearest's order, row by row
            b = np.concatenate([rows, t.next[rows]], axis=1)
            m = 2 * k
            pa, pb = t.points[a.ravel()], t.points[b.ravel()]  # (n·2k, 3)
            d = pb - pa
            dd = np.einsum("ij,ij->i", d, d)
            to_point = (pts[:, None, :] - pa.reshape(n, m, 3)).reshape(-1, 3)
            f = np.where(dd > 0, np.einsum("ij,ij->i", to_point, d) / np.where(dd > 0, dd, 1.0), 0.0)
            f = np.clip(f, 0.0, 1.0)
            proj = pa + d * f[:, None]
            off = (proj.reshape(n, m, 3) - pts[:, None, :]).reshape(-1, 3)
            dist2 = np.einsum("ij,ij->i", off, off).reshape(n, m)
            first = np.argmin(dist2, axis=1)  # the first of equal minima, as argmin on each row alone
            for q in range(n):
                i = int(first[q])
                dist = float(np.sqrt(dist2[q, i]))
                found = best[q]
                if found is None or dist < found[2]:
                    ai, bi = a[q, i], b[q, i]
                    s = float(t.s[ai] + (t.s[bi] - t.s[ai]) * f[q * m + i])
                    best[q] = (int(t.segment[ai]), s, dist)
        return best
