"""Driving primitives: IDM, pure pursuit through the bicycle model, junction reservations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.sim import blueprints
from b2d_data.sim.builtin.lane_following import (
    ANY_LANE,
    IdmParams,
    JunctionArbiter,
    idm_accel,
    lookahead_distance,
    pure_pursuit_steer,
)

P = IdmParams()


def test_idm_by_hand():
    assert idm_accel(0.0, 10.0, None, 0.0, P) == pytest.approx(P.max_accel)  # free road, at rest: a
    assert idm_accel(10.0, 10.0, None, 0.0, P) == pytest.approx(0.0)  # at the desired speed
    # standing behind a stopped leader exactly s0 away: s* = s0, so a·(1 − 0 − 1) = 0, it stays
    assert idm_accel(0.0, 10.0, P.min_gap, 0.0, P) == pytest.approx(0.0)
    # closing at 10 m/s on a stopped car 20 m ahead: s* = 10 + 10·1 + 10·10/(2·sqrt(2.5·3)) = 38.26 m
    s_star = 10.0 + 10.0 + 100.0 / (2.0 * math.sqrt(7.5))
    expected = max(-P.max_decel, P.max_accel * (1.0 - (10.0 / 13.9) ** 4 - (s_star / 20.0) ** 2))
    assert idm_accel(10.0, 13.9, 20.0, 0.0, P) == pytest.approx(expected)
    assert idm_accel(5.0, 0.0, None, 0.0, P) < 0.0  # ordered to stop


def test_pure_pursuit_curvature_goes_through_the_bicycle_model():
    g = blueprints.DEFAULT_GEOMETRY
    path = np.column_stack([np.arange(0.0, 30.0), np.zeros(30)])
    assert pure_pursuit_steer(0.0, 0.0, 0.0, 5.0, path, g) == pytest.approx(0.0)
    # 1 m left of the path (−y in CARLA's frame): steer right (positive)
    steer = pure_pursuit_steer(0.0, -1.0, 0.0, 5.0, path, g)
    ld = lookahead_distance(5.0)  # 3.5 m: the aim point is the first path point at least that far
    k = int(np.argmax(np.hypot(path[:, 0], path[:, 1] + 1.0) >= ld))
    alpha = math.atan2(1.0, path[k, 0])
    curvature = 2.0 * math.sin(alpha) / math.hypot(path[k, 0], 1.0)
    assert steer > 0.0 and steer == pytest.approx(g.steer_for_curvature(curvature))


def _lane(points):
    return np.asarray(points, dtype=float)


def test_arbiter_serialises_crossing_lanes_and_not_a_queue():
    arb = JunctionArbiter()
    # a straight north-south lane along x = 0, a straight west-east lane along y = 0, and a tight right turn
    # from the west entry that stays 4 m or more away from x = 0
    north_south, west_east, west_south = (1, 0, 1), (2, 0, 1), (3, 0, 1)
    arb._polylines[north_south] = _lane([(0, y) for y in range(-10, 11)])
    arb._polylines[west_east] = _lane([(x, 0) for x in range(-10, 11)])
    arb._polylines[west_south] = _lane([(x, (x + 10) ** 2 / 10) for x in range(-10, -3)])
    arb._entry_of.update({north_south: (10, 0, -1), west_east: (20, 0, -1), west_south: (20, 0, -1)})
    assert arb.conflict(north_south, west_east)
    assert not arb.conflict(north_south, west_south)
    assert not arb.conflict(west_east, west_south)  # same entry lane: the queue is IDM's business
    granted = arb.update(1, {}, {7: (5, (north_south,)), 8: (5, (west_east,))})
    assert granted == {7}  # first come (same tick: lower id)
    granted = arb.update(2, {}, {7: (5, (north_south,)), 8: (5, (west_east,)), 9: (5, (west_south,))})
    assert granted == {7, 9}
    granted = arb.update(3, {}, {8: (5, (west_east,))})  # 7 has left: 8 may go
    assert granted == {8}
    # a vehicle whose way is unknown (the ego) holds every lane of its junction; 8 has gone, 10 must wait
    assert arb.update(4, {100: (5, (ANY_LANE,))}, {10: (5, (west_east,))}, managed=[8, 10]) == set()
    # ... but not those of another junction
    assert arb.update(5, {100: (6, (ANY_LANE,))}, {10: (5, (west_east,))}, managed=[10]) == {10}
