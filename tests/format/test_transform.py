"""CARLA transform matrices, worked out by hand."""

from __future__ import annotations

import numpy as np

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform


def test_yaw_90_maps_forward_to_south():
    # CARLA yaw is clockwise seen from above: yaw 90° turns local +x into world +y (south).
    t = Transform(Location(10.0, 20.0, 1.0), Rotation(yaw=90.0))
    p = t.transform_points(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(p, [[10.0, 21.0, 1.0], [9.0, 20.0, 1.0]], atol=1e-12)
    np.testing.assert_allclose(t.inverse_transform_points(p), [[1, 0, 0], [0, 1, 0]], atol=1e-12)


def test_pitch_up_raises_forward_axis():
    fwd = Rotation(pitch=30.0).forward_vector()
    assert abs(fwd.x - np.cos(np.pi / 6)) < 1e-12 and abs(fwd.z - 0.5) < 1e-12


def test_matrix_round_trip():
    t = Transform(Location(1.0, -2.0, 3.0), Rotation(pitch=10.0, yaw=-120.0, roll=5.0))
    np.testing.assert_allclose(t.matrix() @ t.inverse_matrix(), np.eye(4), atol=1e-12)
    back = Transform.from_matrix(t.matrix())
    assert abs(back.rotation.yaw + 120.0) < 1e-9 and abs(back.rotation.roll - 5.0) < 1e-9


def test_world_cord_corner_order():
    box = BoundingBox(Location(0.0, 0.0, 1.0), Location(2.0, 1.0, 0.5))
    corners = box.local_corners()
    np.testing.assert_allclose(corners[0], [2, 1, 1.5])
    np.testing.assert_allclose(corners[3], [2, -1, 0.5])
    np.testing.assert_allclose(corners[7], [-2, -1, 0.5])
