"""Ray casting into the static and the per-tick dynamic scene: the nearer hit wins, with its labels."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from b2d_data.sim.builtin.sensors.map_mesh import ground_plane
from b2d_data.sim.builtin.sensors.raycast import RayCaster
from b2d_data.sim.builtin.sensors.scene_mesh import merge


def _wall(x: float, y: float, z: float, half: float, actor_id: int = 0, tag: int = 10):
    """A square wall facing the x axis, centred on (x, y, z), ``2 * half`` metres wide and high."""
    turn = np.array([[0.0, 0.0, 1.0, x], [0.0, 1.0, 0.0, y], [-1.0, 0.0, 0.0, z], [0.0, 0.0, 0.0, 1.0]])
    mesh = ground_plane(half, half).transformed(turn)
    n = len(mesh)
    return replace(mesh, tags=np.full(n, tag, np.uint8), instance_ids=np.full(n, actor_id, mesh.instance_ids.dtype))


def test_nearest_of_static_and_dynamic_hits():
    # Static: ground z = 0 and a wall at x = 20. Dynamic: a 2 m actor wall at x = 10 (id 7, tag 14) and another
    # actor behind the static wall at x = 30 (id 8), which no ray may report.
    caster = RayCaster(merge([ground_plane(50.0, 10.0), _wall(20.0, 0.0, 0.0, 50.0)]))
    caster.set_dynamic(merge([_wall(10.0, 0.0, 1.0, 1.0, 7, 14), _wall(30.0, 5.0, 1.0, 1.0, 8, 14)]))
    origin = np.array([[0.0, 0.0, 1.0]], np.float32)
    dirs = np.array([
        [1.0, 0.0, 0.0],  # the actor wall, 10 m
        [0.0, 0.0, -1.0],  # the ground, 1 m
        [30.0, 5.0, 0.0],  # towards the hidden actor: the static wall at x = 20 first
        [0.0, 0.0, 1.0],  # the sky
        [1.0, 0.05, 0.0],  # the actor wall off-centre, at y = 0.5
    ], np.float32)  # fmt: skip
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = caster.cast(origin, dirs, 85.0)
    np.testing.assert_array_equal(hits.hit, [True, True, True, False, True])
    # |(20, 20·5/30)| = 20.276 m; |(10, 0.5)| = 10.0125 m.
    np.testing.assert_allclose(hits.t, [10.0, 1.0, math.hypot(20.0, 20.0 * 5.0 / 30.0), 85.0, math.hypot(10.0, 0.5)],
                               rtol=1e-5)  # fmt: skip
    np.testing.assert_array_equal(hits.actor_ids, [7, 0, 0, 0, 7])
    np.testing.assert_array_equal(hits.tags, [14, 10, 10, 0, 14])
