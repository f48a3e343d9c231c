"""Road surface height: z and slope under any (x, y), from the map's lane centre lines.

Built once from every lane's centre polyline (all lane types, so sidewalks count); a 3-D k-d tree query with
the actor's current z picks the right level where roads cross over each other.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

if TYPE_CHECKING:
    from b2d_data.maps import Map

log = logging.getLogger(__name__)

# Vertical distances weigh this much more than horizontal ones when picking the nearest surface sample,
# so that a bridge 6 m above a road is never confused with it.
_Z_WEIGHT = 4.0
# Farther than this from every lane centre there is no road: z is left as it is.
MAX_GROUND_DISTANCE = 15.0


class GroundModel:
    """Nearest-lane-centre height lookup with the slope along the lane."""

    def __init__(self, polylines: Iterable[np.ndarray]) -> None:
        points, slopes, directions = [], [], []
        for line in polylines:
            p = np.asarray(line, dtype=np.float64)
            if p.ndim != 2 or p.shape[0] < 2 or p.shape[1] < 3:
                continue
            d = np.diff(p, axis=0)
            run = np.hypot(d[:, 0], d[:, 1])
            ok = run > 1e-6
            if not ok.any():
                continue
            seg_slope = np.where(ok, d[:, 2] / np.where(ok, run, 1.0), 0.0)
            seg_dir = np.where(ok[:, None], d[:, :2] / np.where(ok, run, 1.0)[:, None], 0.0)
            # every sample gets the slope/direction of the segment that starts (or, for the last, ends) there
            slopes.append(np.concatenate([seg_slope, seg_slope[-1:]]))
            directions.append(np.concatenate([seg_dir, seg_dir[-1:]]))
            points.append(p[:, :3])
        if points:
            self._points = np.concatenate(points)
            self._slope = np.concatenate(slopes)
            self._direction = np.concatenate(directions)
            scaled = self._points * np.array([1.0, 1.0, _Z_WEIGHT])
            self._tree: cKDTree | None = cKDTree(scaled)
        else:
            self._points = np.zeros((0, 3))
            self._tree = None
        log.debug("ground model with %d surface samples", len(self._points))

    @property
    def empty(self) -> bool:
        """No road surface known (flat world at the given z)."""
        return self._tree is None

    def query(self, x: np.ndarray, y: np.ndarray, z: np.ndarray,
              yaw_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ground z, pitch in degrees along each heading, found mask) under n points.

        Where no lane centre is within :data:`MAX_GROUND_DISTANCE`, z is returned unchanged with pitch 0.
        """
        x, y, z = np.asarray(x, float), np.asarray(y, float), np.asarray(z, float)
        if self._tree is None or x.size == 0:
            return z.copy(), np.zeros_like(z), np.zeros(z.shape, dtype=bool)
        query = np.column_stack([x, y, z * _Z_WEIGHT])
        dist, idx = self._tree.query(query, k=1)
        near = self._points[idx]
        found = np.hypot(near[:, 0] - x, near[:, 1] - y) <= MAX_GROUND_DISTANCE
        # move along the lane direction to the point's own station: z follows the slope between samples
        d = self._direction[idx]
        along = (x - near[:, 0]) * d[:, 0] + (y - near[:, 1]) * d[:, 1]
        ground = near[:, 2] + self._slope[idx] * along
        yaw = np.radians(np.asarray(yaw_deg, float))
        cos_rel = np.cos(yaw) * d[:, 0] + np.sin(yaw) * d[:, 1]
        pitch = np.degrees(np.arctan(self._slope[idx] * cos_rel))
        return np.where(found, ground, z), np.where(found, pitch, 0.0), found


def ground_from_map(town: Map) -> GroundModel:
    """The ground model of a map: every lane's centre line from ``Map.lane_geometry()``."""
    return GroundModel(lane.centre for lane in town.lane_geometry(resolution=1.0))
