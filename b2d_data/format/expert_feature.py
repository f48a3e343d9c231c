"""The expert vector b2d-data writes (format.md §2.8): a BEV raster, route progress and a Think2Drive action index.

A released Bench2Drive clip stores Think2Drive's 1536-d latent feature; b2d-data stores, in the same 1536 slots, a
privileged bird's-eye-view raster of the ego's surroundings that a student can distill from. The layout is
recorded in the clip's ``b2d_format.json`` (key ``expert_feature``, :func:`layout_record`); readers reshape the
feature only when that record says it is this raster (:func:`is_bev_record`).

Vector (float32, length 1538): ``[:1536]`` the raster flattened in C order (channel, row, col); ``[-2]`` the route
progress in [0, 1] (index of the dense-route point nearest the ego / (route points − 1)); ``[-1]`` the index of the
action nearest to the control the ego applies at the frame — the expert's, as the annotation's ``throttle``,
``steer``, ``brake``, ``reverse`` record it (:func:`b2d_data.format.expert_actions.nearest_action`).

Raster: 6 channels × 16 rows × 16 columns of 2 m cells, centred on the ego's origin, in the CARLA ego frame (x
forward, y right) turned by the ego's yaw only. Row 0 is the farthest ahead (row ``r`` covers forward distances
(16 − 2(r + 1), 16 − 2r] m); column 0 is the farthest left (column ``c`` covers rightward distances
[−16 + 2c, −16 + 2(c + 1)) m) — a top-down image with the ego heading up. Channels (values 0 or 1 unless said):

== ============ =====================================================================================================
 0  drivable    the cell centre lies within half a lane width of a driving lane's centre line
 1  route       the cell holds one of the next 50 points of the dense 1 m route, from the point nearest the ego
 2  vehicles    the cell overlaps the footprint of another vehicle (parked-car props included; not the ego)
 3  walkers     the cell overlaps the footprint of a pedestrian
 4  stop        the cell overlaps the trigger volume of a red or yellow traffic light or of a stop sign
 5  speed       the ego's forward speed / 25 m/s, clipped to [0, 1], in every cell
== ============ =====================================================================================================

"Overlaps" is an exact rectangle–rectangle test (the cell's open square against the box's footprint), so a box that
only touches a cell edge does not light the neighbouring cell.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

#: Name and version of this layout in ``b2d_format.json`` (bump the version when the layout changes).
FEATURE_NAME = "b2d-bev-raster"
FEATURE_VERSION = 1
#: Channel names, in raster order.
CHANNELS: tuple[str, ...] = ("drivable", "route", "vehicles", "walkers", "stop", "speed")
GRID = 16  # rows = columns
CELL = 2.0  # metres
HALF_RANGE = GRID * CELL / 2.0  # 16 m from the ego to each edge
SPEED_SCALE = 25.0  # m/s for a speed channel of 1
SHAPE: tuple[int, int, int] = (len(CHANNELS), GRID, GRID)
FEATURE_LENGTH = len(CHANNELS) * GRID * GRID  # 1536, the length of Think2Drive's latent
VECTOR_LENGTH = FEATURE_LENGTH + 2
#: What ``vector[-2]`` means in b2d-data clips.
VALUE_MEANING = "route_progress"

DRIVABLE, ROUTE, VEHICLES, WALKERS, STOP, SPEED = range(len(CHANNELS))


def layout_record() -> dict[str, object]:
    """The ``expert_feature`` entry of ``b2d_format.json`` describing this layout."""
    return {
        "name": FEATURE_NAME,
        "version": FEATURE_VERSION,
        "shape": list(SHAPE),
        "order": "C (channel, row, col)",
        "channels": list(CHANNELS),
        "cell_m": CELL,
        "frame": "CARLA ego (x forward, y right), ego origin at the grid centre, yaw only",
        "rows": "row 0 farthest ahead",
        "cols": "col 0 farthest left",
        "speed_scale_mps": SPEED_SCALE,
        "value": VALUE_MEANING,
        "action": "think2drive-39 nearest to the applied control",
    }


def is_bev_record(record: Mapping[str, object] | None) -> bool:
    """Whether a ``b2d_format.json`` ``expert_feature`` entry describes this raster (name, version and shape)."""
    if not record:
        return False
    return (
        record.get("name") == FEATURE_NAME
        and record.get("version") == FEATURE_VERSION
        and list(record.get("shape") or ()) == list(SHAPE)  # type: ignore[call-overload]
    )


def cell_of(x_forward: float, y_right: float) -> tuple[int, int] | None:
    """(row, col) of the cell holding an ego-frame point, or None outside the grid."""
    row = int(np.floor((HALF_RANGE - x_forward) / CELL))
    col = int(np.floor((y_right + HALF_RANGE) / CELL))
    if 0 <= row < GRID and 0 <= col < GRID:
        return row, col
    return None


def assemble_vector(raster: np.ndarray, value: float, action: int) -> np.ndarray:
    """The 1538-long float32 vector: flattened raster, value, action index."""
    raster = np.asarray(raster, dtype=np.float32)
    if raster.shape != SHAPE:
        raise ValueError(f"the BEV raster must have shape {SHAPE}, got {raster.shape}")
    out = np.empty(VECTOR_LENGTH, dtype=np.float32)
    out[:FEATURE_LENGTH] = raster.reshape(-1)
    out[-2] = value
    out[-1] = action
    return out


def unflatten(feature: np.ndarray) -> np.ndarray:
    """The (6, 16, 16) raster of a 1536-long feature (a view when possible)."""
    arr = np.asarray(feature)
    if arr.shape != (FEATURE_LENGTH,):
        raise ValueError(f"a BEV feature has {FEATURE_LENGTH} values, got shape {arr.shape}")
    return arr.reshape(SHAPE)
