"""Reference-line paths between two poses: polylines with filleted corners, line-turn-line solves, fillets, S-curves."""

from __future__ import annotations

import math
from dataclasses import dataclass

from b2d_data.maps.towngen.geometry import (
    Arc,
    Line,
    Pose,
    Primitive,
    bump_prims,
    chain_end,
    hermite_poly3,
    tangent_lengths,
    turn_prims,
    wrap_angle,
)

#: Tolerance on positions when checking that a path lands on its target (metres).
POSITION_TOL = 1e-6


class PathError(ValueError):
    """A path cannot be built with the requested corners or turn (the layout leaves too little room)."""


@dataclass(frozen=True)
class Corner:
    """A polyline vertex rounded by a turn of the given radius, with clothoid transitions of ``spiral`` metres."""

    x: float
    y: float
    radius: float
    spiral: float = 0.0


@dataclass(frozen=True)
class Path:
    """Primitives from a start pose, with the indices where turns begin and end (natural road split points)."""

    start: Pose
    prims: tuple[Primitive, ...]
    turn_bounds: tuple[int, ...]


def _heading(ax: float, ay: float, bx: float, by: float) -> float:
    return math.atan2(by - ay, bx - ax)


def polyline_path(
    start: Pose, corners: tuple[Corner, ...], end: Pose, bump: float = 0.0, bump_min: float = 160.0
) -> Path:
    """Path from ``start`` through rounded ``corners`` to ``end``.

    ``start`` must point at the first corner (or at ``end``), ``end``'s heading must come from the last corner. Straight
    stretches longer than ``bump_min`` get a gentle S-bump of ``bump`` radians (alternating sides) when ``bump`` != 0.
    """
    points = [(start.x, start.y), *((c.x, c.y) for c in corners), (end.x, end.y)]
    headings = [_heading(*points[i], *points[i + 1]) for i in range(len(points) - 1)]
    if abs(wrap_angle(headings[0] - start.hdg)) > 1e-6 or abs(wrap_angle(headings[-1] - end.hdg)) > 1e-6:
        raise PathError("start/end headings do not point along the polyline")
    turns: list[tuple[tuple[Primitive, ...], float, float]] = []
    for i, corner in enumerate(corners):
        delta = wrap_angle(headings[i + 1] - headings[i])
        prims = turn_prims(delta, corner.radius, corner.spiral)
        d0, d1 = tangent_lengths(prims)
        turns.append((prims, d0, d1))
    prims_out: list[Primitive] = []
    bounds: list[int] = []
    side = 1.0
    for i in range(len(points) - 1):
        seg = math.dist(points[i], points[i + 1])
        before = turns[i - 1][2] if i > 0 else 0.0
        after = turns[i][1] if i < len(turns) else 0.0
        straight = seg - before - after
        if straight < -POSITION_TOL:
            raise PathError(f"corners too tight: straight {i} would be {straight:.2f} m long")
        if bump != 0.0 and straight >= bump_min:
            bump_len = min(120.0, 0.6 * straight)
            shape = bump_prims(side * bump, bump_len)
            chord = chain_end(Pose(0.0, 0.0, 0.0), shape).x
            lead = 0.5 * (straight - chord)
            prims_out.extend((Line(lead), *shape, Line(straight - chord - lead)))
            side = -side
        elif straight > POSITION_TOL:
            prims_out.append(Line(straight))
        if i < len(turns):
            bounds.append(len(prims_out))
            prims_out.extend(turns[i][0])
            bounds.append(len(prims_out))
    path = Path(start, tuple(prims_out), tuple(bounds))
    _check_lands(path, end)
    return path


def turn_displacement(
    hdg_from: float, hdg_to: float, radius: float, spiral: float
) -> tuple[tuple[Primitive, ...], float, float]:
    """The turn primitives from one heading to another and the world displacement they cause."""
    prims = turn_prims(wrap_angle(hdg_to - hdg_from), radius, spiral)
    end = chain_end(Pose(0.0, 0.0, hdg_from), prims)
    return prims, end.x, end.y


def line_turn_line(start: Pose, end: Pose, radius: float, spiral: float) -> Path:
    """A straight, one turn (spiral-arc-spiral), and a straight, joining two poses; the straights are solved for."""
    turn, tx, ty = turn_displacement(start.hdg, end.hdg, radius, spiral)
    ax, ay = start.direction
    bx, by = end.direction
    rx, ry = end.x - start.x - tx, end.y - start.y - ty
    det = ax * by - ay * bx
    if abs(det) < 1e-9:
        raise PathError("line_turn_line needs headings that differ")
    l0 = (rx * by - ry * bx) / det
    l1 = (ax * ry - ay * rx) / det
    if l0 < -POSITION_TOL or l1 < -POSITION_TOL:
        raise PathError(f"turn does not fit between the poses (straights {l0:.2f} m and {l1:.2f} m)")
    prims: list[Primitive] = []
    bounds: list[int] = []
    if l0 > POSITION_TOL:
        prims.append(Line(l0))
    bounds.append(len(prims))
    prims.extend(turn)
    bounds.append(len(prims))
    if l1 > POSITION_TOL:
        prims.append(Line(l1))
    path = Path(start, tuple(prims), tuple(bounds))
    _check_lands(path, end)
    return path


def connector(start: Pose, end: Pose, min_radius: float = 3.0) -> tuple[Primitive, ...]:
    """Geometry of a junction connecting road: a line, a line-arc-line fillet for turns, else a paramPoly3."""
    delta = wrap_angle(end.hdg - start.hdg)
    u, v = start.to_local(end.x, end.y)
    if abs(delta) < 1e-7:
        if abs(v) < 1e-6 and u > 0:
            return (Line(u),)
        return (hermite_poly3(start, end),)
    if abs(delta) < math.radians(150.0):
        # Tangent lines: start line through (0, 0) along x; end line through (u, v) along delta.
        s = math.sin(delta)
        d1 = v / s
        d0 = u - d1 * math.cos(delta)
        tangent = min(d0, d1)
        if d0 > 0 and d1 > 0:
            radius = tangent / math.tan(abs(delta) / 2.0)
            if radius >= min_radius:
                prims: list[Primitive] = []
                if d0 - tangent > 1e-6:
                    prims.append(Line(d0 - tangent))
                prims.append(Arc(radius * abs(delta), math.copysign(1.0 / radius, delta)))
                if d1 - tangent > 1e-6:
                    prims.append(Line(d1 - tangent))
                return tuple(prims)
    return (hermite_poly3(start, end),)


def _check_lands(path: Path, end: Pose) -> None:
    got = chain_end(path.start, path.prims)
    if math.hypot(got.x - end.x, got.y - end.y) > 1e-4 or abs(wrap_angle(got.hdg - end.hdg)) > 1e-6:
        raise PathError(f"path misses its end: got ({got.x:.4f}, {got.y:.4f}) want ({end.x:.4f}, {end.y:.4f})")
