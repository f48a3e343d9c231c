"""Radar: depth, angles and radial velocity (negative when approaching) of a box driving at the front radar."""

from __future__ import annotations

import math

import numpy as np

from b2d_data.format.rig import RADARS_V0, RADARS_V004
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.radar import radar_ray_directions
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, box_prop, flat_scene, snapshot_of

RADAR_X, RADAR_Z = 2.27, 0.48  # RADAR_FRONT mount


def _detections_to_dirs(det: np.ndarray) -> np.ndarray:
    alt, az = det[:, 1], det[:, 2]
    return np.stack([np.cos(alt) * np.cos(az), np.cos(alt) * np.sin(az), np.sin(alt)], axis=1)


def test_box_approaching_the_front_radar(small_suite, noon):
    # Ego drives +x at 5 m/s; a 12 m wide, 8 m tall box whose face is 20 m ahead comes towards it at 10 m/s.
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 0.0, role_name="hero", velocity=(5.0, 0.0, 0.0))
    box = box_prop(9, 21.0, 0.0, (1.0, 6.0, 4.0), velocity=(-10.0, 0.0, 0.0))
    data = small_suite.capture(snapshot_of([ego, box], noon), ego.id)
    det = data.radar["radar_front"]
    assert det.dtype == np.float32 and det.shape[1] == 4
    assert 0 < len(det) <= 75  # 1500 points/s × 0.05 s
    d = _detections_to_dirs(det)
    # A ray either meets the face x = 20 m (depth·dir_x = 20 − 2.27) or, pointing down steeply enough, the
    # ground first (depth·(−dir_z) = 0.48, the radar's height).
    on_box = np.isclose(det[:, 0] * d[:, 0], 20.0 - RADAR_X, rtol=1e-4)
    on_ground = np.isclose(det[:, 0] * -d[:, 2], RADAR_Z, rtol=1e-4)
    assert (on_box | on_ground).all() and on_box.sum() > 20
    # Radial velocity = (v_target − v_radar) · dir: (−10 − 5)·dir_x for the box, (0 − 5)·dir_x for the
    # ground; negative for both, since both approach the radar.
    np.testing.assert_allclose(det[on_box, 3], -15.0 * d[on_box, 0], atol=1e-4)
    np.testing.assert_allclose(det[~on_box, 3], -5.0 * d[~on_box, 0], atol=1e-4)
    assert (det[:, 3] < 0).all()
    # Angles stay inside the FOV ellipse (half angles 15°).
    assert (np.abs(det[:, 2]) <= math.radians(15.0) + 1e-6).all()
    assert (np.abs(det[:, 1]) <= math.radians(15.0) + 1e-6).all()


def test_static_ground_seen_by_a_moving_radar(small_suite, noon):
    # Nothing in front: the lower half of the cone hits the ground, which is static: velocity = −5 · dir_x.
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 0.0, role_name="hero", velocity=(5.0, 0.0, 0.0))
    det = small_suite.capture(snapshot_of([ego], noon), ego.id).radar["radar_front"]
    assert len(det) > 10
    d = _detections_to_dirs(det)
    assert (d[:, 2] < 0).all()  # only downward rays find the ground within 100 m
    # Ground at z = 0, radar at 0.48 m: depth·(−dir_z) = 0.48.
    np.testing.assert_allclose(det[:, 0] * -d[:, 2], RADAR_Z, rtol=1e-4)
    np.testing.assert_allclose(det[:, 3], -5.0 * d[:, 0], atol=1e-4)


def test_ray_pattern_is_seeded_and_inside_the_cone():
    spec = RADARS_V0[0]
    a = radar_ray_directions(spec, np.random.default_rng(3), 2000)
    b = radar_ray_directions(spec, np.random.default_rng(3), 2000)
    np.testing.assert_array_equal(a, b)
    # CARLA aims at an ellipse spanning the FOV at the far range: y/x ≤ tan 15°, z/x ≤ tan 15°.
    t = math.tan(math.radians(15.0))
    assert ((a[:, 1] / a[:, 0]) ** 2 + (a[:, 2] / a[:, 0]) ** 2 <= t * t + 1e-9).all()


def test_back_radar_mounts_v0_and_v004():
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 0.0, role_name="hero")
    for radars, mounts in ((False, RADARS_V0), (True, RADARS_V004)):
        config = RigConfig(cameras=(), lidar=False, radar_v004_mounts=radars)
        suite = SensorSuite.from_scene(flat_scene(20.0, 10.0), config)
        poses = suite.sensor_poses(ego)
        for spec in mounts:
            fwd = poses[spec.sensor_id][:3, 0]
            yaw = math.radians(spec.mount.yaw)
            np.testing.assert_allclose(fwd, [math.cos(yaw), math.sin(yaw), 0.0], atol=1e-12)
        suite.close()
    # v0 keeps the released collector's back-right yaw bug (−90°); v0.0.4 turns both back radars backwards.
    assert RADARS_V0[4].mount.yaw == -90.0 and RADARS_V004[4].mount.yaw == 180.0
