"""The GPU ray caster gives Embree's hits: same rays, same hit or miss, same tag and actor id, distance within float
rounding; the rig's LiDAR and radar data are the same with either caster. Run on llvmpipe with the GPU path forced on
(``gpu_rays="on"``), where the compute shader runs on the CPU."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from b2d_data.format.rig import LIDAR
from b2d_data.sim.builtin.sensors.bvh import LEAF_SIZE, build_bvh
from b2d_data.sim.builtin.sensors.gpu_raycast import GpuRayCaster, make_ray_caster
from b2d_data.sim.builtin.sensors.lidar import cast_from, lidar_directions
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene, ground_plane
from b2d_data.sim.builtin.sensors.raycast import RayCaster, RayHits
from b2d_data.sim.builtin.sensors.renderer import create_gl_context, is_hardware
from b2d_data.sim.builtin.sensors.scene_mesh import merge
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import crossroads_layout, snapshot_of

from .test_determinism_weather import CONFIG, NOON, _actors
from .test_raycast import _wall

#: Distances may differ by float32 rounding (the two casters order the same products differently): 0.12 mm was the
#: largest difference over 256 000 Town10HD rays (scripts/bench_lidar.py).
ATOL_M = 1e-3


def _assert_same_hits(a: RayHits, b: RayHits) -> None:
    np.testing.assert_array_equal(a.hit, b.hit)
    np.testing.assert_array_equal(a.tags, b.tags)
    np.testing.assert_array_equal(a.actor_ids, b.actor_ids)
    np.testing.assert_allclose(a.t, b.t, atol=ATOL_M, rtol=0)


def _leaf_rows(bvh):
    leaves = bvh.leaves
    data = bvh.nodes[leaves - 1 :, :, 3].copy().view(np.uint32)
    return data[:, 0], data[:, 1]


def test_tree_boxes_hold_their_triangles_and_children():
    rng = np.random.default_rng(5)
    centres = rng.uniform(-50.0, 50.0, (301, 1, 3))
    tris = (centres + rng.normal(0.0, 1.0, (301, 3, 3))).astype(np.float32)
    groups = np.repeat(np.arange(30), [10] * 29 + [11])
    for bvh in (build_bvh(tris), build_bvh(tris, groups=groups)):
        # Rows are a permutation of the triangles, stored as vertex 0 and the two edges from it.
        assert sorted(bvh.order.tolist()) == list(range(301))
        v = tris[bvh.order]
        np.testing.assert_array_equal(bvh.triangles[:, 0, :3], v[:, 0])
        np.testing.assert_allclose(bvh.triangles[:, 0, :3] + bvh.triangles[:, 1, :3], v[:, 1], atol=1e-5)
        leaves = bvh.leaves
        assert leaves & (leaves - 1) == 0 and len(bvh.nodes) == 2 * leaves - 1
        first, count = _leaf_rows(bvh)
        assert count.max() <= LEAF_SIZE and count.sum() == 301
        covered = np.zeros(301, int)
        for k in np.flatnonzero(count):
            rows = slice(int(first[k]), int(first[k] + count[k]))
            covered[rows] += 1
            lo, hi = bvh.nodes[leaves - 1 + k, 0, :3], bvh.nodes[leaves - 1 + k, 1, :3]
            assert (v[rows].min(axis=1) >= lo).all() and (v[rows].max(axis=1) <= hi).all()
        assert (covered == 1).all()  # every row in exactly one leaf
        # Each inner node's box holds both children's (empty children sit far away and are skipped).
        for node in range(leaves - 1):
            for child in (2 * node + 1, 2 * node + 2):
                if bvh.nodes[child, 0, 0] > 1e29:
                    continue
                assert (bvh.nodes[node, 0, :3] <= bvh.nodes[child, 0, :3]).all()
                assert (bvh.nodes[node, 1, :3] >= bvh.nodes[child, 1, :3]).all()
    # With groups no leaf mixes two keys (an actor's leaves never span another actor).
    bvh = build_bvh(tris, groups=groups)
    first, count = _leaf_rows(bvh)
    for k in np.flatnonzero(count):
        keys = groups[bvh.order[int(first[k]) : int(first[k] + count[k])]]
        assert len(set(keys.tolist())) == 1


@pytest.fixture(scope="module")
def gpu():
    caster = GpuRayCaster()  # its own context: llvmpipe here
    yield caster
    caster.close()


def test_morton_codes_interleave_the_cell_bits():
    # Bit b of the x, y and z cells goes to bit 3·b, 3·b + 1 and 3·b + 2 of the code: by hand for single bits, and
    # bit by bit for a few thousand random cells (the points span exactly 0..1023 in each axis).
    from b2d_data.sim.builtin.sensors.bvh import _morton

    rng = np.random.default_rng(4)
    cells = np.vstack([np.zeros((1, 3)), np.full((1, 3), 1023.0), rng.integers(0, 1024, (4000, 3))])
    points = np.vstack([cells, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [512.0, 0.0, 0.0]]])
    code = _morton(points)
    assert code[1] == (1 << 30) - 1 and code[-4:].tolist() == [1, 2, 4, 1 << 27]
    want = np.zeros(len(points), np.uint64)
    for bit in range(10):
        for axis in range(3):
            want |= ((points[:, axis].astype(np.uint64) >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    np.testing.assert_array_equal(code, want)


def test_hand_scene(gpu):
    # The scene of test_raycast: ground z = 0 and a wall at x = 20 (static), an actor wall at x = 10 (id 7, tag 14)
    # and an actor behind the static wall (id 8). Expected distances worked out by hand there.
    gpu.set_static(merge([ground_plane(50.0, 10.0), _wall(20.0, 0.0, 0.0, 50.0)]))
    gpu.set_dynamic(merge([_wall(10.0, 0.0, 1.0, 1.0, 7, 14), _wall(30.0, 5.0, 1.0, 1.0, 8, 14)]))
    dirs = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [30.0, 5.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.05, 0.0]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = gpu.cast(np.array([[0.0, 0.0, 1.0]]), dirs, 85.0)
    np.testing.assert_array_equal(hits.hit, [True, True, True, False, True])
    np.testing.assert_allclose(hits.t, [10.0, 1.0, math.hypot(20.0, 20.0 * 5.0 / 30.0), 85.0, math.hypot(10.0, 0.5)],
                               rtol=1e-5)  # fmt: skip
    np.testing.assert_array_equal(hits.actor_ids, [7, 0, 0, 0, 7])
    np.testing.assert_array_equal(hits.tags, [14, 10, 10, 0, 14])
    # Range: the wall at 20 m is out of a 15 m range; the actor wall at 10 m is in it.
    short = gpu.cast(np.array([[0.0, 0.0, 1.0]]), dirs[[0, 2]], 15.0)
    np.testing.assert_array_equal(short.hit, [True, False])
    np.testing.assert_allclose(short.t, [10.0, 15.0], rtol=1e-5)
    # Per-ray origins: from (0, 0, 1) and from (15, 0, 1) along +x: the actor wall at 10 m, the static wall at 5 m.
    two = gpu.cast(np.array([[0.0, 0.0, 1.0], [15.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]] * 2), 85.0)
    np.testing.assert_allclose(two.t, [10.0, 5.0], rtol=1e-5)
    np.testing.assert_array_equal(two.actor_ids, [7, 0])


def test_lidar_sweeps_match_embree_on_a_street(gpu):
    # The crossroads town and a few actors; 64 channels × 120 azimuths from two poses, one turned off the axes.
    scene = build_static_scene(crossroads_layout(), seed=3)
    suite = SensorSuite.from_scene(scene, replace(CONFIG, cameras=(), radar=False, gpu_rays="off"), seed=0)
    try:
        tick = suite._prepare(snapshot_of(_actors(), NOON, frame=3), 1)
        embree = suite.caster
        assert isinstance(embree, RayCaster)
        gpu.set_static(embree_static(suite))
        gpu.set_dynamic(merge([m for i, m in tick.actor_parts if i != 1] + [tick.lamps]))
        dirs = lidar_directions(LIDAR, 120)
        base = suite.sensor_poses(tick.ego)[LIDAR.sensor_id]
        turn = np.eye(4)
        c, s = math.cos(0.7), math.sin(0.7)
        turn[:2, :2] = [[c, -s], [s, c]]
        turn[:3, 3] = [3.0, -1.0, 0.0]
        hit_actor = 0
        for pose in (base, base @ turn):
            a = cast_from(embree, pose, dirs, LIDAR.range_m)
            b = cast_from(gpu, pose, dirs, LIDAR.range_m)  # turned on the GPU (cast_turned)
            _assert_same_hits(a, b)
            hit_actor += int((b.actor_ids > 0).sum())
            # The plain cast (world directions turned on the host, as the radars give them) agrees too.
            world = (dirs @ pose[:3, :3].T.astype(np.float32)).astype(np.float32)
            _assert_same_hits(a, gpu.cast(pose[None, :3, 3], world, LIDAR.range_m))
        assert hit_actor > 50  # the actors were in the sweep, not only the town
        assert a.hit.mean() > 0.3
    finally:
        suite.close()


def embree_static(suite: SensorSuite):
    """The static mesh the suite handed to Embree: the town plus its fixtures."""
    from b2d_data.sim.builtin.sensors.fixture_mesh import fixture_static_mesh

    return merge([suite.scene.mesh, fixture_static_mesh(suite.fixtures)])


def test_rig_data_are_the_same_with_either_caster():
    # The whole rig (small cameras, so the GPU caster works in the renderer's context), twice: Embree, then GPU.
    scene = build_static_scene(crossroads_layout(), seed=3)
    out = {}
    for mode in ("off", "on"):
        suite = SensorSuite.from_scene(scene, replace(CONFIG, gpu_rays=mode), seed=11)
        try:
            assert isinstance(suite.caster, GpuRayCaster if mode == "on" else RayCaster)
            if mode == "on":
                assert suite.caster.ctx is suite.renderer.ctx
            out[mode] = [suite.capture(snapshot_of(_actors(), NOON, frame=f), 1) for f in (3, 4)]
        finally:
            suite.close()
    for a, b in zip(out["off"], out["on"]):
        np.testing.assert_array_equal(a.lidar_tags, b.lidar_tags)
        np.testing.assert_array_equal(a.lidar_actor_ids, b.lidar_actor_ids)
        # Points are direction · distance: within the distance tolerance.
        np.testing.assert_allclose(a.lidar, b.lidar, atol=ATOL_M, rtol=0)
        assert list(a.radar) == list(b.radar)
        for key in a.radar:
            np.testing.assert_allclose(a.radar[key], b.radar[key], atol=ATOL_M, rtol=0)
        assert sum(len(r) for r in a.radar.values()) > 10
        np.testing.assert_array_equal(a.cameras["front"].rgb, b.cameras["front"].rgb)


def test_mode_gpu_keeps_embree_on_llvmpipe():
    ctx = create_gl_context()
    try:
        if is_hardware(ctx):
            pytest.skip("a hardware GPU: 'gpu' casts on it")
        assert isinstance(make_ray_caster("gpu", ctx), RayCaster)
    finally:
        ctx.release()
    assert isinstance(make_ray_caster("gpu"), RayCaster)  # opens its own context, finds llvmpipe, keeps Embree
    assert isinstance(make_ray_caster("off"), RayCaster)
    with pytest.raises(ValueError):
        make_ray_caster("yes")
