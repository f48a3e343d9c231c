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


def _actor_scene(shift: float = 0.0, yaw: float = 0.0):
    """The world meshes of a car, a van, a walker and a cone around the origin (``shift`` moves the car)."""
    from b2d_data.sim.builtin.sensors.actor_mesh import ActorMeshBuilder
    from b2d_data.sim.builtin.sensors.synthetic import actor_state

    actors = [
        actor_state(2, "vehicle.tesla.model3", 8.0 + shift, 1.5, yaw),
        actor_state(3, "vehicle.mercedes.sprinter", -9.0, -2.0, 30.0),
        actor_state(4, "walker.pedestrian.0001", 3.0, -6.0, 90.0, velocity=(0.0, 1.2, 0.0)),
        actor_state(5, "static.prop.constructioncone", -3.0, 5.0, 0.0),
    ]
    return merge(m for _, m in ActorMeshBuilder().build_parts(actors, False, 0.35))


def _rays(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    origins = rng.normal(0.0, 4.0, (n, 3)) * [1.0, 1.0, 0.1] + [0.0, 0.0, 1.0]
    directions = rng.normal(size=(n, 3))
    return origins, directions / np.linalg.norm(directions, axis=1, keepdims=True)


def _assert_same_hits(a, b) -> None:
    for field in ("hit", "t", "tags", "actor_ids"):
        x, y = getattr(a, field), getattr(b, field)
        assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), field


def test_dynamic_layer_with_shared_vertices_hits_as_the_flat_soup():
    # The dynamic layer hands Embree each distinct vertex once (raycast.SharedVertices); every ray must get the
    # same hit, distance bits and labels as from the flat triangle soup, also after the actors moved (the last
    # tick's pattern of distinct vertices is reused only where it still holds).
    from b2d_data.sim.builtin.sensors import raycast

    ground = ground_plane(60.0, 60.0)
    shared, flat = RayCaster(ground), RayCaster(ground)
    origins, directions = _rays(40_000, 3)
    for shift, yaw in ((0.0, 0.0), (0.0, 0.0), (0.37, 12.5), (0.37, 12.5)):
        mesh = _actor_scene(shift, yaw)
        shared.set_dynamic(mesh)
        flat._dynamic = raycast._Layer(mesh)  # the flat soup, as every tick was built before
        assert shared._shared is not None and len(shared._shared.first) < len(mesh) * 3 // 2
        a, b = shared.cast(origins, directions, 60.0), flat.cast(origins, directions, 60.0)
        assert int((a.actor_ids != 0).sum()) > 1000
        _assert_same_hits(a, b)


def test_shared_vertices_are_worked_out_again_when_the_mesh_changes():
    # A pattern of distinct vertices that no longer matches the vertices must not be used: the same triangles in
    # another order (same size, other corners at every row) get a pattern of their own, and the hits of the soup.
    from b2d_data.sim.builtin.sensors import raycast

    a = _actor_scene()
    b = a.subset(np.arange(len(a))[::-1])
    bits_a = a.vertices.reshape(-1, 3).view(np.uint32)
    bits_b = b.vertices.reshape(-1, 3).view(np.uint32)
    pattern = raycast.shared_vertices(bits_a)
    assert pattern is not None and pattern.holds(bits_a) and not pattern.holds(bits_b)
    caster, flat = RayCaster(), RayCaster()
    caster.set_dynamic(a)
    caster.set_dynamic(b)
    assert caster._shared is not None and caster._shared.holds(bits_b)
    flat._dynamic = raycast._Layer(b)
    origins, directions = _rays(20_000, 5)
    _assert_same_hits(caster.cast(origins, directions, 60.0), flat.cast(origins, directions, 60.0))
