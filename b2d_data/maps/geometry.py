"""Reference-line evaluation in OpenDRIVE's frame: line, arc, spiral, poly3, paramPoly3.

Every function takes local arc lengths ``ds`` (array, metres from the geometry start) and returns OpenDRIVE
``x``, ``y``, heading ``hdg`` (radians, counter-clockwise) and signed curvature ``k`` (1/m, positive = left turn).
Curves without a closed form (spiral, poly3, paramPoly3 re-parameterised by arc length) are integrated on a fine
grid; :data:`INTEGRATION_STEP` keeps the error far below a millimetre for road-like curvatures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from b2d_data.maps.opendrive_parser import GeometryRecord, Poly3

#: Grid step (m) for numerically integrated curves.
INTEGRATION_STEP = 0.02

Evaluated = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def evaluate_line(g: GeometryRecord, ds: np.ndarray) -> Evaluated:
    """Straight segment."""
    c, s = math.cos(g.hdg), math.sin(g.hdg)
    n = np.shape(ds)
    return g.x + ds * c, g.y + ds * s, np.full(n, g.hdg), np.zeros(n)


def evaluate_arc(g: GeometryRecord, ds: np.ndarray) -> Evaluated:
    """Circular arc of constant curvature ``params[0]``."""
    k = g.params[0]
    if abs(k) < 1e-12:
        return evaluate_line(g, ds)
    hdg = g.hdg + k * ds
    x = g.x + (np.sin(hdg) - math.sin(g.hdg)) / k
    y = g.y + (math.cos(g.hdg) - np.cos(hdg)) / k
    return x, y, hdg, np.full(np.shape(ds), k)


def _cumulative_trapezoid(values: np.ndarray, step: np.ndarray | float) -> np.ndarray:
    out = np.empty_like(values)
    out[0] = 0.0
    np.cumsum(0.5 * (values[1:] + values[:-1]) * step, out=out[1:])
    return out


def _grid(length: float) -> np.ndarray:
    n = max(8, int(math.ceil(length / INTEGRATION_STEP)))
    return np.linspace(0.0, length, n + 1)


def evaluate_spiral(g: GeometryRecord, ds: np.ndarray) -> Evaluated:
    """Clothoid: curvature varies linearly from curvStart to curvEnd over the length."""
    k0, k1 = g.params
    rate = (k1 - k0) / g.length if g.length > 0 else 0.0
    u = _grid(g.length)
    theta = g.hdg + k0 * u + 0.5 * rate * u * u
    step = u[1] - u[0] if len(u) > 1 else 0.0
    xs = g.x + _cumulative_trapezoid(np.cos(theta), step)
    ys = g.y + _cumulative_trapezoid(np.sin(theta), step)
    d = np.clip(ds, 0.0, g.length)
    hdg = g.hdg + k0 * ds + 0.5 * rate * ds * ds
    return np.interp(d, u, xs), np.interp(d, u, ys), hdg, k0 + rate * ds


def evaluate_poly3(g: GeometryRecord, ds: np.ndarray) -> Evaluated:
    """Cubic ``v(u)`` in the local frame of the start pose, walked by arc length."""
    a, b, c, d = g.params
    # The arc length is never shorter than u, so u stays within [0, length].
    u = _grid(max(g.length, 1e-9))
    dv = b + 2 * c * u + 3 * d * u * u
    arc = _cumulative_trapezoid(np.sqrt(1.0 + dv * dv), u[1] - u[0])
    uu = np.interp(ds, arc, u)
    v = a + uu * (b + uu * (c + uu * d))
    dvu = b + 2 * c * uu + 3 * d * uu * uu
    ddv = 2 * c + 6 * d * uu
    ch, sh = math.cos(g.hdg), math.sin(g.hdg)
    x = g.x + uu * ch - v * sh
    y = g.y + uu * sh + v * ch
    hdg = g.hdg + np.arctan(dvu)
    k = ddv / np.power(1.0 + dvu * dvu, 1.5)
    return x, y, hdg, k


def evaluate_param_poly3(g: GeometryRecord, ds: np.ndarray) -> Evaluated:
    """Parametric cubic ``(u(p), v(p))``; p spans [0, 1] (normalized) or [0, length] (arcLength)."""
    au, bu, cu, du, av, bv, cv, dv = g.params
    p_max = 1.0 if g.normalized else max(g.length, 1e-9)
    n = max(8, int(math.ceil(max(g.length, 1e-9) / INTEGRATION_STEP)))
    p = np.linspace(0.0, p_max, n + 1)
    dup = bu + 2 * cu * p + 3 * du * p * p
    dvp = bv + 2 * cv * p + 3 * dv * p * p
    arc = _cumulative_trapezoid(np.hypot(dup, dvp), p[1] - p[0])
    # Map road s to p by arc length, as CARLA's lookup table does; the end is pinned to the declared length.
    if arc[-1] > 0:
        arc *= g.length / arc[-1] if g.length > 0 else 1.0
    pp = np.interp(ds, arc, p)
    uu = au + pp * (bu + pp * (cu + pp * du))
    vv = av + pp * (bv + pp * (cv + pp * dv))
    d1u = bu + 2 * cu * pp + 3 * du * pp * pp
    d1v = bv + 2 * cv * pp + 3 * dv * pp * pp
    d2u = 2 * cu + 6 * du * pp
    d2v = 2 * cv + 6 * dv * pp
    ch, sh = math.cos(g.hdg), math.sin(g.hdg)
    x = g.x + uu * ch - vv * sh
    y = g.y + uu * sh + vv * ch
    hdg = g.hdg + np.arctan2(d1v, d1u)
    speed2 = np.maximum(d1u * d1u + d1v * d1v, 1e-18)
    k = (d1u * d2v - d1v * d2u) / np.power(speed2, 1.5)
    return x, y, hdg, k


_EVALUATORS = {
    "line": evaluate_line,
    "arc": evaluate_arc,
    "spiral": evaluate_spiral,
    "poly3": evaluate_poly3,
    "paramPoly3": evaluate_param_poly3,
}


def evaluate_geometry(g: GeometryRecord, ds: np.ndarray) -> Evaluated:
    """Evaluate one geometry record at local arc lengths ``ds``."""
    return _EVALUATORS[g.kind](g, np.asarray(ds, dtype=np.float64))


def evaluate_reference_line(geometries: Sequence[GeometryRecord], s: np.ndarray) -> Evaluated:
    """Evaluate a road's plan view at road ``s`` values (geometries sorted by ``s``)."""
    s = np.asarray(s, dtype=np.float64)
    starts = np.array([g.s for g in geometries])
    index = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(geometries) - 1)
    x, y, hdg, k = (np.empty_like(s) for _ in range(4))
    for i in np.unique(index):
        mask = index == i
        g = geometries[i]
        gx, gy, gh, gk = evaluate_geometry(g, np.maximum(s[mask] - g.s, 0.0))
        x[mask], y[mask], hdg[mask], k[mask] = gx, gy, gh, gk
    return x, y, hdg, k


