"""Plan-view geometry of OpenDRIVE reference lines: lines, arcs, clothoid spirals and paramPoly3 curves.

Everything here works in the OpenDRIVE inertial frame (x east, y north, heading counter-clockwise from x, radians).
Curves are evaluated in closed form where one exists and by Gauss-Legendre quadrature otherwise (spiral positions,
paramPoly3 arc length), which is exact to far below a millimetre for the lengths a town uses.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_angle(angle: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle + math.pi) % TWO_PI - math.pi


@lru_cache(maxsize=8)
def _gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    nodes, weights = np.polynomial.legendre.leggauss(n)
    return nodes, weights


def _integrate(
    func: Callable[[np.ndarray], np.ndarray], lo: float, hi: float, pieces: int, order: int = 16
) -> np.ndarray:
    """Composite Gauss-Legendre integral of a vector-valued ``func(x: ndarray) -> ndarray (k, n)`` over [lo, hi]."""
    nodes, weights = _gauss_legendre(order)
    edges = np.linspace(lo, hi, pieces + 1)
    half = 0.5 * (edges[1:] - edges[:-1])
    mid = 0.5 * (edges[1:] + edges[:-1])
    xs = (mid[:, None] + half[:, None] * nodes[None, :]).ravel()
    ws = (half[:, None] * weights[None, :]).ravel()
    return np.asarray(func(xs)) @ ws


@dataclass(frozen=True)
class Pose:
    """A position and heading in the OpenDRIVE frame."""

    x: float
    y: float
    hdg: float

    @property
    def direction(self) -> tuple[float, float]:
        """Unit vector along the heading."""
        return math.cos(self.hdg), math.sin(self.hdg)

    @property
    def left(self) -> tuple[float, float]:
        """Unit vector pointing to the left of the heading (the +t direction of OpenDRIVE)."""
        return -math.sin(self.hdg), math.cos(self.hdg)

    def offset(self, t: float) -> tuple[float, float]:
        """The point ``t`` metres to the left (negative: right) of this pose."""
        lx, ly = self.left
        return self.x + t * lx, self.y + t * ly

    def forward(self, d: float) -> Pose:
        """This pose moved ``d`` metres along its heading."""
        dx, dy = self.direction
        return Pose(self.x + d * dx, self.y + d * dy, self.hdg)

    def shifted(self, t: float) -> Pose:
        """This pose moved ``t`` metres to its left, same heading."""
        x, y = self.offset(t)
        return Pose(x, y, self.hdg)

    def reversed(self) -> Pose:
        """Same point, opposite heading."""
        return Pose(self.x, self.y, wrap_angle(self.hdg + math.pi))

    def to_local(self, x: float, y: float) -> tuple[float, float]:
        """Coordinates of a world point in this pose's frame (u forward, v left)."""
        dx, dy = x - self.x, y - self.y
        c, s = math.cos(self.hdg), math.sin(self.hdg)
        return c * dx + s * dy, -s * dx + c * dy

    def to_world(self, u: float, v: float) -> tuple[float, float]:
        """World coordinates of a point given in this pose's frame."""
        c, s = math.cos(self.hdg), math.sin(self.hdg)
        return self.x + c * u - s * v, self.y + s * u + c * v


@dataclass(frozen=True)
class Line:
    """A straight plan-view segment."""

    length: float

    def local(self, ds: float) -> tuple[float, float, float]:
        """(u, v, heading change) ``ds`` metres into the segment, in the segment's start frame."""
        return ds, 0.0, 0.0

    def curvature(self, ds: float) -> float:
        """Signed curvature (1/m, positive to the left) at ``ds``."""
        return 0.0


@dataclass(frozen=True)
class Arc:
    """A circular arc of constant signed curvature (positive turns left)."""

    length: float
    curvature_value: float

    def local(self, ds: float) -> tuple[float, float, float]:
        """(u, v, heading change) ``ds`` metres into the arc, in its start frame."""
        k = self.curvature_value
        if abs(k) < 1e-12:
            return ds, 0.0, 0.0
        dh = k * ds
        return math.sin(dh) / k, (1.0 - math.cos(dh)) / k, dh

    def curvature(self, ds: float) -> float:
        """Signed curvature at ``ds`` (constant)."""
        return self.curvature_value


