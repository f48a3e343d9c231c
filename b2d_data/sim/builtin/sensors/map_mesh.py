"""The static scene of a town: road surfaces, marks, sidewalks with curbs, crosswalks, terrain, buildings, trees
and street lights, meshed once from the map's lane polylines.

The map is first reduced to a :class:`RoadLayout` (lane strips, painted lines, crosswalk outlines), which is what
:func:`build_static_scene` meshes; tests and benchmarks can build a layout directly. Procedural content
(buildings set back from the sidewalks, trees, lamps) is deterministic for a seed.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from b2d_data.format.semantic import SemanticTag
from b2d_data.sim.builtin.sensors.scene_mesh import (
    Material,
    TriangleMesh,
    box_triangles,
    cylinder,
    ellipsoid,
    fan,
    grid_triangles,
    merge,
    strip,
)

log = logging.getLogger(__name__)

SIDEWALK_HEIGHT = 0.15
MARK_LIFT = 0.02
ASPHALT = (72, 72, 75)
SHOULDER = (84, 83, 82)
SIDEWALK = (152, 150, 144)
CURB = (170, 168, 162)
GRASS = (88, 112, 58)
WHITE_PAINT = (225, 225, 218)
YELLOW_PAINT = (225, 180, 40)
FACADES: tuple[tuple[int, int, int], ...] = (
    (196, 180, 150), (170, 95, 70), (150, 150, 152), (215, 210, 198), (120, 110, 100), (185, 160, 120),
    (110, 125, 140), (205, 190, 170), (140, 80, 60), (175, 175, 165),
)  # fmt: skip
ROOF = (90, 88, 86)
TRUNK = (85, 62, 40)
LEAVES: tuple[tuple[int, int, int], ...] = ((62, 100, 40), (78, 112, 45), (55, 88, 38), (92, 118, 52))
POLE_GREY = (105, 108, 110)
LAMP_WARM = (255, 226, 170)

#: Lane types meshed as drivable asphalt.
_ROAD_TYPES = {
    "driving", "parking", "shoulder", "biking", "bidirectional", "stop", "restricted", "entry", "exit",
    "onramp", "offramp", "roadworks", "special1", "special2", "special3",
}  # fmt: skip


@dataclass(frozen=True)
class LaneStrip:
    """A lane surface: ``left`` (inner) and ``right`` (outer) borders (N, 3) sampled at the same stations.

    ``surface`` is ``road``, ``shoulder``, ``sidewalk`` or ``median``; ``outermost`` marks the last lane on its
    side of the road (its right border is where buildings may start).
    """

    left: np.ndarray
    right: np.ndarray
    surface: str
    junction_id: int = -1
    outermost: bool = False


@dataclass(frozen=True)
class PaintLine:
    """A painted line along ``points`` (N, 3): style ``solid``/``broken``/``solidsolid``/``solidbroken``/
    ``brokensolid``/``brokenbroken``/``dots``, RGB colour and stroke width (m)."""

    points: np.ndarray
    style: str
    color: tuple[int, int, int]
    width: float = 0.15


@dataclass
class RoadLayout:
    """What the static scene is meshed from."""

    lanes: list[LaneStrip]
    lines: list[PaintLine] = field(default_factory=list)
    crosswalks: list[np.ndarray] = field(default_factory=list)


@dataclass
class StaticScene:
    """The merged static mesh plus the street-lamp positions (for night lighting) and the scene bounds."""

    mesh: TriangleMesh
    lamps: np.ndarray
    bounds_min: np.ndarray
    bounds_max: np.ndarray

    def lightmap(
        self, cell: float = 1.0, sigma: float = 7.0
    ) -> tuple[np.ndarray, tuple[float, float], tuple[float, float]]:
        """Ground-level light pools of the lamps: (H, W) image in [0, 1], origin (x, y) and size (m)."""
        x0, y0 = float(self.bounds_min[0]), float(self.bounds_min[1])
        w = max(1, int(math.ceil((self.bounds_max[0] - x0) / cell)))
        h = max(1, int(math.ceil((self.bounds_max[1] - y0) / cell)))
        img = np.zeros((h, w), np.float32)
        reach = int(math.ceil(3.0 * sigma / cell))
        offs = np.arange(-reach, reach + 1) * cell
        kernel = np.exp(-(offs[None, :] ** 2 + offs[:, None] ** 2) / (2.0 * sigma * sigma))
        for lx, ly, _ in self.lamps:
            cx, cy = int((lx - x0) / cell), int((ly - y0) / cell)
            ra, rb = max(0, cy - reach), min(h, cy + reach + 1)
            ca, cb = max(0, cx - reach), min(w, cx + reach + 1)
            if ra >= rb or ca >= cb:
                continue
            img[ra:rb, ca:cb] += kernel[ra - (cy - reach) : rb - (cy - reach), ca - (cx - reach) : cb - (cx - reach)]
        return np.clip(img, 0.0, 1.0), (x0, y0), (w * cell, h * cell)


# --------------------------------------------------------------------------------------------- map → layout
def _name(value: object) -> str:
    return str(getattr(value, "name", value)).lower()


_STYLES = {
    "solid": "solid", "broken": "broken", "solidsolid": "solidsolid", "solidbroken": "solidbroken",
    "brokensolid": "brokensolid", "brokenbroken": "brokenbroken", "bottsdots": "dots",
}  # fmt: skip


def _paint(marking: object, points: np.ndarray) -> PaintLine | None:
    style = _STYLES.get(_name(getattr(marking, "type", "none")))
    if style is None or len(points) < 2:
        return None
    color = YELLOW_PAINT if _name(getattr(marking, "color", "white")) == "yellow" else WHITE_PAINT
    width = float(getattr(marking, "width", 0.15) or 0.15)
    return PaintLine(points, style, color, min(max(width, 0.1), 0.3))


def layout_from_map(town_map: object, resolution: float = 2.0) -> RoadLayout:
    """Reduce a :class:`b2d_data.maps.Map` to lane strips, painted lines and crosswalks."""
    geoms = town_map.lane_geometry(resolution)
    lanes: list[LaneStrip] = []
    lines: list[PaintLine] = []
    outer_id: dict[tuple[int, int, int], int] = {}
    present: set[tuple[int, int, int]] = set()
    for g in geoms:
        if _name(g.lane_type) == "none":
            continue
        side = 1 if g.lane_id > 0 else -1
        key = (g.road_id, g.section_id, side)
        outer_id[key] = max(outer_id.get(key, 0), abs(g.lane_id))
        present.add((g.road_id, g.section_id, g.lane_id))
    for g in geoms:
        kind = _name(g.lane_type)
        if kind == "none" or len(g.s) < 2:
            continue
        if kind in ("sidewalk", "border"):
            surface = "sidewalk"
        elif kind == "median":
            surface = "median"
        elif kind == "shoulder":
            surface = "shoulder"
        elif kind in _ROAD_TYPES:
            surface = "road"
        else:
            continue
        side = 1 if g.lane_id > 0 else -1
        outermost = abs(g.lane_id) == outer_id.get((g.road_id, g.section_id, side), 0)
        lanes.append(LaneStrip(np.asarray(g.left), np.asarray(g.right), surface, int(g.junction_id), outermost))
        # Each painted line once: every lane's own (outer) marks, plus the centre line from lane −1 (or +1 alone).
        for start, end, marking in g.right_marks:
            line = _paint(marking, np.asarray(g.right)[start : end + 1])
            if line is not None:
                lines.append(line)
        centre_owner = g.lane_id == -1 or (g.lane_id == 1 and (g.road_id, g.section_id, -1) not in present)
        if centre_owner:
            for start, end, marking in g.left_marks:
                line = _paint(marking, np.asarray(g.left)[start : end + 1])
                if line is not None:
                    lines.append(line)
    crosswalks: list[np.ndarray] = []
    try:
        for cw in town_map.crosswalks():
            pts = np.asarray(getattr(cw, "polygon", cw), np.float64)
            if pts.ndim == 2 and pts.shape[1] == 3 and len(pts) >= 3:
                crosswalks.append(pts)
    except (ImportError, AttributeError) as exc:  # a map object without crosswalk support
        log.info("map %s: no crosswalks (%s)", getattr(town_map, "name", "?"), exc)
    return RoadLayout(lanes, lines, crosswalks)


# --------------------------------------------------------------------------------------------- roads
def _lift(points: np.ndarray, dz: float) -> np.ndarray:
    out = np.array(points, np.float64)
    out[:, 2] += dz
    return out


def _horizontal_normals(points: np.ndarray) -> np.ndarray:
    """Unit horizontal normals of a polyline (the tangent turned by 90° in the x-y plane)."""
    p = np.asarray(points, np.float64)
    t = np.empty_like(p)
    t[1:-1] = p[2:] - p[:-2]
    t[0] = p[1] - p[0]
    t[-1] = p[-1] - p[-2]
    n = np.stack([-t[:, 1], t[:, 0], np.zeros(len(p))], axis=1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-9)


def _lane_meshes(lanes: Sequence[LaneStrip]) -> list[TriangleMesh]:
    road = [strip(s.left, s.right) for s in lanes if s.surface == "road"]
    shoulder = [strip(s.left, s.right) for s in lanes if s.surface == "shoulder"]
    parts = []
    if road:
        parts.append(TriangleMesh.from_triangles(np.concatenate(road), ASPHALT, SemanticTag.ROAD, 0, Material.ROAD))
    if shoulder:
        tris = np.concatenate(shoulder)
        parts.append(TriangleMesh.from_triangles(tris, SHOULDER, SemanticTag.ROAD, 0, Material.ROAD))
    for surface, color, tag, material in (
        ("sidewalk", SIDEWALK, SemanticTag.SIDEWALK, Material.MATTE),
        ("median", GRASS, SemanticTag.TERRAIN, Material.FOLIAGE),
    ):
        tops, curbs = [], []
        for s in lanes:
            if s.surface != surface:
                continue
            top_l, top_r = _lift(s.left, SIDEWALK_HEIGHT), _lift(s.right, SIDEWALK_HEIGHT)
            tops.append(strip(top_l, top_r))
            curbs.append(strip(s.left, top_l))
            curbs.append(strip(top_r, s.right))
        if tops:
            parts.append(TriangleMesh.from_triangles(np.concatenate(tops), color, tag, 0, material))
            parts.append(TriangleMesh.from_triangles(np.concatenate(curbs), CURB, tag, 0, Material.MATTE))
    return parts


def _junction_fill(lanes: Sequence[LaneStrip]) -> TriangleMesh:
    """Asphalt under each junction: the convex hull of its lane borders, 1 cm below the lanes."""
    by_junction: dict[int, list[np.ndarray]] = {}
    for s in lanes:
        if s.junction_id >= 0 and s.surface in ("road", "shoulder"):
            by_junction.setdefault(s.junction_id, []).extend([s.left, s.right])
    tris = []
    for pts_list in by_junction.values():
        pts = np.concatenate(pts_list)
        if len(pts) < 3:
            continue
        try:
            hull = ConvexHull(pts[:, :2])
        except QhullError:
            continue
        poly = pts[hull.vertices].copy()
        poly[:, 2] -= 0.01
        tris.append(fan(poly))
    if not tris:
        return TriangleMesh.empty()
    return TriangleMesh.from_triangles(np.concatenate(tris), ASPHALT, SemanticTag.ROAD, 0, Material.ROAD)


def _resample(points: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ≤ ``step`` m along a polyline and their arc lengths."""
    p = np.asarray(points, np.float64)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    if s[-1] <= 0:
        return p[:1], s[:1]
    n = max(2, int(math.ceil(s[-1] / step)) + 1)
    si = np.linspace(0.0, s[-1], n)
    out = np.column_stack([np.interp(si, s, p[:, j]) for j in range(3)])
    return out, si