def max_curvature(geometries: Sequence[GeometryRecord], s0: float, s1: float) -> float:
    """Largest |curvature| of the geometries overlapping [s0, s1] (used to pick a sampling step)."""
    best = 0.0
    for i, g in enumerate(geometries):
        end = geometries[i + 1].s if i + 1 < len(geometries) else math.inf
        if end < s0 or g.s > s1:
            continue
        if g.kind == "arc":
            best = max(best, abs(g.params[0]))
        elif g.kind == "spiral":
            best = max(best, abs(g.params[0]), abs(g.params[1]))
        elif g.kind in ("poly3", "paramPoly3"):
            ds = np.linspace(0.0, max(g.length, 1e-9), 33)
            best = max(best, float(np.max(np.abs(evaluate_geometry(g, ds)[3]))))
    return best


def evaluate_cubic(records: Sequence[Poly3], s: np.ndarray, base: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Piecewise cubic value and derivative at ``s``; record ``i`` holds from ``base + records[i].s``.

    Before the first record the first one is used; with no records the value is 0.
    """
    s = np.asarray(s, dtype=np.float64)
    if not records:
        return np.zeros_like(s), np.zeros_like(s)
    starts = np.array([base + r.s for r in records])
    index = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(records) - 1)
    coeffs = np.array([(r.a, r.b, r.c, r.d) for r in records])[index]
    ds = s - starts[index]
    a, b, c, d = coeffs[:, 0], coeffs[:, 1], coeffs[:, 2], coeffs[:, 3]
    value = a + ds * (b + ds * (c + ds * d))
    slope = b + ds * (2 * c + 3 * d * ds)
    return value, slope