@dataclass(frozen=True)
class Spiral:
    """A clothoid whose curvature changes linearly from ``curv_start`` to ``curv_end``."""

    length: float
    curv_start: float
    curv_end: float

    @property
    def rate(self) -> float:
        """Curvature change per metre."""
        return (self.curv_end - self.curv_start) / self.length

    def heading_change(self, ds: float) -> float:
        """Heading change after ``ds`` metres."""
        return self.curv_start * ds + 0.5 * self.rate * ds * ds

    def local(self, ds: float) -> tuple[float, float, float]:
        """(u, v, heading change) ``ds`` metres into the spiral, in its start frame."""
        if ds <= 0.0:
            return 0.0, 0.0, 0.0
        k0, c = self.curv_start, self.rate

        def integrand(s: np.ndarray) -> np.ndarray:
            theta = k0 * s + 0.5 * c * s * s
            return np.vstack((np.cos(theta), np.sin(theta)))

        u, v = _integrate(integrand, 0.0, ds, pieces=max(1, math.ceil(ds / 10.0)))
        return float(u), float(v), self.heading_change(ds)

    def curvature(self, ds: float) -> float:
        """Signed curvature at ``ds``."""
        return self.curv_start + self.rate * ds


@dataclass(frozen=True)
class ParamPoly3:
    """A parametric cubic ``u(p), v(p)`` in the start frame, ``p`` normalised to [0, 1] over the arc length."""

    length: float
    au: float
    bu: float
    cu: float
    du: float
    av: float
    bv: float
    cv: float
    dv: float

    def _uv(self, p: float) -> tuple[float, float]:
        u = self.au + p * (self.bu + p * (self.cu + p * self.du))
        v = self.av + p * (self.bv + p * (self.cv + p * self.dv))
        return u, v

    def _duv(self, p: float) -> tuple[float, float]:
        du = self.bu + p * (2.0 * self.cu + 3.0 * p * self.du)
        dv = self.bv + p * (2.0 * self.cv + 3.0 * p * self.dv)
        return du, dv

    def local(self, ds: float) -> tuple[float, float, float]:
        """(u, v, heading change) at ``ds`` metres, i.e. at ``p = ds / length`` (OpenDRIVE's normalised range)."""
        p = min(max(ds / self.length, 0.0), 1.0)
        u, v = self._uv(p)
        du, dv = self._duv(p)
        return u, v, math.atan2(dv, du)

    def curvature(self, ds: float) -> float:
        """Signed curvature at ``ds``."""
        p = min(max(ds / self.length, 0.0), 1.0)
        du, dv = self._duv(p)
        ddu = 2.0 * self.cu + 6.0 * p * self.du
        ddv = 2.0 * self.cv + 6.0 * p * self.dv
        return (du * ddv - dv * ddu) / max((du * du + dv * dv) ** 1.5, 1e-12)


Primitive = Line | Arc | Spiral | ParamPoly3


def arc_length_of_cubic(bu: float, cu: float, du: float, bv: float, cv: float, dv: float) -> float:
    """Arc length of the cubic ``(u(p), v(p))`` for p in [0, 1]."""

    def speed(p: np.ndarray) -> np.ndarray:
        dup = bu + p * (2.0 * cu + 3.0 * p * du)
        dvp = bv + p * (2.0 * cv + 3.0 * p * dv)
        return np.sqrt(dup * dup + dvp * dvp)[None, :]

    return float(_integrate(speed, 0.0, 1.0, pieces=8, order=16)[0])


def hermite_poly3(start: Pose, end: Pose, tangent_scale: float = 1.0) -> ParamPoly3:
    """A paramPoly3 leaving ``start`` along its heading and arriving at ``end`` along its heading.

    Tangent magnitudes equal the chord length (times ``tangent_scale``), which gives a smooth S or bend without loops
    for the gentle lateral shifts and small heading changes it is used for.
    """
    ex, ey = start.to_local(end.x, end.y)
    eh = wrap_angle(end.hdg - start.hdg)
    m = math.hypot(ex, ey) * tangent_scale
    t1u, t1v = m * math.cos(eh), m * math.sin(eh)
    # u(p) = b p + c p^2 + d p^3 with u(0)=0, u'(0)=m, u(1)=ex, u'(1)=t1u (same for v with v'(0)=0).
    bu, bv = m, 0.0
    cu = 3.0 * ex - 2.0 * bu - t1u
    du = -2.0 * ex + bu + t1u
    cv = 3.0 * ey - 2.0 * bv - t1v
    dv = -2.0 * ey + bv + t1v
    length = arc_length_of_cubic(bu, cu, du, bv, cv, dv)
    return ParamPoly3(length, 0.0, bu, cu, du, 0.0, bv, cv, dv)