def _stroke(points: np.ndarray, offset: float, width: float, pattern: tuple[float, float] | None) -> np.ndarray:
    """Quads of a line at a lateral ``offset``; ``pattern`` (dash, gap) in metres or None for solid."""
    if pattern is None:
        p = np.asarray(points, np.float64)
        s = None
    else:
        p, s = _resample(points, 1.0)  # 1 m segments: dashes start and end within half a metre
    if len(p) < 2:
        return np.zeros((0, 3, 3), np.float32)
    n = _horizontal_normals(p)
    a = p + n * (offset - width / 2)
    b = p + n * (offset + width / 2)
    a[:, 2] += MARK_LIFT
    b[:, 2] += MARK_LIFT
    tris = strip(a, b)
    if pattern is not None:
        dash, gap = pattern
        mid = 0.5 * (s[:-1] + s[1:])
        on = (mid % (dash + gap)) < dash
        keep = np.repeat(on, 2)
        tris = tris[keep]
    return tris


def _paint_meshes(lines: Iterable[PaintLine]) -> list[TriangleMesh]:
    out = []
    for line in lines:
        w = line.width
        sep = w + 0.12
        if line.style in ("solid", "broken", "dots"):
            pattern = {"solid": None, "broken": (3.0, 6.0), "dots": (0.2, 0.8)}[line.style]
            tris = _stroke(line.points, 0.0, w, pattern)
        else:
            first, second = line.style[:5], line.style[5:]
            tris = np.concatenate(
                [
                    _stroke(line.points, -sep / 2, w, None if first == "solid" else (3.0, 6.0)),
                    _stroke(line.points, sep / 2, w, None if second == "solid" else (3.0, 6.0)),
                ]
            )
        if len(tris):
            out.append(TriangleMesh.from_triangles(tris, line.color, SemanticTag.ROAD_LINE, 0, Material.ROAD))
    return out


