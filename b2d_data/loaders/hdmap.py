"""HD-map polylines near the ego, from Bench2Drive's ``<Town>_HD_map.npz`` (format.md §6).

The npz holds ``arr``: an object array of rows (road_id, road_dict); road_dict maps lane ids to lists of
elements {Points, Type, Color, ...} and ``Trigger_Volumes`` (docs spell it ``TriggerVolumes``) to stop-sign /
traffic-light polygons. A map is flattened once per process into one point array plus offsets, types and
per-polyline bounding boxes, so a radius query only touches nearby polylines.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from b2d_data.codecs.object_npz import load_object_npz
from b2d_data.format.errors import B2DFormatError

logger = logging.getLogger(__name__)

#: Map element types, as stored (lane-marking types, ``Center``) plus the two trigger-volume types.
MAP_TYPES: tuple[str, ...] = (
    "Center", "Broken", "Solid", "SolidSolid", "SolidBroken", "BrokenSolid", "BrokenBroken", "BottsDots",
    "Grass", "Curb", "Other", "NONE", "TrafficLight", "StopSign",
)  # fmt: skip
MAP_TYPE_ID: dict[str, int] = {name: i for i, name in enumerate(MAP_TYPES)}
_TRIGGER_KEYS = ("Trigger_Volumes", "TriggerVolumes")


def _xyz(point: object) -> tuple[float, float, float]:
    # Lane points are ((x, y, z), (roll, pitch, yaw)[, is_junction]); trigger points are [x, y, z].
    first = point[0]  # type: ignore[index]
    if isinstance(first, (list, tuple, np.ndarray)):
        point = first
    return float(point[0]), float(point[1]), float(point[2]) if len(point) > 2 else 0.0  # type: ignore[index, arg-type]


@dataclass
class HDMap:
    """A town's map elements as polylines in the CARLA world frame."""

    town: str
    points: np.ndarray  # (P, 3) float64
    offsets: np.ndarray  # (L + 1,) int64: polyline i is points[offsets[i]:offsets[i+1]]
    types: np.ndarray  # (L,) int16 index into MAP_TYPES
    bounds: np.ndarray  # (L, 4) float64 min x, min y, max x, max y

    @property
    def num_polylines(self) -> int:
        """Number of polylines (lane elements and trigger-volume polygons)."""
        return len(self.types)

    @classmethod
    def load(cls, path: str | os.PathLike[str], town: str | None = None) -> HDMap:
        """Read and flatten a ``<Town>_HD_map.npz``; errors name the file."""
        path = Path(path)
        town = town or path.name.split("_")[0]
        # The map is a pickle (Bench2Drive's layout), so it is read without letting it run code.
        rows = load_object_npz(path, "arr")
        try:
            roads = dict(rows)
        except (TypeError, ValueError) as exc:
            raise B2DFormatError(path, f"not a readable HD map npz: 'arr' is not (road id, road) rows: {exc}") from exc
        lines: list[np.ndarray] = []
        types: list[int] = []
        try:
            for road in roads.values():
                for lane_key, elements in road.items():
                    is_trigger = lane_key in _TRIGGER_KEYS
                    for element in elements:
                        pts = np.array([_xyz(p) for p in element["Points"]], dtype=np.float64).reshape(-1, 3)
                        if len(pts) < 2:
                            continue
                        if is_trigger:
                            pts = np.concatenate([pts, pts[:1]])  # close the polygon
                        kind = str(element.get("Type", "Other"))
                        lines.append(pts)
                        types.append(MAP_TYPE_ID.get(kind, MAP_TYPE_ID["Other"]))
        except (KeyError, TypeError, IndexError, ValueError, AttributeError) as exc:
            raise B2DFormatError(path, f"unexpected HD map layout: {exc!r}") from exc
        if not lines:
            return cls(town, np.zeros((0, 3)), np.zeros(1, np.int64), np.zeros(0, np.int16), np.zeros((0, 4)))
        offsets = np.zeros(len(lines) + 1, np.int64)
        offsets[1:] = np.cumsum([len(p) for p in lines])
        bounds = np.array([[p[:, 0].min(), p[:, 1].min(), p[:, 0].max(), p[:, 1].max()] for p in lines])
        return cls(town, np.concatenate(lines), offsets, np.array(types, np.int16), bounds)

    def query(self, center_xy: np.ndarray, radius: float) -> list[tuple[np.ndarray, int]]:
        """Polylines within ``radius`` metres of a CARLA-world (x, y): (points (n, 3), type id) pieces.

        Points farther than ``radius`` are dropped; a polyline leaving and re-entering the circle becomes
        several pieces, so no segment jumps across the gap.
        """
        cx, cy = float(center_xy[0]), float(center_xy[1])
        b = self.bounds
        near = np.nonzero(
            (b[:, 0] <= cx + radius) & (b[:, 2] >= cx - radius) & (b[:, 1] <= cy + radius) & (b[:, 3] >= cy - radius)
        )[0]
        out: list[tuple[np.ndarray, int]] = []
        r2 = radius * radius
        for i in near:
            pts = self.points[self.offsets[i] : self.offsets[i + 1]]
            inside = (pts[:, 0] - cx) ** 2 + (pts[:, 1] - cy) ** 2 <= r2
            if not inside.any():
                continue
            # Split into runs of consecutive inside points.
            edges = np.flatnonzero(np.diff(np.concatenate([[0], inside.astype(np.int8), [0]])))
            for start, stop in zip(edges[::2], edges[1::2], strict=True):
                if stop - start >= 2:
                    out.append((pts[start:stop], int(self.types[i])))
        return out


@lru_cache(maxsize=4)
def load_hdmap_cached(path: str) -> HDMap:
    """:meth:`HDMap.load` cached per process (a few towns at a time: large towns take hundreds of MB)."""
    return HDMap.load(path)


def find_hdmap(town: str, search_dirs: list[Path]) -> Path | None:
    """The first ``<Town>_HD_map.npz`` found in ``search_dirs``."""
    for folder in search_dirs:
        candidate = folder / f"{town}_HD_map.npz"
        if candidate.is_file():
            return candidate
    return None
