"""Embree ray casting over a static scene (built once) and a dynamic scene (rebuilt per tick).

Every ray is cast into the static scene first and then into the dynamic one with the static hit distance as its
limit, so the nearer of the two wins. Hits report distance, semantic tag and actor id of the triangle hit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from embreex import mesh_construction, rtcore, rtcore_scene

from b2d_data.sim.builtin.sensors.scene_mesh import TriangleMesh

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


class _Layer:
    """One Embree scene plus the per-triangle labels of the mesh it was built from."""

    def __init__(self, mesh: TriangleMesh) -> None:
        self.size = len(mesh)
        self.tags = mesh.tags.copy()
        self.actor_ids = mesh.instance_ids.astype(np.int32)
        self.scene = rtcore_scene.EmbreeScene(_device())
        if self.size:
            mesh_construction.TriangleMesh(self.scene, np.ascontiguousarray(mesh.vertices, dtype=np.float32))


class RayCaster:
    """Nearest-hit queries against static + dynamic triangle meshes."""

    def __init__(self, static: TriangleMesh | None = None) -> None:
        self._static = _Layer(static if static is not None else TriangleMesh.empty())
        self._dynamic = _Layer(TriangleMesh.empty())

    def set_static(self, mesh: TriangleMesh) -> None:
        """Build the static scene (once per map)."""
        self._static = _Layer(mesh)

    def set_dynamic(self, mesh: TriangleMesh) -> None:
        """Rebuild the dynamic scene (once per tick)."""
        self._dynamic = _Layer(mesh)

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
        self._static = _Layer(TriangleMesh.empty())
        self._dynamic = _Layer(TriangleMesh.empty())