def _crosswalk_mesh(polygons: Iterable[np.ndarray]) -> TriangleMesh:
    """Zebra bars inside each crosswalk outline: 0.5 m bars every metre across the road."""
    tris = []
    for poly in polygons:
        p = np.asarray(poly, np.float64)
        if np.allclose(p[0], p[-1]) and len(p) > 3:
            p = p[:-1]
        xy = p[:, :2]
        centre = xy.mean(axis=0)
        cov = np.cov((xy - centre).T)
        evals, evecs = np.linalg.eigh(cov)
        long_axis = evecs[:, 1]  # across the road (walking direction)
        short_axis = evecs[:, 0]  # along the road
        proj_l = (xy - centre) @ long_axis
        proj_s = (xy - centre) @ short_axis
        z = float(p[:, 2].mean()) + MARK_LIFT
        half_s = 0.5 * (proj_s.max() - proj_s.min()) * 0.95
        for u in np.arange(proj_l.min() + 0.25, proj_l.max() - 0.25, 1.0):
            c0 = centre + long_axis * u
            corners = [
                c0 - short_axis * half_s, c0 - short_axis * half_s + long_axis * 0.5,
                c0 + short_axis * half_s + long_axis * 0.5, c0 + short_axis * half_s,
            ]  # fmt: skip
            q = np.array([[c[0], c[1], z] for c in corners])
            tris.append(np.array([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]))
    if not tris:
        return TriangleMesh.empty()
    return TriangleMesh.from_triangles(np.concatenate(tris), WHITE_PAINT, SemanticTag.ROAD_LINE, 0, Material.ROAD)


