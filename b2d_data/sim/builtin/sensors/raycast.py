"""Embree ray casting over a static scene (built once) and a dynamic scene (rebuilt per tick).

Every ray is cast into the static scene first and then into the dynamic one with the static hit distance as its
limit, so the nearer of the two wins. Hits report distance, semantic tag and actor id of the triangle hit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from embreex import mesh_construction, rtcore, rtcore_scene

from b2d_data.sim.builtin.sensors.scene_mesh import StaticCache, TriangleMesh

_DEVICE: list[rtcore.EmbreeDevice] = []


def _device() -> rtcore.EmbreeDevice:
    """One Embree device per process (creating one per scene would spin up a thread pool each time)."""
    if not _DEVICE:
        _DEVICE.append(rtcore.EmbreeDevice())
    return _DEVICE[0]


@dataclass
class RayHits:
    """Result of a ray batch: ``hit`` mask, distance ``t`` (metres; ``max_range`` where missed), tag and actor id."""

    hit: np.ndarray
    t: np.ndarray
    tags: np.ndarray
    actor_ids: np.ndarray


@dataclass
class SharedVertices:
    """A triangle soup's vertices with each distinct one kept once: ``first`` (V,) the flat vertex row of each,
    ``inverse`` (3T,) the distinct vertex of every flat row, ``triangles`` (T,) each triangle's three indices as a
    tuple (the form embreex's indexed path reads fastest)."""

    first: np.ndarray
    inverse: np.ndarray
    triangles: np.ndarray

    def holds(self, bits: np.ndarray) -> bool:
        """Whether every flat row of ``bits`` ((3T, 3) uint32 views of the vertices) equals its distinct vertex."""
        return len(self.inverse) == len(bits) and bool((bits[self.first][self.inverse] == bits).all())


def shared_vertices(bits: np.ndarray) -> SharedVertices | None:
    """The distinct rows of (3T, 3) uint32 vertex bits; None when two distinct rows share a hash key (never seen)."""
    wide = bits.astype(np.uint64)
    key = (wide[:, 0] << np.uint64(32) | wide[:, 1]) ^ (wide[:, 2] * np.uint64(0x9E3779B97F4A7C15))
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    rows = inverse.reshape(-1, 3)
    triangles = np.fromiter(zip(rows[:, 0].tolist(), rows[:, 1].tolist(), rows[:, 2].tolist()), object, len(rows))
    shared = SharedVertices(first, inverse.reshape(-1), triangles)
    return shared if shared.holds(bits) else None


class _Layer:
    """One Embree scene plus the per-triangle labels of the mesh it was built from.

    With ``shared`` (the dynamic layer) Embree gets each distinct vertex once and an index per triangle corner:
    embreex copies its input element by element through Python, ~90 ns per coordinate, and the actors' closed
    shapes repeat each corner about five times. Every triangle keeps the exact vertex bits of the flat soup, so
    Embree builds and hits the same triangles.
    """

    def __init__(self, mesh: TriangleMesh, shared: SharedVertices | None = None) -> None:
        self.size = len(mesh)
        self.tags = mesh.tags.copy()
        self.actor_ids = mesh.instance_ids.astype(np.int32)
        self.scene = rtcore_scene.EmbreeScene(_device())
        if not self.size:
            return
        vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
        if shared is None:
            mesh_construction.TriangleMesh(self.scene, vertices)
        else:
            # Python floats hold float32 values exactly; embreex reads them back without a numpy scalar each.
            distinct = vertices.reshape(-1, 3)[shared.first].astype(object)
            mesh_construction.TriangleMesh(self.scene, distinct, shared.triangles)


class RayCaster:
    """Nearest-hit queries against static + dynamic triangle meshes."""

    def __init__(self, static: TriangleMesh | None = None) -> None:
        self._statics: StaticCache[_Layer] = StaticCache(_Layer)
        self._static = self._statics.get(static if static is not None else TriangleMesh.empty())
        self._dynamic = _Layer(TriangleMesh.empty())
        # The last dynamic mesh's distinct vertices: from tick to tick the same actors repeat the same corners, so
        # the pattern is checked against the new vertices (a gather) and worked out afresh only when it fails.
        self._shared: SharedVertices | None = None

    def set_static(self, mesh: TriangleMesh) -> None:
        """Build the static scene (once per map: the last two stay built, ``StaticCache``)."""
        self._static = self._statics.get(mesh)

    def set_dynamic(self, mesh: TriangleMesh) -> None:
        """Rebuild the dynamic scene (once per tick)."""
        bits = np.ascontiguousarray(mesh.vertices, dtype=np.float32).reshape(-1, 3).view(np.uint32)
        if self._shared is None or not self._shared.holds(bits):
            self._shared = shared_vertices(bits) if len(bits) else None
        self._dynamic = _Layer(mesh, self._shared)

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_range: float) -> RayHits:
        """Cast unit-direction rays; the nearest hit within ``max_range`` of either scene wins."""
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        n = len(d)
        if o.shape[0] != n:
            o = np.ascontiguousarray(np.broadcast_to(o.reshape(-1, 3)[0], (n, 3)))
        t = np.full(n, max_range, np.float32)
        tags = np.zeros(n, np.uint8)
        ids = np.zeros(n, np.int32)
        hit = np.zeros(n, bool)
        for layer in (self._static, self._dynamic):
            if layer.size == 0 or n == 0:
                continue
            if layer is self._dynamic:
                # Few rays reach an actor before the static hit. A first pass asks only which ones do (half the
                # cost per ray of the full answer); the full answer is then cast for those alone. Rays are
                # independent, so each one gets the hit the whole batch would have given it.
                rows = np.flatnonzero(layer.scene.run(o, d, dists=t.copy()) >= 0)
                if len(rows) == 0:
                    continue
                res = layer.scene.run(o[rows], d[rows], dists=t[rows], output=1)
            else:
                rows = np.arange(n)
                res = layer.scene.run(o, d, dists=t.copy(), output=1)
            got = res["primID"] >= 0
            rows, prim = rows[got], res["primID"][got]
            t[rows] = res["tfar"][got]
            tags[rows] = layer.tags[prim]
            ids[rows] = layer.actor_ids[prim]
            hit[rows] = True
        return RayHits(hit, t, tags, ids)

    def close(self) -> None:
        """Drop the scenes (the GPU caster's counterpart releases its context)."""
        self._statics.clear()
        self._static = _Layer(TriangleMesh.empty())
        self._dynamic = _Layer(TriangleMesh.empty())