def advance(pose: Pose, prim: Primitive, ds: float) -> Pose:
    """The pose ``ds`` metres into ``prim`` started at ``pose``."""
    u, v, dh = prim.local(ds)
    x, y = pose.to_world(u, v)
    return Pose(x, y, wrap_angle(pose.hdg + dh))


@dataclass(frozen=True)
class Segment:
    """One ``<geometry>`` record: a primitive with its start s and start pose."""

    s: float
    start: Pose
    prim: Primitive


@dataclass(frozen=True)
class RefLine:
    """A road reference line: primitives chained from a start pose."""

    start: Pose
    prims: tuple[Primitive, ...]

    @property
    def length(self) -> float:
        """Total length in metres."""
        return float(sum(p.length for p in self.prims))

    def segments(self) -> list[Segment]:
        """The primitives with their start s and start poses."""
        out: list[Segment] = []
        pose, s = self.start, 0.0
        for prim in self.prims:
            out.append(Segment(s, pose, prim))
            pose = advance(pose, prim, prim.length)
            s += prim.length
        return out

    @property
    def end(self) -> Pose:
        """Pose at the end of the line."""
        pose = self.start
        for prim in self.prims:
            pose = advance(pose, prim, prim.length)
        return pose

    def pose_at(self, s: float) -> Pose:
        """Pose at ``s`` (clamped to the line)."""
        segs = self.segments()
        s = min(max(s, 0.0), self.length)
        for seg in reversed(segs):
            if s >= seg.s - 1e-12:
                return advance(seg.start, seg.prim, min(s - seg.s, seg.prim.length))
        return self.start

    def split(self, at: list[int]) -> list[RefLine]:
        """Cut the line before the primitive indices in ``at`` (each piece keeps its own start pose)."""
        cuts = [0, *sorted(set(i for i in at if 0 < i < len(self.prims))), len(self.prims)]
        segs = self.segments()
        return [RefLine(segs[a].start, self.prims[a:b]) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def turn_prims(delta: float, radius: float, spiral: float) -> tuple[Primitive, ...]:
    """A turn by ``delta`` radians (positive left): spiral in, arc, spiral out (no spirals when ``spiral`` is 0).

    The spirals take ``spiral`` metres each (shortened if the turn is too small to hold them).
    """
    sign = 1.0 if delta >= 0 else -1.0
    kappa = sign / radius
    total = abs(delta)
    if spiral <= 0.0:
        return (Arc(total * radius, kappa),)
    # Each spiral turns by spiral * |kappa| / 2; keep at least a third of the turn for the arc.
    max_spiral = total * radius / 1.5
    ls = min(spiral, max_spiral)
    arc_angle = total - ls / radius
    return (
        Spiral(ls, 0.0, kappa),
        Arc(arc_angle * radius, kappa),
        Spiral(ls, kappa, 0.0),
    )


def chain_end(start: Pose, prims: tuple[Primitive, ...]) -> Pose:
    """Pose after running ``prims`` from ``start``."""
    return RefLine(start, prims).end


def tangent_lengths(prims: tuple[Primitive, ...]) -> tuple[float, float]:
    """Distances from the start and from the end of a turn to the intersection of its end tangents."""
    end = chain_end(Pose(0.0, 0.0, 0.0), prims)
    s = math.sin(end.hdg)
    if abs(s) < 1e-9:
        raise ValueError("tangent lengths of a turn by 0 or 180 degrees are undefined")
    # Intersection of y = 0 with the line through the end point along its heading.
    d1 = end.y / s
    d0 = end.x - d1 * math.cos(end.hdg)
    return d0, d1


def bump_prims(angle: float, length: float) -> tuple[Primitive, ...]:
    """A gentle S-bump that leaves and rejoins a straight line: arcs of +k, -k (twice as long), +k.

    ``angle`` is the largest heading deviation (radians, sign picks the side), ``length`` the bump's total arc length.
    """
    quarter = length / 4.0
    k = angle / quarter
    return Arc(quarter, k), Arc(2.0 * quarter, -k), Arc(quarter, k)