# --------------------------------------------------------------------------------------------- surroundings
class _Occupancy:
    """Coarse grid of taken ground cells (buildings, trees) so procedural objects do not overlap."""

    _STRIDE = 1 << 24  # cell (i, j) ↦ i·stride + j, with j well inside ±stride/2 for any town

    def __init__(self, cell: float = 2.0) -> None:
        self.cell = cell
        self.cells: set[int] = set()

    def _ij(self, pts: np.ndarray) -> np.ndarray:
        return np.floor(np.asarray(pts)[:, :2] / self.cell).astype(np.int64)

    def free(self, pts: np.ndarray) -> bool:
        ij = self._ij(pts)
        return self.cells.isdisjoint((ij[:, 0] * self._STRIDE + ij[:, 1]).tolist())

    def take(self, pts: np.ndarray, margin: int = 0) -> None:
        ij = np.unique(self._ij(pts), axis=0)
        d = np.arange(-margin, margin + 1)
        grown = (ij[:, None, None, :] + np.stack(np.meshgrid(d, d, indexing="ij"), axis=-1)[None]).reshape(-1, 2)
        self.cells.update((grown[:, 0] * self._STRIDE + grown[:, 1]).tolist())


def _road_tree(lanes: Sequence[LaneStrip]) -> tuple[cKDTree, np.ndarray]:
    """KD-tree over points covering every lane surface (borders, centre and quarter lines)."""
    pts = []
    for s in lanes:
        for f in (0.0, 0.25, 0.5, 0.75, 1.0):
            pts.append(s.left + (s.right - s.left) * f)
    allp = np.concatenate(pts) if pts else np.zeros((1, 3))
    return cKDTree(allp[:, :2]), allp


