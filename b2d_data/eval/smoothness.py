"""Driving smoothness ("comfort") from per-route ``metric_info.json`` files (format.md §8.6).

The agent writes ``<metric dir>/<save_name>/metric_info.json``: an object keyed by step (one per 20 Hz
tick) whose values hold ``acceleration`` [m/s², world], ``angular_velocity`` [**deg/s**, CARLA's actor API],
``forward_vector``, ``right_vector``, ``location`` and ``rotation``. A route is cut into consecutive
20-step chunks (an incomplete last chunk is dropped; a route of ≤ 20 steps is one chunk); each chunk
passes when nuPlan's six comfort bounds hold on Savitzky–Golay-smoothed signals (window 7, order 2).
The route's smoothness is the fraction of passing chunks, the result set's the mean over routes (×100).

Two modes:

* ``bench2drive`` (default) reproduces tools/efficiency_smoothness_benchmark.py with its quirks: the
  deg/s angular velocity is compared with rad/s bounds (after a 2π "phase unwrap" meant for angles),
  derivatives use Δt = 0.1 s although samples are 0.05 s apart, and the "yaw acceleration" checked is the
  smoothed yaw *rate*, not its derivative.
* ``corrected`` converts the angular velocity to rad/s, uses the real sample interval (0.05 s by
  default) and checks the derivative of the smoothed yaw rate as yaw acceleration. Reported separately
  as ``smoothness_corrected``; it is *not* comparable with published Bench2Drive numbers.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.leaderboard import RouteRecord
from b2d_data.format.names import is_safe_name

# nuPlan comfort bounds as Bench2Drive uses them.
MAX_ABS_MAG_JERK = 8.37  # m/s³
MAX_ABS_LAT_ACCEL = 4.89  # m/s²
MAX_LON_ACCEL = 2.40  # m/s²
MIN_LON_ACCEL = -4.05  # m/s²
MAX_ABS_YAW_ACCEL = 1.93  # rad/s²
MAX_ABS_LON_JERK = 4.13  # m/s³
MAX_ABS_YAW_RATE = 0.95  # rad/s

WINDOW = 7
POLY_ORDER = 2
CHUNK_STEPS = 20
#: Δt Bench2Drive's tool differentiates with.
BENCH2DRIVE_DT = 0.1
#: The real interval between metric_info steps (the agent records every 20 Hz tick).
TICK_DT = 0.05

METRIC_FILE = "metric_info.json"
_FIELDS = ("acceleration", "angular_velocity", "forward_vector", "right_vector")


@dataclass(frozen=True)
class MotionSeries:
    """The per-step quantities of one route, as (N, 3) arrays in file order."""

    acceleration: np.ndarray
    angular_velocity: np.ndarray
    forward_vector: np.ndarray
    right_vector: np.ndarray

    def __len__(self) -> int:
        return int(self.acceleration.shape[0])

    def chunk(self, start: int, stop: int) -> MotionSeries:
        """Steps ``start:stop``."""
        return MotionSeries(
            self.acceleration[start:stop],
            self.angular_velocity[start:stop],
            self.forward_vector[start:stop],
            self.right_vector[start:stop],
        )


def read_metric_info(path: str | Path) -> MotionSeries:
    """Read a metric_info.json; raise ``B2DFormatError`` naming the file when it is malformed."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise B2DFormatError(path, f"not JSON: {exc.msg} at line {exc.lineno}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise B2DFormatError(path, f"cannot be read: {exc}") from None
    if not isinstance(data, dict):
        raise B2DFormatError(path, "expected an object keyed by step number")
    columns: dict[str, list[list[float]]] = {name: [] for name in _FIELDS}
    # Steps are taken in file order, as Bench2Drive's tool iterates the object.
    for step, entry in data.items():
        if not isinstance(entry, dict):
            raise B2DFormatError(path, f"step {step} is not an object")
        for name in _FIELDS:
            value = entry.get(name)
            if not isinstance(value, list) or len(value) < 3:
                raise B2DFormatError(path, f"step {step}: '{name}' is missing or not an [x, y, z] list")
            try:
                columns[name].append([float(v) for v in value[:3]])
            except (TypeError, ValueError):
                raise B2DFormatError(path, f"step {step}: '{name}' holds a value that is not a number") from None
    arrays = {name: np.asarray(values, dtype=np.float64).reshape(-1, 3) for name, values in columns.items()}
    return MotionSeries(**arrays)


def phase_unwrap(values: np.ndarray) -> np.ndarray:
    """Shift each sample by a multiple of 2π so that successive samples differ by at most π (nuPlan's helper)."""
    two_pi = 2.0 * np.pi
    adjustments = np.zeros_like(values)
    adjustments[1:] = np.cumsum(np.round(np.diff(values) / two_pi))
    return values - two_pi * adjustments


def _within(values: np.ndarray, low: float, high: float) -> bool:
    return bool(np.all((values > low) & (values < high)))


