"""Oriented-box overlap: broad phase and separating axes."""

from __future__ import annotations

import math

import numpy as np

from b2d_data.sim.builtin import collisions


def _boxes(*rows):
    return collisions.Boxes.from_rows([(cx, cy, math.radians(yaw), hx, hy, 0.0, 1.5) for cx, cy, yaw, hx, hy in rows])


def test_overlapping_and_separated_pairs():
    boxes = _boxes((0, 0, 0, 2, 1), (3.5, 0, 0, 2, 1), (20, 0, 0, 2, 1))
    assert collisions.overlapping_pairs(boxes).tolist() == [[0, 1]]


def test_rotated_boxes_need_the_separating_axis_test():
    # Two 4 × 1 boxes (half 2 × 0.5), the second turned 45° and centred at (3.3, 2.1): the centres are 3.91 m
    # apart, less than the two circumscribed radii (2 × 2.06 m), so the broad phase keeps the pair. The second
    # box's near edge runs from corner c + R45·(−2, 0.5) = (1.53, 1.04) to c + R45·(−2, −0.5) = (2.24, 0.33),
    # i.e. along x + y = 2.57, and the first box's nearest corner (2, 0.5) has x + y = 2.5: separated along
    # the axis (1, 1)/√2, which is one of the second box's edge normals.
    a = _boxes((0, 0, 0, 2, 0.5), (3.3, 2.1, 45, 2, 0.5))
    assert collisions.candidate_pairs(a).tolist() == [[0, 1]]
    assert collisions.overlapping_pairs(a).size == 0
    # centred at (3.0, 1.9) the corner c + R45·(−2, −0.5) = (1.94, 0.13) lies inside the first box
    b = _boxes((0, 0, 0, 2, 0.5), (3.0, 1.9, 45, 2, 0.5))
    assert collisions.overlapping_pairs(b).tolist() == [[0, 1]]


def test_crossed_boxes_overlap_even_with_centres_outside_each_other():
    boxes = _boxes((0, 0, 0, 3, 0.3), (0, 0, 90, 3, 0.3))
    assert collisions.overlapping_pairs(boxes).tolist() == [[0, 1]]


def test_heights_must_overlap_too():
    boxes = collisions.Boxes.from_rows([(0, 0, 0, 2, 1, 0.0, 1.5), (0, 0, 0, 2, 1, 6.0, 7.5)])
    assert collisions.overlapping_pairs(boxes).size == 0


def test_kdtree_broad_phase_agrees_with_all_pairs():
    rng = np.random.default_rng(3)
    n = 150  # above the k-d tree threshold
    rows = [(rng.uniform(0, 60), rng.uniform(0, 60), rng.uniform(-180, 180), 2.2, 1.0) for _ in range(n)]
    boxes = _boxes(*rows)
    fast = collisions.overlapping_pairs(boxes)
    i, j = np.triu_indices(n, k=1)
    brute = np.column_stack([i, j])[collisions.overlap(boxes, i, boxes, j)]
    assert fast.tolist() == brute.tolist()