def _footprint_samples(
    centre: np.ndarray, along: np.ndarray, across: np.ndarray, half_a: float, half_c: float
) -> np.ndarray:
    """Ground points (K, 2) about 1 m apart over a rectangular footprint (2-D centre and axes)."""
    ua = np.linspace(-half_a, half_a, max(2, int(half_a) + 2))
    uc = np.linspace(-half_c, half_c, max(2, int(half_c) + 2))
    g = centre[None, None, :] + ua[:, None, None] * along[None, None, :] + uc[None, :, None] * across[None, None, :]
    return g.reshape(-1, 2)


def _building(centre: np.ndarray, along: np.ndarray, across: np.ndarray, half_a: float, half_c: float, z0: float,
              height: float, color: tuple[int, int, int]) -> TriangleMesh:
    """A block: walls with procedural windows (facade material) and a darker flat roof."""
    tris = box_triangles((0.0, 0.0, height / 2), (half_a, half_c, height / 2), skip_bottom=True)
    rot = np.array([[along[0], across[0], 0.0], [along[1], across[1], 0.0], [0.0, 0.0, 1.0]])
    if np.linalg.det(rot) < 0.0:
        # A mirrored frame would turn the box inside out: every block keeps the box's winding, so that the renderer
        # can skip the walls that face away from a camera (the renderer culls).
        tris = tris[:, [0, 2, 1]]
    world = tris @ rot.T + np.array([centre[0], centre[1], z0])
    walls = TriangleMesh.from_triangles(world[:8], color, SemanticTag.BUILDING, 0, Material.FACADE)
    roof = TriangleMesh.from_triangles(world[8:10], ROOF, SemanticTag.BUILDING, 0, Material.MATTE)
    return merge([walls, roof])


def _tree(base: np.ndarray, rng: np.random.Generator) -> TriangleMesh:
    tag = SemanticTag.VEGETATION
    h = rng.uniform(2.2, 3.2)
    r = rng.uniform(1.6, 2.6)
    trunk = cylinder(base, 0.16, h + 0.6, TRUNK, tag, sides=5, cap_top=False)
    leaves = LEAVES[int(rng.integers(len(LEAVES)))]
    crown = ellipsoid(base + np.array([0.0, 0.0, h + r * 0.8]), (r, r, r * 1.15), leaves, tag, Material.FOLIAGE)
    return merge([trunk, crown])


