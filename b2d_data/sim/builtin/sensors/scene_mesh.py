"""Triangle soups shared by the renderer, the LiDAR and the radar, plus the primitives they are built from.

Every mesh is a flat list of triangles (three vertices each, no index buffer) carrying one colour, one CARLA
semantic tag, one instance id and one material per triangle. The GPU gets it as an interleaved vertex buffer and
Embree as a (T, 3, 3) array, so the camera images and the LiDAR see exactly the same surfaces.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Generic, TypeVar

import numpy as np

T = TypeVar("T")


class Material(IntEnum):
    """How the shader lights a triangle (stored in the vertex colour's alpha)."""

    MATTE = 0
    ROAD = 1  # darkens and reflects when wet, carries puddles
    FACADE = 2  # procedural windows, some lit at night; closed blocks wound as box_triangles (the renderer culls)
    GLASS = 3  # dark, reflects the sky
    EMISSIVE = 4  # glows at night (lamps, head/tail lights)
    FOLIAGE = 5  # per-fragment colour jitter
    PAINT = 6  # car paint: a little specular


@dataclass
class TriangleMesh:
    """A triangle soup: ``vertices`` (T, 3, 3) float32 plus per-triangle attributes.

    ``normals`` (T, 3, 3) float32 are per-vertex (flat by default); ``colors`` (T, 3) uint8 RGB;
    ``tags`` (T,) uint8 CARLA semantic tags; ``instance_ids`` (T,) int32 actor ids (0 = static map);
    ``materials`` (T,) uint8 :class:`Material` values.
    """

    vertices: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    tags: np.ndarray
    instance_ids: np.ndarray
    materials: np.ndarray

    def __len__(self) -> int:
        return int(self.vertices.shape[0])

    @classmethod
    def empty(cls) -> TriangleMesh:
        """A mesh with no triangles."""
        return cls(
            np.zeros((0, 3, 3), np.float32),
            np.zeros((0, 3, 3), np.float32),
            np.zeros((0, 3), np.uint8),
            np.zeros(0, np.uint8),
            np.zeros(0, np.int32),
            np.zeros(0, np.uint8),
        )

    @classmethod
    def from_triangles(
        cls,
        vertices: np.ndarray,
        color: Sequence[int] | np.ndarray,
        tag: int,
        instance_id: int = 0,
        material: int = Material.MATTE,
        normals: np.ndarray | None = None,
    ) -> TriangleMesh:
        """Wrap (T, 3, 3) vertices with one colour / tag / id / material (flat normals unless given)."""
        v = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3, 3)
        t = v.shape[0]
        col = np.asarray(color, dtype=np.uint8)
        colors = np.broadcast_to(col, (t, 3)).copy() if col.ndim == 1 else col.reshape(t, 3)
        return cls(
            v,
            flat_normals(v) if normals is None else np.ascontiguousarray(normals, dtype=np.float32).reshape(-1, 3, 3),
            colors,
            np.full(t, tag, np.uint8),
            np.full(t, instance_id, np.int32),
            np.full(t, int(material), np.uint8),
        )

    def transformed(self, matrix: np.ndarray) -> TriangleMesh:
        """The mesh mapped by a 4×4 rigid (or scaled) matrix; normals are rotated only."""
        m = np.asarray(matrix, dtype=np.float64)
        rot = m[:3, :3].astype(np.float32)
        trans = m[:3, 3].astype(np.float32)
        # The products are float32 already (float32 operands): no second copy.
        return TriangleMesh(
            (self.vertices @ rot.T + trans).astype(np.float32, copy=False),
            (self.normals @ rot.T).astype(np.float32, copy=False),
            self.colors,
            self.tags,
            self.instance_ids,
            self.materials,
        )

    def with_instance(self, instance_id: int) -> TriangleMesh:
        """A copy whose triangles all carry ``instance_id``."""
        return TriangleMesh(
            self.vertices,
            self.normals,
            self.colors,
            self.tags,
            np.full(len(self), instance_id, np.int32),
            self.materials,
        )

    def subset(self, index: np.ndarray) -> TriangleMesh:
        """The triangles selected by a boolean mask or an index array."""
        return TriangleMesh(
            self.vertices[index],
            self.normals[index],
            self.colors[index],
            self.tags[index],
            self.instance_ids[index],
            self.materials[index],
        )

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned (min, max) corners; zeros for an empty mesh."""
        if len(self) == 0:
            return np.zeros(3), np.zeros(3)
        flat = self.vertices.reshape(-1, 3)
        return flat.min(axis=0).astype(np.float64), flat.max(axis=0).astype(np.float64)


def mesh_digest(mesh: TriangleMesh) -> bytes:
    """A fingerprint of every array of ``mesh`` (shapes, types and bytes): equal digests, the same mesh."""
    h = hashlib.blake2b(digest_size=16)
    for array in (mesh.vertices, mesh.normals, mesh.colors, mesh.tags, mesh.instance_ids, mesh.materials):
        h.update(f"{array.dtype.str}{array.shape}".encode())
        h.update(np.ascontiguousarray(array).data)
    return h.digest()


class StaticCache(Generic[T]):
    """What a consumer built from its last ``keep`` static meshes (GPU buffers, a tree), found by ``mesh_digest``.

    A suite sets the town's bare scene, then the scene with the fixtures its first snapshot shows; a renderer or caster
    kept for the next route (kept_rig.py) gets both again and builds neither twice.
    """

    def __init__(self, build: Callable[[TriangleMesh], T], release: Callable[[T], None] | None = None,
                 keep: int = 2) -> None:  # fmt: skip
        self._build = build
        self._release = release
        self.keep = keep
        self._items: OrderedDict[bytes, T] = OrderedDict()

    def get(self, mesh: TriangleMesh) -> T:
        """What was built from ``mesh`` (built now if no kept mesh has its arrays; the least recent one then goes
        when there are more than ``keep``)."""
        digest = mesh_digest(mesh)
        item = self._items.get(digest)
        if item is None:
            item = self._items[digest] = self._build(mesh)
            while len(self._items) > self.keep:
                _, old = self._items.popitem(last=False)
                if self._release is not None:
                    self._release(old)
        self._items.move_to_end(digest)
        return item

    def clear(self) -> None:
        """Release everything kept."""
        while self._items:
            _, old = self._items.popitem()
            if self._release is not None:
                self._release(old)


def merge(meshes: Iterable[TriangleMesh]) -> TriangleMesh:
    """Concatenate meshes into one."""
    parts = [m for m in meshes if len(m)]
    if not parts:
        return TriangleMesh.empty()
    if len(parts) == 1:
        return parts[0]
    return TriangleMesh(
        np.concatenate([m.vertices for m in parts]),
        np.concatenate([m.normals for m in parts]),
        np.concatenate([m.colors for m in parts]),
        np.concatenate([m.tags for m in parts]),
        np.concatenate([m.instance_ids for m in parts]),
        np.concatenate([m.materials for m in parts]),
    )


def flat_normals(vertices: np.ndarray) -> np.ndarray:
    """Per-vertex normals equal to each triangle's face normal, (T, 3, 3) float32.

    CARLA's frame is left-handed, so "outward" is ambiguous from winding alone; the shader lights both faces
    (it flips the normal towards the viewer), which makes the winding irrelevant.
    """
    v = np.asarray(vertices, dtype=np.float32)
    if v.shape[0] == 0:
        return np.zeros((0, 3, 3), np.float32)
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = n / np.maximum(norm, 1e-12)
    return np.repeat(n[:, None, :], 3, axis=1).astype(np.float32)


# --------------------------------------------------------------------------------------------- primitives
# Box corner signs in the same x-slowest order as BoundingBox.local_corners.
_BOX_SIGNS = np.array([(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)], dtype=np.float64)
# Two triangles per face, indices into _BOX_SIGNS: +x, -x, +y, -y, +z, -z.
_BOX_FACES = np.array(
    [
        [0, 1, 3], [0, 3, 2],  # +x
        [4, 6, 7], [4, 7, 5],  # -x
        [0, 4, 5], [0, 5, 1],  # +y
        [2, 3, 7], [2, 7, 6],  # -y
        [0, 2, 6], [0, 6, 4],  # +z
        [1, 5, 7], [1, 7, 3],  # -z
    ],
    dtype=np.int64,
)  # fmt: skip
_BOX_NORMALS = np.array(
    [[1, 0, 0]] * 2 + [[-1, 0, 0]] * 2 + [[0, 1, 0]] * 2 + [[0, -1, 0]] * 2 + [[0, 0, 1]] * 2 + [[0, 0, -1]] * 2,
    dtype=np.float32,
)


def box_triangles(center: Sequence[float], half: Sequence[float], skip_bottom: bool = False) -> np.ndarray:
    """(12, 3, 3) triangles of an axis-aligned box (10 without its bottom face)."""
    corners = np.asarray(center, np.float64) + _BOX_SIGNS * np.asarray(half, np.float64)
    faces = _BOX_FACES[:10] if skip_bottom else _BOX_FACES
    return corners[faces].astype(np.float32)


def box(
    center: Sequence[float],
    half: Sequence[float],
    color: Sequence[int],
    tag: int,
    material: int = Material.MATTE,
    skip_bottom: bool = False,
) -> TriangleMesh:
    """An axis-aligned box with exact face normals."""
    tris = box_triangles(center, half, skip_bottom)
    normals = np.repeat(_BOX_NORMALS[: len(tris), None, :], 3, axis=1)
    return TriangleMesh.from_triangles(tris, color, tag, 0, material, normals)


def prism(
    bottom: np.ndarray,
    top: np.ndarray,
    color: Sequence[int],
    tag: int,
    material: int = Material.MATTE,
    cap_top: bool = True,
    cap_bottom: bool = False,
) -> TriangleMesh:
    """A closed loop of side quads between two polygons with the same vertex count (convex caps as fans)."""
    b = np.asarray(bottom, np.float64)
    t = np.asarray(top, np.float64)
    n = len(b)
    j = (np.arange(n) + 1) % n
    sides = np.concatenate(
        [np.stack([b, b[j], t[j]], axis=1), np.stack([b, t[j], t], axis=1)],
    )
    parts = [sides]
    if cap_top:
        parts.append(fan(t))
    if cap_bottom:
        parts.append(fan(b))
    return TriangleMesh.from_triangles(np.concatenate(parts), color, tag, 0, material)


def fan(polygon: np.ndarray) -> np.ndarray:
    """Fan triangulation of a convex polygon (its centroid as hub), (n, 3, 3)."""
    p = np.asarray(polygon, np.float64)
    c = p.mean(axis=0)
    j = (np.arange(len(p)) + 1) % len(p)
    return np.stack([np.broadcast_to(c, p.shape), p, p[j]], axis=1).astype(np.float32)


def cylinder(
    base: Sequence[float],
    radius: float,
    height: float,
    color: Sequence[int],
    tag: int,
    sides: int = 6,
    material: int = Material.MATTE,
    top_radius: float | None = None,
    cap_top: bool = True,
) -> TriangleMesh:
    """A vertical cylinder (or frustum) standing on ``base``, with smooth side normals."""
    a = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    rt = radius if top_radius is None else top_radius
    b = np.asarray(base, np.float64) + ring * radius
    t = np.asarray(base, np.float64) + ring * rt + np.array([0.0, 0.0, height])
    j = (np.arange(sides) + 1) % sides
    tris = np.concatenate([np.stack([b, b[j], t[j]], axis=1), np.stack([b, t[j], t], axis=1)])
    nrm = np.concatenate([np.stack([ring, ring[j], ring[j]], axis=1), np.stack([ring, ring[j], ring], axis=1)])
    if cap_top and rt > 0:
        cap = fan(t)
        tris = np.concatenate([tris, cap])
        nrm = np.concatenate([nrm, np.tile(np.array([0.0, 0.0, 1.0]), (len(cap), 3, 1))])
    return TriangleMesh.from_triangles(tris, color, tag, 0, material, nrm.astype(np.float32))


def horizontal_cylinder(
    center: Sequence[float], radius: float, half_width: float, color: Sequence[int], tag: int, sides: int = 8
) -> TriangleMesh:
    """A cylinder whose axis is the local y axis (a wheel), capped on both ends."""
    a = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    ring = np.stack([np.cos(a), np.zeros_like(a), np.sin(a)], axis=1)
    c = np.asarray(center, np.float64)
    left = c + ring * radius + np.array([0.0, -half_width, 0.0])
    right = c + ring * radius + np.array([0.0, half_width, 0.0])
    j = (np.arange(sides) + 1) % sides
    sides = [np.stack([left, left[j], right[j]], 1), np.stack([left, right[j], right], 1)]
    tris = np.concatenate([*sides, fan(left), fan(right)])
    return TriangleMesh.from_triangles(tris, color, tag)


def ellipsoid(
    center: Sequence[float], radii: Sequence[float], color: Sequence[int], tag: int, material: int = Material.MATTE
) -> TriangleMesh:
    """A low-poly ellipsoid (an octahedron subdivided once: 32 triangles) with smooth normals."""
    unit = _unit_sphere()
    r = np.asarray(radii, np.float64)
    verts = unit * r + np.asarray(center, np.float64)
    normals = unit / np.maximum(r, 1e-6)
    normals /= np.linalg.norm(normals, axis=2, keepdims=True)
    return TriangleMesh.from_triangles(verts, color, tag, 0, material, normals.astype(np.float32))


_SPHERE_CACHE: list[np.ndarray] = []


def _unit_sphere() -> np.ndarray:
    if not _SPHERE_CACHE:
        p = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
        faces = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
        tris = []
        for a, b, c in faces:
            ab, bc, ca = (p[a] + p[b]) / 2, (p[b] + p[c]) / 2, (p[c] + p[a]) / 2
            for tri in ((p[a], ab, ca), (ab, p[b], bc), (ca, bc, p[c]), (ab, bc, ca)):
                tris.append(tri)
        arr = np.array(tris)
        arr /= np.linalg.norm(arr, axis=2, keepdims=True)
        _SPHERE_CACHE.append(arr)
    return _SPHERE_CACHE[0]


def grid_triangles(grid: np.ndarray) -> np.ndarray:
    """Two triangles per cell of a (rows, columns, D) grid of points, as (2·cells, 3, D)."""
    a, b, c, d = grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]
    dim = grid.shape[-1]
    first = np.stack([a, b, c], axis=-2).reshape(-1, 3, dim)
    second = np.stack([a, c, d], axis=-2).reshape(-1, 3, dim)
    return np.concatenate([first, second])


def strip(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Triangles of the ribbon between two polylines of equal length, (2·(n−1), 3, 3)."""
    a = np.asarray(left, np.float64)
    b = np.asarray(right, np.float64)
    if len(a) < 2:
        return np.zeros((0, 3, 3), np.float32)
    t1 = np.stack([a[:-1], b[:-1], b[1:]], axis=1)
    t2 = np.stack([a[:-1], b[1:], a[1:]], axis=1)
    out = np.empty((2 * len(t1), 3, 3), np.float32)
    out[0::2] = t1
    out[1::2] = t2
    return out
