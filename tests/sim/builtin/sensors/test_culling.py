"""One culling pass per view over every material's tiles: visible tiles, nearest first, contiguous ones merged."""

from __future__ import annotations

import numpy as np

from b2d_data.sim.builtin.sensors.renderer import _Culling, _Tiles


def _boxes(x_ranges: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Bounding boxes (lo, hi) of unit-high boxes spanning the given x ranges (y, z in [0, 1])."""
    lo = np.array([(a, 0.0, 0.0) for a, _ in x_ranges])
    hi = np.array([(b, 1.0, 1.0) for _, b in x_ranges])
    return lo, hi


def _culling() -> _Culling:
    # Material 1: tiles at x 0–1, 1–2, 2–3 (vertices 0–9, contiguous) and one at x 100–101 (vertices 9–12).
    # Material 2: one tile at x 3–4 (vertices 12–15).
    one = _Tiles(np.array([0, 3, 6, 9]), np.array([3, 3, 3, 3]), *_boxes([(0, 1), (1, 2), (2, 3), (100, 101)]))
    two = _Tiles(np.array([12]), np.array([3]), *_boxes([(3, 4)]))
    return _Culling({1: one, 2: two})


# Clip space = world scaled by 0.2 (w = 1): x up to 5 is inside, the tile at x = 100 is outside.
VIEWPROJ = np.diag([0.2, 0.2, 0.2, 1.0])


def test_tiles_seen_from_the_far_end_come_nearest_first_and_do_not_merge():
    runs = _culling().runs(VIEWPROJ, np.array([10.0, 0.5, 0.5]))
    # Nearest first: x 2–3 (first 6), 1–2 (first 3), 0–1 (first 0); 6 + 3 ≠ 3, so no two of them merge.
    np.testing.assert_array_equal(runs[1], [[6, 3], [3, 3], [0, 3]])
    np.testing.assert_array_equal(runs[2], [[12, 3]])


def test_tiles_seen_from_the_near_end_merge_into_one_run():
    runs = _culling().runs(VIEWPROJ, np.array([-10.0, 0.5, 0.5]))
    # Order 0–1, 1–2, 2–3: vertex ranges 0+3 = 3, 3+3 = 6, so one run of 9; the x = 100 tile is culled, and the
    # material-2 tile right after it in the buffer (first 12) never merges across materials.
    np.testing.assert_array_equal(runs[1], [[0, 9]])
    np.testing.assert_array_equal(runs[2], [[12, 3]])


def test_a_material_with_nothing_visible_gets_no_runs():
    culling = _culling()
    behind = np.diag([0.2, 0.2, 0.2, 1.0])
    behind[0, 3] = -3.0  # shifts clip x by −3: x 0–4 maps to −3 … −2.2, all left of the view
    runs = culling.runs(behind, np.zeros(3))
    assert runs[2].shape == (0, 2)
    # Only x 100–101 → 17 … 17.2 is right of the view too: nothing of material 1 either.
    assert runs[1].shape == (0, 2)


def test_batch_boxes_are_the_minimum_and_maximum_of_each_batch():
    # _batch_mesh's boxes: per (material, tile) batch, the corner-wise minimum and maximum of its triangles' vertices
    # (worked out here with a reduction over the vertex axis), signed zeros included.
    from b2d_data.sim.builtin.sensors.renderer import _batch_mesh
    from b2d_data.sim.builtin.sensors.scene_mesh import TriangleMesh

    rng = np.random.default_rng(2)
    tris = rng.normal(0.0, 30.0, (500, 3, 3)).astype(np.float32)
    tris[::7, 1, 2] = -0.0
    tris[::7, 2, 2] = 0.0
    mesh = TriangleMesh.from_triangles(tris, (90, 90, 90), 1)
    mesh.materials[:] = rng.integers(0, 7, len(mesh))
    for tile in (None, 16.0):
        batched, batches = _batch_mesh(mesh, tile)
        assert sum(len(b.first) for b in batches.values()) > (1 if tile is None else 7)
        for b in batches.values():
            for first, count, lo, hi in zip(b.first, b.count, b.lo, b.hi):
                rows = batched.vertices[first // 3 : (first + count) // 3].reshape(-1, 3)
                assert lo.tobytes() == rows.min(axis=0).tobytes() and hi.tobytes() == rows.max(axis=0).tobytes()