def _street_light(foot: np.ndarray, towards_road: np.ndarray) -> tuple[TriangleMesh, np.ndarray]:
    """A lamp post: pole, an arm over the road and an emissive lamp head; returns the lamp position too."""
    tag = SemanticTag.POLE
    h = 7.5
    pole = cylinder(foot, 0.1, h, POLE_GREY, tag, sides=6, top_radius=0.07)
    d = np.array([towards_road[0], towards_road[1], 0.0])
    d /= max(np.linalg.norm(d), 1e-9)
    side = np.array([-d[1], d[0], 0.0])
    arm_len = 1.8
    top = foot + np.array([0.0, 0.0, h - 0.05])
    end = top + d * arm_len
    arm = np.array(
        [
            [top - side * 0.04, end - side * 0.04, end + side * 0.04],
            [top - side * 0.04, end + side * 0.04, top + side * 0.04],
        ]
    )
    arm_mesh = TriangleMesh.from_triangles(arm, POLE_GREY, tag)
    head_c = end + d * 0.25 - np.array([0.0, 0.0, 0.08])
    head = box_triangles((0.0, 0.0, 0.0), (0.3, 0.14, 0.06))
    rot = np.array([[d[0], side[0], 0.0], [d[1], side[1], 0.0], [0.0, 0.0, 1.0]])
    head_mesh = TriangleMesh.from_triangles(head @ rot.T + head_c, LAMP_WARM, tag, 0, Material.EMISSIVE)
    return merge([pole, arm_mesh, head_mesh]), head_c


def _arc(points: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1))]


