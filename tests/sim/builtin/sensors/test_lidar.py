"""LiDAR: points in the ego frame as Bench2Drive stores them, on the surfaces the cameras see, with tags and ids."""

from __future__ import annotations

import math

import numpy as np

from b2d_data.format.rig import LidarSpec, Mount
from b2d_data.sim.builtin.sensors.lidar import Lidar, lidar_directions
from b2d_data.sim.builtin.sensors.raycast import RayCaster
from b2d_data.sim.builtin.sensors.synthetic import actor_state, box_prop, flat_scene, snapshot_of

BOX_ID = 42


def test_points_on_a_box_lie_inside_it_and_carry_its_labels(small_suite, noon):
    # A turned ego away from the origin, so that a frame mix-up (world vs ego, with or without the mount) shows.
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 5.0, -3.0, 30.0, role_name="hero")
    yaw = math.radians(30.0)
    fwd, right = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
    centre = np.array([5.0, -3.0]) + 9.0 * fwd + 1.0 * right
    box = box_prop(BOX_ID, centre[0], centre[1], (1.5, 1.0, 0.9), yaw=75.0, tag=14)
    data = small_suite.capture(snapshot_of([ego, box], noon), ego.id)
    assert data.lidar.dtype == np.float32 and data.lidar.shape[1] == 3
    on_box = data.lidar_actor_ids == BOX_ID
    assert on_box.sum() > 40
    assert (data.lidar_tags[on_box] == 14).all()
    assert (data.lidar_tags[~on_box] == 10).all()  # everything else is the flat terrain
    assert not (data.lidar_actor_ids == ego.id).any()  # the ego's own body is not seen
    # Box corners in the ego frame; every hit must lie inside the box (within 2 cm).
    corners_ego = ego.transform.inverse_transform_points(box.bounding_box.world_corners(box.transform))
    box_yaw = math.radians(75.0 - 30.0)
    c, s = math.cos(box_yaw), math.sin(box_yaw)
    axes = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    centre_ego = corners_ego.mean(axis=0)
    local = (data.lidar[on_box] - centre_ego) @ axes.T
    assert (np.abs(local) <= np.array([1.5, 1.0, 0.9]) + 0.02).all()
    # Terrain hits: the ground is z = 0 in the world and the ego stands on it, so ego-frame z is 0.
    np.testing.assert_allclose(data.lidar[~on_box, 2], 0.0, atol=1e-3)


def test_lowest_channel_ring_on_flat_ground(small_suite, noon):
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 0.0, role_name="hero")
    data = small_suite.capture(snapshot_of([ego], noon), ego.id)
    # 64 channels × 360 azimuths, all rays below the horizon hit the plane within 85 m.
    steps = small_suite.config.lidar_azimuth_steps
    # The −30° channel meets the ground 1.84 / tan 30° = 3.187 m from the sensor, which sits at x = −0.39.
    r = np.hypot(data.lidar[:, 0] + 0.39, data.lidar[:, 1])
    ring = np.abs(r - 1.84 / math.tan(math.radians(30.0))) < 1e-3
    assert ring.sum() == steps
    # Beyond 85 m nothing comes back: the shallowest channel to hit the ground within range is kept, others not.
    assert (np.linalg.norm(data.lidar - np.array([-0.39, 0.0, 1.84]), axis=1) <= 85.0 + 1e-3).all()


def test_ray_straight_down_gives_the_point_below_the_mount():
    # A one-azimuth LiDAR whose last channel points straight down, over flat ground at z = 0.3 m.
    spec = LidarSpec(mount=Mount(-0.39, 0.0, 1.84), channels=11, upper_fov=10.0, lower_fov=-90.0)
    lidar = Lidar(spec, azimuth_steps=1)
    lift = np.eye(4)
    lift[2, 3] = 0.3
    caster = RayCaster(flat_scene().mesh.transformed(lift))
    ego_pose = np.eye(4)
    ego_pose[:3, 3] = (10.0, 20.0, 0.0)
    sensor = ego_pose.copy()
    sensor[:3, 3] += (-0.39, 0.0, 1.84)
    sweep = lidar.scan(caster, sensor)
    down = np.abs(sweep.points[:, 0] + 0.39) < 1e-6
    assert down.sum() == 1
    # Straight down from 1.84 m onto ground at 0.3 m: 1.54 m; in the ego frame (mount added back) z = 0.3.
    np.testing.assert_allclose(sweep.points[down][0], [-0.39, 0.0, 0.3], atol=1e-5)


def test_channel_layout():
    spec = LidarSpec()
    d = lidar_directions(spec, 4).reshape(64, 4, 3)
    elev = np.degrees(np.arcsin(d[:, 0, 2]))
    np.testing.assert_allclose(elev[[0, -1]], [10.0, -30.0], atol=1e-5)
    np.testing.assert_allclose(np.diff(elev), -40.0 / 63.0, atol=1e-4)
    # Azimuth 90° points to +y (right in CARLA's left-handed frame).
    up = math.radians(10.0)
    np.testing.assert_allclose(d[0, 1], [0.0, math.cos(up), math.sin(up)], atol=1e-6)
