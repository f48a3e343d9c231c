"""Gap acceptance across a flow that never yields: where the ego waits and when it goes (a deviation from PDM-Lite).

LB2.0's ActorFlow cars drive their lane at a constant speed and ignore the ego. A flow whose path crosses the route
(the oncoming flow of a left turn) leaves gaps the ego must take whole: PDM-Lite's forecast checks, run every tick
with boxes that grow once the ego drives faster than 5 m/s, accept a gap standing and refuse it a second later,
and the ego brakes where it then stands, on the flow's path (seed 97, SignalizedJunctionLeftTurn: struck while
standing there, after which the flow stopped for good, TickRuntime). Here, for a crossing flow's cars:

- the ego waits short of where its box would come within ``flow_hold_margin`` m of a crossing car's path (the
  *line*), as short of a red light's;
- it goes when its forecast at the target speed (the PDM-Lite ego forecast, real box) clears every crossing car's
  real box driven along its hinted path (the cars' own plan), each lengthened by ``flow_crossing_accept_time`` s
  of its speed at both ends;
- once braking would no longer stop it short of a crossing path it is committed and drives on: standing there it
  would be struck by this car or a later one (LB2.0's flow then stops for good), or stand in another flow's way
  (InterurbanAdvancedActorFlow 101150002 on Town100, seed 101: it braked in the junction for a crossing car and was
  struck from behind by the flow it was turning into);
- while such a flow is within reach the ego's target speed is at least the fastest crossing car's, within the speed
  limit and the junction cap (``Expert.run_step``): at 0.72 x 40 km/h it spent ~1.4 s on a left turn's oncoming lane,
  longer than any gap a 10 m/s flow 22-26 m apart leaves.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.forecasting import BoxTrack
from b2d_data.sim.api import ActorState, ScenarioHint

#: Spacing (m) of the path points the clearance is measured to (its error is at most half of it).
PATH_STEP = 0.25
#: Spacing (m) of the route poses checked for the line.
ROUTE_STEP = 0.2


@dataclass(frozen=True)
class Crossing:
    """One tick's outcome: the crossing cars, those to brake for, how far the ego may drive, whether committed."""

    cars: frozenset[int]
    blocking: tuple[int, ...] = ()
    line: float | None = None  # metres the ego's centre may still drive before its box nears a crossing path
    committed: bool = False


NO_CROSSING = Crossing(frozenset())


def densify(path: np.ndarray, step: float = PATH_STEP) -> np.ndarray:
    """The polyline ``path`` ((N, 2) x, y) resampled every ``step`` metres (its last point kept)."""
    path = np.asarray(path, dtype=np.float64)[:, :2]
    if path.shape[0] < 2:
        return path
    seg = np.hypot(*np.diff(path, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    at = np.append(np.arange(0.0, s[-1], step), s[-1])
    return np.stack([np.interp(at, s, path[:, 0]), np.interp(at, s, path[:, 1])], axis=1)


def box_clearance(centres: np.ndarray, yaws: np.ndarray, half: tuple[float, float], points: np.ndarray) -> np.ndarray:
    """Per box (M): the distance from a box of half extents ``half`` at ``centres`` (M, 2), headed ``yaws`` (M,)
    radians, to the nearest of ``points`` (P, 2); 0 for a point inside."""
    if points.shape[0] == 0:
        return np.full(centres.shape[0], np.inf)
    d = points[None, :, :] - centres[:, None, :2]
    c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
    along = np.abs(d[..., 0] * c + d[..., 1] * s) - half[0]
    across = np.abs(-d[..., 0] * s + d[..., 1] * c) - half[1]
    return np.hypot(np.maximum(along, 0.0), np.maximum(across, 0.0)).min(axis=1)


def line_distance(points: np.ndarray, headings_deg: np.ndarray, ego: ActorState, path: np.ndarray,
                  clearance: float) -> float | None:
    """Metres the ego's centre may still drive along the route ``points`` (from its current point, 1 per
    ``ROUTE_STEP`` m, with ``headings_deg``) before its box comes within ``clearance`` of ``path``; 0 when it
    already has, None when it does not within these points."""
    if points.shape[0] == 0 or path.shape[0] == 0:
        return None
    e = ego.bounding_box.extent
    yaws = np.radians(headings_deg)
    # the box centre sits bounding_box.location.x ahead of the actor origin
    centres = points[:, :2] + ego.bounding_box.location.x * np.stack([np.cos(yaws), np.sin(yaws)], axis=1)
    near = np.flatnonzero(box_clearance(centres, yaws, (e.x, e.y), path) < clearance)
    return None if near.size == 0 else float(near[0]) * ROUTE_STEP


def lengthened(track: BoxTrack, vehicle: ActorState, seconds: float) -> BoxTrack:
    """``track`` with the vehicle's real box, ``seconds`` of its current speed longer at each end."""
    e = vehicle.bounding_box.extent
    extent = np.array([e.x + seconds * vehicle.speed(), e.y, e.z])
    return BoxTrack(track.actor_id, track.centres, track.yaws, np.tile(extent, (track.centres.shape[0], 1)))


def crossing_cars(route_points: np.ndarray, route_headings: np.ndarray, ego: ActorState,
                  cars: Iterable[ActorState], paths: Mapping[int, np.ndarray],
                  clearance: float) -> dict[int, float]:
    """The cars whose path ahead comes within ``clearance`` m (plus the car's half width) of the ego's box driven
    along ``route_points``: id → the line distance for that car (see :func:`line_distance`)."""
    out: dict[int, float] = {}
    for car in cars:
        path = paths.get(car.id)
        if path is None or len(path) < 2:
            continue
        line = line_distance(route_points, route_headings, ego, densify(path),
                             car.bounding_box.extent.y + clearance)
        if line is not None:
            out[car.id] = line
    return out


def crossing_flow_paths(cfg: ExpertConfig, hints: Iterable[ScenarioHint]) -> dict[int, np.ndarray]:
    """The hinted paths of the flows that get this gap acceptance: those of ``cfg.flow_crossing_types`` (none while
    ``cfg.flow_crossing_gap`` is off)."""
    if not cfg.flow_crossing_gap:
        return {}
    return {k: v for h in hints if h.scenario_type in cfg.flow_crossing_types for k, v in h.paths.items()}