def _at(points: np.ndarray, s: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
    """Point and unit horizontal tangent at arc length ``u``."""
    i = int(np.clip(np.searchsorted(s, u) - 1, 0, len(points) - 2))
    f = (u - s[i]) / max(s[i + 1] - s[i], 1e-9)
    p = points[i] + (points[i + 1] - points[i]) * f
    t = points[i + 1, :2] - points[i, :2]
    return p, t / max(np.linalg.norm(t), 1e-9)


def _outward(inner: np.ndarray, outer: np.ndarray, arc: np.ndarray, u: float) -> np.ndarray:
    """Unit horizontal direction from the inner to the outer border near arc length ``u``."""
    i = int(np.clip(np.searchsorted(arc, u), 0, len(inner) - 1))
    d = (outer[i] - inner[i])[:2]
    return d / max(np.linalg.norm(d), 1e-9)


class _Surroundings:
    """Procedural furniture of a town (lamps, trees, buildings), placed without overlaps for one seed."""

    def __init__(self, lanes: Sequence[LaneStrip], seed: int) -> None:
        self.lanes = lanes
        self.rng = np.random.default_rng([seed, 4242])
        self.tree, self.road_pts = _road_tree(lanes)
        self.occ = _Occupancy(2.0)
        self.parts: list[TriangleMesh] = []
        self.lamps: list[np.ndarray] = []

    def sidewalk_furniture(self) -> None:
        """Street lights near the curb every ~30 m, trees near the outer edge of wide sidewalks."""
        rng = self.rng
        for s in self.lanes:
            if s.surface != "sidewalk" or s.junction_id >= 0:
                continue
            inner, outer = s.left, s.right
            arc = _arc(inner)
            width = float(np.median(np.linalg.norm((outer - inner)[:, :2], axis=1)))
            if arc[-1] < 6.0 or width < 1.2:
                continue
            lift = np.array([0.0, 0.0, SIDEWALK_HEIGHT])
            u = rng.uniform(3.0, 15.0)
            while u < arc[-1] - 2.0:
                o = _outward(inner, outer, arc, u)
                foot = _at(inner, arc, u)[0] + np.array([o[0], o[1], 0.0]) * 0.45 + lift
                if self.occ.free(foot[None]):
                    mesh, lamp = _street_light(foot, -o)
                    self.parts.append(mesh)
                    self.lamps.append(lamp)
                    self.occ.take(foot[None])
                u += rng.uniform(26.0, 36.0)
            if width < 2.4:
                continue
            u = rng.uniform(2.0, 10.0)
            while u < arc[-1] - 2.0:
                o = _outward(inner, outer, arc, u)
                foot = _at(inner, arc, u)[0] + np.array([o[0], o[1], 0.0]) * (width - 0.9) + lift
                if rng.random() < 0.6 and self.occ.free(foot[None]):
                    self.parts.append(_tree(foot, rng))
                    self.occ.take(foot[None])
                u += rng.uniform(9.0, 16.0)

    def _try_building(self, centre: np.ndarray, along: np.ndarray, across: np.ndarray, half_a: float, half_c: float,
                      clearance: float) -> bool:
        if not self.occ.free(centre[None]):
            return False
        samples = _footprint_samples(centre, along, across, half_a, half_c)
        # Only "is any road point within the clearance" matters: a bounded query stops early.
        dist, _ = self.tree.query(samples, distance_upper_bound=clearance)
        if np.isfinite(dist).any() or not self.occ.free(samples):
            return False
        rng = self.rng
        height = rng.uniform(22.0, 48.0) if rng.random() < 0.18 else rng.uniform(7.0, 19.0)
        z0 = float(self.road_pts[self.tree.query(centre)[1], 2]) - 0.3
        color = FACADES[int(rng.integers(len(FACADES)))]
        self.parts.append(
            _building(centre, along, across, half_a, half_c, z0, height, color)
        )
        self.occ.take(samples, margin=1)
        return True

    def street_buildings(self) -> None:
        """Blocks along the outer edge of the outermost lane of every road side, 1–3 m behind it."""
        rng = self.rng
        edges = [s for s in self.lanes if s.outermost and s.junction_id < 0 and len(s.right) >= 2]
        for k in rng.permutation(len(edges)):
            outer, inner = edges[k].right, edges[k].left
            arc = _arc(outer)
            if arc[-1] < 8.0:
                continue
            u = rng.uniform(0.0, 6.0)
            while u < arc[-1]:
                p, t = _at(outer, arc, u)
                o = _outward(inner, outer, arc, u)
                half_a, half_c = rng.uniform(5.0, 12.0), rng.uniform(5.0, 11.0)
                centre = p[:2] + o * (rng.uniform(1.0, 3.0) + half_c) + t * half_a
                if self._try_building(centre, t, o, half_a, half_c, clearance=0.9):
                    u += 2.0 * half_a + rng.uniform(0.5, 3.0)
                else:
                    u += 4.0

    def block_fill(self, lo: np.ndarray, hi: np.ndarray, reach: float = 60.0) -> None:
        """Buildings (now and then a tree) on the free ground within ``reach`` metres of a road."""
        rng = self.rng
        step = 16.0
        gx, gy = np.meshgrid(np.arange(lo[0] + step / 2, hi[0], step), np.arange(lo[1] + step / 2, hi[1], step))
        n = gx.size
        centres = np.column_stack([gx.ravel(), gy.ravel()]) + rng.uniform(-3.0, 3.0, (n, 2))
        yaws = rng.uniform(0.0, math.pi, n)
        halves = rng.uniform(5.0, 10.0, (n, 2))
        is_tree = rng.random(n) < 0.15
        road_dist, nearest = self.tree.query(centres)
        for k in np.flatnonzero(road_dist <= reach):
            centre = centres[k]
            if is_tree[k]:
                foot = np.array([centre[0], centre[1], self.road_pts[nearest[k], 2] - 0.1])
                if road_dist[k] > 4.0 and self.occ.free(foot[None]):
                    self.parts.append(_tree(foot, rng))
                    self.occ.take(foot[None], margin=1)
                continue
            if road_dist[k] <= 2.5 + halves[k].min():
                continue  # the footprint would reach the road: skip the detailed test
            c, s = math.cos(yaws[k]), math.sin(yaws[k])
            self._try_building(centre, np.array([c, s]), np.array([-s, c]), halves[k, 0], halves[k, 1], clearance=2.5)


def _surroundings(
    lanes: Sequence[LaneStrip], seed: int, lo: np.ndarray, hi: np.ndarray
) -> tuple[list[TriangleMesh], np.ndarray]:
    """Street lights, trees and buildings; returns the meshes and the lamp positions."""
    town = _Surroundings(lanes, seed)
    town.sidewalk_furniture()
    town.street_buildings()
    town.block_fill(lo, hi)
    return town.parts, (np.array(town.lamps) if town.lamps else np.zeros((0, 3)))


def _terrain(lanes: Sequence[LaneStrip], lo: np.ndarray, hi: np.ndarray) -> TriangleMesh:
    """A grass grid under everything, 10 cm below the nearest lane surface.

    Cells are 8 m, coarser on large towns (about 100 cells across) to keep the triangle count moderate.
    """
    cell = max(8.0, float(max(hi[0] - lo[0], hi[1] - lo[1])) / 100.0)
    tree, pts = _road_tree(lanes)
    xs = np.arange(lo[0], hi[0] + cell, cell)
    ys = np.arange(lo[1], hi[1] + cell, cell)
    gx, gy = np.meshgrid(xs, ys)
    _, idx = tree.query(np.column_stack([gx.ravel(), gy.ravel()]))
    gz = (pts[idx, 2] - 0.1).reshape(gx.shape)
    tris = grid_triangles(np.stack([gx, gy, gz], axis=-1))
    normals = np.tile(np.array([0.0, 0.0, 1.0], np.float32), (len(tris), 3, 1))
    return TriangleMesh.from_triangles(tris, GRASS, SemanticTag.TERRAIN, 0, Material.FOLIAGE, normals)


def ground_plane(half_size: float = 500.0, cell: float = 20.0, z: float = 0.0) -> TriangleMesh:
    """A flat grass grid centred on the origin (the ground of a town without roads).

    It is tessellated (not two huge triangles) because the shaders light and fog per vertex.
    """
    xs = np.arange(-half_size, half_size + cell / 2, cell)
    gx, gy = np.meshgrid(xs, xs)
    tris = grid_triangles(np.stack([gx, gy, np.full_like(gx, z)], axis=-1))
    normals = np.tile(np.array([0.0, 0.0, 1.0], np.float32), (len(tris), 3, 1))
    return TriangleMesh.from_triangles(tris, GRASS, SemanticTag.TERRAIN, 0, Material.FOLIAGE, normals)


def build_static_scene(layout: RoadLayout, seed: int = 0, margin: float = 60.0) -> StaticScene:
    """Mesh a road layout: roads, junction fills, marks, crosswalks, sidewalks, terrain, buildings, trees, lamps.

    A layout without lanes (a town with no roads) gets a flat ground at z = 0.
    """
    if not layout.lanes:
        half = 500.0
        lo, hi = np.array([-half, -half, 0.0]), np.array([half, half, 0.0])
        return StaticScene(ground_plane(half), np.zeros((0, 3)), lo, hi)
    allpts = np.concatenate([np.concatenate([s.left, s.right]) for s in layout.lanes])
    lo = allpts.min(axis=0) - np.array([margin, margin, 0.0])
    hi = allpts.max(axis=0) + np.array([margin, margin, 0.0])
    parts = _lane_meshes(layout.lanes)
    parts.append(_junction_fill(layout.lanes))
    parts += _paint_meshes(layout.lines)
    parts.append(_crosswalk_mesh(layout.crosswalks))
    surroundings, lamps = _surroundings(layout.lanes, seed, lo, hi)
    parts += surroundings
    parts.append(_terrain(layout.lanes, lo, hi))
    mesh = merge(parts)
    log.info("static scene: %d triangles, %d lamps", len(mesh), len(lamps))
    return StaticScene(mesh, lamps, lo, hi)