def comfort_checks(series: MotionSeries, corrected: bool = False, dt: float | None = None) -> dict[str, bool]:
    """The six comfort bounds of one chunk, name → holds (see the module docstring for the two modes)."""
    n = len(series)
    window = min(WINDOW, n)
    if POLY_ORDER >= window:
        raise ValueError(f"a chunk needs at least {POLY_ORDER + 1} steps, got {n}")
    dt = dt if dt is not None else (TICK_DT if corrected else BENCH2DRIVE_DT)

    def smooth(x: np.ndarray, deriv: int = 0) -> np.ndarray:
        return savgol_filter(x, window_length=window, polyorder=POLY_ORDER, deriv=deriv, delta=dt, axis=-1)

    acc = series.acceleration[:, :2]
    lon = np.einsum("ij,ij->i", acc, series.forward_vector[:, :2])
    lat = np.einsum("ij,ij->i", acc, series.right_vector[:, :2])
    magnitude = np.hypot(acc[:, 0], acc[:, 1])
    yaw_z = series.angular_velocity[:, 2]
    if corrected:
        # A rate needs no unwrapping; only the unit changes.
        yaw_rate = smooth(np.deg2rad(yaw_z))
        yaw_accel = smooth(yaw_rate, deriv=1)
    else:
        yaw_rate = smooth(phase_unwrap(yaw_z))
        yaw_accel = yaw_rate  # Bench2Drive checks the smoothed rate against the acceleration bound.
    lon = smooth(lon)
    lat = smooth(lat)
    magnitude = smooth(magnitude)
    return {
        "lon_accel": _within(lon, MIN_LON_ACCEL, MAX_LON_ACCEL),
        "lat_accel": _within(lat, -MAX_ABS_LAT_ACCEL, MAX_ABS_LAT_ACCEL),
        "jerk": _within(smooth(magnitude, deriv=1), -MAX_ABS_MAG_JERK, MAX_ABS_MAG_JERK),
        "lon_jerk": _within(smooth(lon, deriv=1), -MAX_ABS_LON_JERK, MAX_ABS_LON_JERK),
        "yaw_accel": _within(yaw_accel, -MAX_ABS_YAW_ACCEL, MAX_ABS_YAW_ACCEL),
        "yaw_rate": _within(yaw_rate, -MAX_ABS_YAW_RATE, MAX_ABS_YAW_RATE),
    }


@dataclass(frozen=True)
class RouteSmoothness:
    """Chunks of one route and how many passed."""

    chunks: int
    passed: int

    @property
    def value(self) -> float:
        """Fraction of passing chunks (0–1)."""
        return self.passed / self.chunks


def route_smoothness(series: MotionSeries, corrected: bool = False, dt: float | None = None) -> RouteSmoothness | None:
    """Passing 20-step chunks of a route; None when it has fewer than 3 steps (nothing to smooth)."""
    n = len(series)
    if n <= POLY_ORDER:
        return None
    if n <= CHUNK_STEPS:
        return RouteSmoothness(1, int(all(comfort_checks(series, corrected, dt).values())))
    starts = range(0, n - CHUNK_STEPS + 1, CHUNK_STEPS)
    results = [all(comfort_checks(series.chunk(s, s + CHUNK_STEPS), corrected, dt).values()) for s in starts]
    return RouteSmoothness(len(results), sum(results))


@dataclass(frozen=True)
class Smoothness:
    """Smoothness of a result set (percentage) and the routes it could not use."""

    value: float | None
    mode: str
    time_step: float
    #: route_id → route smoothness (0–1) for every route with data.
    per_route: dict[str, float] = field(default_factory=dict)
    missing_files: tuple[str, ...] = ()
    too_short: tuple[str, ...] = ()


def driving_smoothness(
    records: Sequence[RouteRecord], metric_dir: str | Path, corrected: bool = False, dt: float | None = None
) -> Smoothness:
    """Mean route smoothness (×100) over the records whose ``<metric_dir>/<save_name>/metric_info.json`` exists."""
    metric_dir = Path(metric_dir)
    if not metric_dir.is_dir():
        raise B2DFormatError(metric_dir, "metric directory not found")
    step = dt if dt is not None else (TICK_DT if corrected else BENCH2DRIVE_DT)
    per_route: dict[str, float] = {}
    missing: list[str] = []
    short: list[str] = []
    for record in records:
        if record.save_name and not is_safe_name(str(record.save_name)):
            # A results file's save_name is joined into a path: "../x" must not read outside metric_dir.
            missing.append(
                f"{metric_dir}/{record.save_name!r} (route {record.route_id}: save_name is not a plain name)"
            )
            continue
        path = metric_dir / str(record.save_name) / METRIC_FILE
        if not record.save_name or not path.is_file():
            missing.append(str(path))
            continue
        result = route_smoothness(read_metric_info(path), corrected, step)
        if result is None:
            short.append(record.route_id)
        else:
            per_route[record.route_id] = result.value
    value = 100.0 * math.fsum(per_route.values()) / len(per_route) if per_route else None
    return Smoothness(
        value=value,
        mode="corrected" if corrected else "bench2drive",
        time_step=step,
        per_route=per_route,
        missing_files=tuple(missing),
        too_short=tuple(short),
    )
