"""The per-frame expert vector (format.md §2.8) from the simulator snapshot: BEV raster, route progress, action.

The layout is :mod:`b2d_data.format.expert_feature`'s; this module fills it from what the data agent already holds
(the snapshot, the map, the dense route). It runs once per recorded frame, so everything is vectorised over boxes
and cells; the only per-town work (a KD-tree over driving-lane centre samples) is done once per map and cached.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from b2d_data.collection.annotations import is_static_vehicle
from b2d_data.format import expert_feature as ef
from b2d_data.format.expert_actions import nearest_action
from b2d_data.format.transform import BoundingBox, Location, Transform
from b2d_data.maps import LaneType, Map
from b2d_data.sim.api import ActorKind, ActorState, Snapshot, TrafficLightState

#: Lane-centre sampling step of the drivable-area lookup (m); the along-lane error of the test is at most half.
_LANE_STEP = 0.5
#: Actors and trigger volumes farther than this (2-D, from the ego) cannot reach the grid (corner 22.6 m + box).
_REACH = ef.HALF_RANGE * math.sqrt(2.0) + 15.0
_STOP_LIGHT_STATES = (TrafficLightState.RED, TrafficLightState.YELLOW)

# Ego-frame centres of the cells: x forward (rows, top = ahead), y right (columns).
_CELL_X = ef.HALF_RANGE - ef.CELL * (np.arange(ef.GRID) + 0.5)
_CELL_Y = -ef.HALF_RANGE + ef.CELL * (np.arange(ef.GRID) + 0.5)
_GRID_X, _GRID_Y = np.meshgrid(_CELL_X, _CELL_Y, indexing="ij")  # (16, 16) each, [row, col]

_DRIVABLE_CACHE: weakref.WeakKeyDictionary[Map, tuple[cKDTree, np.ndarray]] = weakref.WeakKeyDictionary()


def _drivable_lookup(world_map: Map) -> tuple[cKDTree, np.ndarray]:
    """(2-D KD-tree of driving-lane centre samples, their half widths), built once per map."""
    cached = _DRIVABLE_CACHE.get(world_map)
    if cached is None:
        lanes = world_map.lane_geometry(_LANE_STEP, LaneType.DRIVING)
        if lanes:
            points = np.concatenate([lane.centre[:, :2] for lane in lanes])
            half = 0.5 * np.concatenate([lane.width for lane in lanes])
        else:  # a map without driving lanes: nothing is drivable
            points, half = np.full((1, 2), np.inf), np.zeros(1)
        cached = (cKDTree(points), half)
        _DRIVABLE_CACHE[world_map] = cached
    return cached


def boxes_overlap_cells(centres: np.ndarray, yaws: np.ndarray, half_extents: np.ndarray) -> np.ndarray:
    """(16, 16) bool: cells whose open square overlaps one of the ego-frame rectangles (separating-axis test).

    ``centres`` (N, 2) x forward / y right, ``yaws`` (N,) radians relative to the ego, ``half_extents`` (N, 2).
    """
    if len(centres) == 0:
        return np.zeros((ef.GRID, ef.GRID), dtype=bool)
    h = ef.CELL / 2.0
    c, s = np.abs(np.cos(yaws))[:, None, None], np.abs(np.sin(yaws))[:, None, None]
    cos, sin = np.cos(yaws)[:, None, None], np.sin(yaws)[:, None, None]
    ex, ey = half_extents[:, 0, None, None], half_extents[:, 1, None, None]
    dx = centres[:, 0, None, None] - _GRID_X[None]
    dy = centres[:, 1, None, None] - _GRID_Y[None]
    # Four candidate separating axes: the cell's x and y, the box's length and width axes.
    apart = np.abs(dx) >= h + ex * c + ey * s
    apart |= np.abs(dy) >= h + ex * s + ey * c
    apart |= np.abs(dx * cos + dy * sin) >= ex + h * (c + s)
    apart |= np.abs(-dx * sin + dy * cos) >= ey + h * (c + s)
    return (~apart).any(axis=0)


def points_in_cells(points: np.ndarray) -> np.ndarray:
    """(16, 16) bool: cells holding at least one of the ego-frame points (N, 2)."""
    out = np.zeros((ef.GRID, ef.GRID), dtype=bool)
    if len(points) == 0:
        return out
    rows = np.floor((ef.HALF_RANGE - points[:, 0]) / ef.CELL).astype(np.int64)
    cols = np.floor((points[:, 1] + ef.HALF_RANGE) / ef.CELL).astype(np.int64)
    inside = (rows >= 0) & (rows < ef.GRID) & (cols >= 0) & (cols < ef.GRID)
    out[rows[inside], cols[inside]] = True
    return out


class BevRasterizer:
    """Builds the 6 × 16 × 16 raster of :mod:`b2d_data.format.expert_feature` for one town."""

    def __init__(self, world_map: Map) -> None:
        self.map = world_map
        self._tree, self._half_width = _drivable_lookup(world_map)

    def raster(self, snapshot: Snapshot, ego: ActorState, route_xy: np.ndarray) -> np.ndarray:
        """The raster around ``ego`` at ``snapshot``; ``route_xy`` (M, 2) are the next route points (world)."""
        ex, ey = ego.location.x, ego.location.y
        yaw = math.radians(ego.transform.rotation.yaw)
        cy, sy = math.cos(yaw), math.sin(yaw)

        def to_ego(xy: np.ndarray) -> np.ndarray:
            d = np.asarray(xy, dtype=np.float64).reshape(-1, 2) - (ex, ey)
            return np.column_stack([cy * d[:, 0] + sy * d[:, 1], -sy * d[:, 0] + cy * d[:, 1]])

        out = np.zeros(ef.SHAPE, dtype=np.float32)
        # Drivable: cell centres (world) against the nearest driving-lane centre sample.
        world = np.column_stack([
            (ex + cy * _GRID_X - sy * _GRID_Y).ravel(), (ey + sy * _GRID_X + cy * _GRID_Y).ravel()
        ])  # fmt: skip
        dist, idx = self._tree.query(world, k=1)
        half = self._half_width[np.minimum(idx, len(self._half_width) - 1)]
        out[ef.DRIVABLE] = (dist <= half).reshape(ef.GRID, ef.GRID)
        out[ef.ROUTE] = points_in_cells(to_ego(route_xy))

        boxes: dict[int, list[tuple[float, float, float, float, float]]] = {ef.VEHICLES: [], ef.WALKERS: []}
        for actor in snapshot.actors.values():
            if actor.id == ego.id or actor.parent_id is not None:
                continue
            if actor.kind is ActorKind.VEHICLE or is_static_vehicle(actor):
                channel = ef.VEHICLES
            elif actor.kind is ActorKind.WALKER:
                channel = ef.WALKERS
            else:
                continue
            loc = actor.location
            if abs(loc.x - ex) > _REACH or abs(loc.y - ey) > _REACH:
                continue
            boxes[channel].append(_world_box(actor.transform, actor.bounding_box))
        stops = [
            _world_box(light.transform, light.trigger_volume)
            for light in snapshot.traffic_lights.values()
            if light.state in _STOP_LIGHT_STATES and _near(light.transform.location, ex, ey)
        ]
        stops += [
            _world_box(sign.transform, sign.trigger_volume)
            for sign in snapshot.traffic_signs.values()
            if sign.type_id.startswith("traffic.stop") and _near(sign.transform.location, ex, ey)
        ]
        for channel, rows in ((ef.VEHICLES, boxes[ef.VEHICLES]), (ef.WALKERS, boxes[ef.WALKERS]), (ef.STOP, stops)):
            if rows:
                arr = np.asarray(rows, dtype=np.float64)
                out[channel] = boxes_overlap_cells(to_ego(arr[:, :2]), arr[:, 2] - yaw, arr[:, 3:5])
        out[ef.SPEED] = min(max(ego.forward_speed() / ef.SPEED_SCALE, 0.0), 1.0)
        return out


def _near(location: Location, ex: float, ey: float) -> bool:
    return abs(location.x - ex) <= _REACH and abs(location.y - ey) <= _REACH


def _world_box(transform: Transform, box: BoundingBox) -> tuple[float, float, float, float, float]:
    """(centre x, centre y, yaw rad, half length, half width) of a box given in an actor's frame (2-D)."""
    loc, bl = transform.location, box.location
    yaw = math.radians(transform.rotation.yaw)
    c, s = math.cos(yaw), math.sin(yaw)
    return (
        loc.x + c * bl.x - s * bl.y,
        loc.y + s * bl.x + c * bl.y,
        yaw + math.radians(box.rotation.yaw),
        box.extent.x,
        box.extent.y,
    )


def assessment_vector(
    rasterizer: BevRasterizer, snapshot: Snapshot, ego: ActorState, route_xy: np.ndarray, progress: float,
    anno: Mapping[str, Any],
) -> np.ndarray:
    """The 1538-long vector of one frame; the action is the one nearest to the annotation's applied control."""
    action = nearest_action(
        float(anno["throttle"]), float(anno["steer"]), float(anno["brake"]), bool(anno["reverse"])
    )
    raster = rasterizer.raster(snapshot, ego, route_xy)
    return ef.assemble_vector(raster, min(max(progress, 0.0), 1.0), action)
