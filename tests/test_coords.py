"""coords.py: every frame conversion and fix, each against a value worked out by hand in the test."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data import coords
from b2d_data.format.transform import Location, Rotation, Transform

PI = math.pi


def world2ego_at(x: float, y: float, z: float = 0.0, yaw_deg: float = 0.0) -> list[list[float]]:
    """The ``world2ego`` an annotation stores for an ego at (x, y, z) with CARLA yaw ``yaw_deg``."""
    return Transform(Location(x, y, z), Rotation(yaw=yaw_deg)).inverse_matrix().tolist()


# ----------------------------------------------------------------------------------------- fix 1: compass


@pytest.mark.parametrize(
    ("theta", "carla_yaw", "iso_yaw"),
    [
        # Facing east (+x): compass π/2; CARLA yaw 0; ISO yaw 0.
        (PI / 2, 0.0, 0.0),
        # Facing south (CARLA +y): compass π; CARLA yaw +π/2 (clockwise); ISO world y points north ⇒ −π/2.
        (PI, PI / 2, -PI / 2),
        # Facing north (CARLA −y): compass 0; CARLA yaw −π/2; ISO yaw +π/2.
        (0.0, -PI / 2, PI / 2),
        # NaN is a heading due south whose arccos rounded past −1: same as π.
        (float("nan"), PI / 2, -PI / 2),
        (None, PI / 2, -PI / 2),
    ],
)
def test_compass_to_yaw(theta: float | None, carla_yaw: float, iso_yaw: float) -> None:
    assert coords.compass_to_carla_yaw(theta) == pytest.approx(carla_yaw)
    assert coords.compass_to_iso_yaw(theta) == pytest.approx(iso_yaw)


def test_fix_theta_nan_is_pi() -> None:
    assert coords.fix_theta(float("nan")) == PI
    assert coords.fix_theta(1.25) == 1.25


# ------------------------------------------------------------------------------------ fix 2: handedness


def test_flip_y_points_and_yaw() -> None:
    # A point 2 m to the right in CARLA's ego (y right) is 2 m to the *left-negative* side in ISO (y left).
    assert coords.flip_y(np.array([1.0, 2.0, 3.0])).tolist() == [1.0, -2.0, 3.0]
    # A CARLA yaw of +30° (clockwise, turned right) is −30° counter-clockwise in ISO.
    assert coords.carla_yaw_to_iso(math.radians(30)) == pytest.approx(-math.radians(30))


def test_flip_y_matrix_maps_flipped_points() -> None:
    # M: CARLA sensor at (1, 2, 0) yawed +90° (looking right). A point 1 m ahead of it is at CARLA ego (1, 3, 0);
    # in ISO that is (1, −3, 0), and F·M·F applied to the ISO sensor point (1, 0, 0) must give it.
    m = Transform(Location(1.0, 2.0, 0.0), Rotation(yaw=90.0)).matrix()
    assert (m @ [1, 0, 0, 1])[:3] == pytest.approx([1.0, 3.0, 0.0])
    assert (coords.flip_y_matrix(m) @ [1, 0, 0, 1])[:3] == pytest.approx([1.0, -3.0, 0.0])


def test_angular_velocity_is_a_pseudo_vector() -> None:
    # Reflecting y flips the sense of rotation about x and z but not about y: (wx, wy, wz) → (−wx, wy, −wz).
    # A right turn in CARLA has positive yaw rate (clockwise); in ISO a right turn is negative.
    assert coords.angular_velocity_to_frame([0.1, 0.2, 0.3], "iso").tolist() == pytest.approx([-0.1, 0.2, -0.3])
    # The Zoo negates all three.
    assert coords.zoo_ego_rotation_rate([0.1, 0.2, 0.3]).tolist() == pytest.approx([-0.1, -0.2, -0.3])


def test_world_points_to_ego() -> None:
    # Ego at (100, 50) facing south (CARLA yaw 90°): its forward is world +y, its right is world −x.
    # World point (97, 60): 10 m forward, 3 m to the right ⇒ CARLA ego (10, 3), ISO ego (10, −3).
    w2e = np.array(world2ego_at(100.0, 50.0, 0.0, 90.0))
    assert coords.world_points_to_ego(np.array([[97.0, 60.0, 0.0]]), w2e, "carla")[0] == pytest.approx([10, 3, 0])
    assert coords.world_points_to_ego(np.array([[97.0, 60.0, 0.0]]), w2e, "iso")[0] == pytest.approx([10, -3, 0])
    assert coords.world_points_to_ego(np.array([[97.0, 60.0]]), w2e, "iso")[0] == pytest.approx([10, -3])


def test_camera_to_ego_opencv_axes() -> None:
    # CAM_FRONT at CARLA ego (0.8, 0, 1.6), yaw 0. OpenCV point (0, 0, 5) is 5 m down the optical axis
    # ⇒ ISO ego (5.8, 0, 1.6); OpenCV (1, 0, 5) is 1 m to the image right ⇒ ISO y = −1; OpenCV y is down ⇒ z − 1.
    cam2ego = Transform(Location(0.8, 0.0, 1.6)).matrix()
    m = coords.cam_to_ego(cam2ego, "iso")
    assert (m @ [0, 0, 5, 1])[:3] == pytest.approx([5.8, 0.0, 1.6])
    assert (m @ [1, 0, 5, 1])[:3] == pytest.approx([5.8, -1.0, 1.6])
    assert (m @ [0, 1, 5, 1])[:3] == pytest.approx([5.8, 0.0, 0.6])
    # CAM_FRONT_LEFT (yaw −55°): optical axis along CARLA (cos 55°, −sin 55°) ⇒ ISO (0.5736, +0.8192).
    m_left = coords.cam_to_ego(Transform(Location(0.27, -0.55, 1.6), Rotation(yaw=-55.0)).matrix(), "iso")
    axis = m_left[:3, 2]
    assert axis == pytest.approx([math.cos(math.radians(55)), math.sin(math.radians(55)), 0.0])
    # The Zoo's cam2ego is the same matrix.
    assert coords.zoo_cam2ego(cam2ego) == pytest.approx(m)


# -------------------------------------------------------------------------------------- fix 3: extents


def test_half_to_full() -> None:
    # Lincoln MKZ half extents (2.451, 1.064, 0.755) ⇒ 4.902 × 2.128 × 1.51 m.
    assert coords.half_to_full([2.451, 1.064, 0.755]) == pytest.approx([4.902, 2.128, 1.51])
    box = {"class": "vehicle", "type_id": "vehicle.tesla.model3", "extent": [2.0, 1.0, 0.75]}
    assert coords.box_size(box) == pytest.approx([4.0, 2.0, 1.5])


# ---------------------------------------------------------------------------------- fix 4: walker speed


def test_walker_velocity_from_finite_differences() -> None:
    # Walker centre (10, 5, 0) → (10.3, 5.4, 0) in 0.1 s ⇒ world velocity (3, 4, 0), speed 5 m/s.
    v = coords.finite_difference_velocity([10.3, 5.4, 0.0], [10.0, 5.0, 0.0])
    assert v == pytest.approx([3.0, 4.0, 0.0])
    assert coords.zoo_walker_speed([10.3, 5.4, 0.0], [10.0, 5.0, 0.0]) == pytest.approx(5.0)
    # Forward difference on a first frame: next centre with dt = −0.1 gives the same velocity.
    assert coords.finite_difference_velocity([10.0, 5.0, 0.0], [10.3, 5.4, 0.0], dt=-0.1) == pytest.approx([3, 4, 0])
    # In the ego frame of an ego facing south (CARLA yaw 90°): forward = world +y ⇒ 4 m/s forward;
    # CARLA right = world −x ⇒ −3 right; ISO left = world +x (east) ⇒ +3.
    w2e = np.array(world2ego_at(0.0, 0.0, 0.0, 90.0))
    assert coords.world_vectors_to_ego(v[None], w2e, "iso")[0] == pytest.approx([4.0, 3.0, 0.0])
    assert coords.trusts_stored_speed({"class": "walker"}) is False
    assert coords.trusts_stored_speed({"class": "vehicle"}) is True


def test_vehicle_velocity_from_forward_speed() -> None:
    # Vehicle yawed 90° (facing world +y) at 7 m/s ⇒ world velocity (0, 7, 0).
    box = {"class": "vehicle", "speed": 7.0, "center": [0, 0, 0], "world2vehicle": world2ego_at(3.0, 4.0, 0.0, 90.0)}
    assert coords.forward_velocity_world(box) == pytest.approx([0.0, 7.0, 0.0])
    # Null speed counts as 0 (fix 10).
    assert coords.fix_speed(None) == 0.0


# --------------------------------------------------------------------------------- fix 5: static vehicles


def test_static_vehicle_box_from_center_extent_and_world2vehicle() -> None:
    # The prop's location (100, 0) and rotation (yaw 0) are wrong; the box centre is (105, 3, 0.8), the
    # matched bbox half extents (2.4, 1.0, 0.8) and world2vehicle says yaw 90°. Ego at the origin, yaw 0.
    box = {
        "class": "vehicle", "state": "static", "type_id": "/Game/Carla/Static/Car/4Wheeled/ParkedVehicles/x",
        "location": [100.0, 0.0, 0.0], "rotation": [0.0, 0.0, 0.0], "center": [105.0, 3.0, 0.8],
        "extent": [2.4, 1.0, 0.8], "world2vehicle": world2ego_at(105.0, 3.0, 0.0, 90.0),
    }  # fmt: skip
    # ISO ego: centre (105, −3, 0.8); size 4.8 × 2.0 × 1.6; CARLA yaw +90° ⇒ ISO −90°.
    got = coords.box_in_ego(box, np.array(world2ego_at(0, 0, 0, 0)), "iso")
    assert got == pytest.approx([105.0, -3.0, 0.8, 4.8, 2.0, 1.6, -PI / 2])
    got_carla = coords.box_in_ego(box, np.array(world2ego_at(0, 0, 0, 0)), "carla")
    assert got_carla == pytest.approx([105.0, 3.0, 0.8, 4.8, 2.0, 1.6, PI / 2])


def test_box_relative_to_a_turned_ego() -> None:
    # Ego at (10, 10) yaw 90°; vehicle at centre (10, 20, 1) yaw 90°: 10 m straight ahead, same heading.
    box = {
        "class": "vehicle",
        "center": [10.0, 20.0, 1.0],
        "extent": [2, 1, 1],
        "world2vehicle": world2ego_at(10, 20, 0, 90),
    }
    got = coords.box_in_ego(box, np.array(world2ego_at(10, 10, 0, 90)), "iso")
    assert got == pytest.approx([10.0, 0.0, 1.0, 4.0, 2.0, 2.0, 0.0])


# -------------------------------------------------------------------------------------- fix 6: dirt debris


def test_dirt_debris_extents_swapped() -> None:
    # Stored extent (0.5, 2.0, 0.1) has x/y swapped: the real size is 2·(2.0, 0.5, 0.1) = 4.0 × 1.0 × 0.2.
    box = {"class": "traffic_sign", "type_id": "static.prop.dirtdebris01", "extent": [0.5, 2.0, 0.1]}
    assert coords.is_dirt_debris(box)
    assert coords.box_size(box) == pytest.approx([4.0, 1.0, 0.2])


# ----------------------------------------------------------------------------------- fix 7: trigger volumes


def test_trigger_volume_corners() -> None:
    # Volume at (10, 20, 0), yaw 90°, half extents (2, 1). CARLA rotation by 90°: (x, y) → (−y, x).
    # (+2, +1) → (−1, 2) → (9, 22); (−2, +1) → (−1, −2) → (9, 18); (−2, −1) → (1, −2) → (11, 18);
    # (+2, −1) → (1, 2) → (11, 22).
    box = {
        "trigger_volume_location": [10.0, 20.0, 0.0], "trigger_volume_rotation": [0.0, 0.0, 90.0],
        "trigger_volume_extent": [2.0, 1.0, 0.5], "rotation": [0.0, 0.0, 90.0],
    }  # fmt: skip
    corners = coords.trigger_volume_corners(box)
    assert corners[:, :2] == pytest.approx(np.array([[9, 22], [9, 18], [11, 18], [11, 22]], dtype=float))
    # Data following docs/anno.md (rotation relative to the parent): 90 + 90 = 180° ⇒ (+2, +1) → (−2, −1) → (8, 19).
    assert coords.trigger_volume_corners(box, add_parent_rotation=True)[0, :2] == pytest.approx([8.0, 19.0])
    # As a box in the ISO ego frame of an ego at the origin (yaw 0): centre (10, −20, 0), size 4 × 2 × 1, yaw −90°.
    got = coords.trigger_volume_in_ego(box, np.array(world2ego_at(0, 0, 0, 0)))
    assert got == pytest.approx([10.0, -20.0, 0.0, 4.0, 2.0, 1.0, -PI / 2])


# --------------------------------------------------------------------------------------- fix 8: radar mounts


def test_radar_uses_per_frame_radar2ego() -> None:
    # One detection 10 m away at azimuth +90° (to the radar's right), altitude 0 ⇒ radar frame (0, 10, 0).
    det = np.array([[10.0, 0.0, PI / 2, -1.0]])
    assert coords.radar_detections_to_points(det)[0] == pytest.approx([0.0, 10.0, 0.0])
    # The annotation mounts RADAR_BACK_RIGHT at (−2, 0.67, 0.51) yaw 180 (looking back): its right is ego left,
    # so the point is CARLA ego (−2, 0.67 − 10, 0.51) = (−2, −9.33, 0.51) ⇒ ISO (−2, 9.33, 0.51).
    anno = {
        "sensors": {
            "RADAR_BACK_RIGHT": {"radar2ego": Transform(Location(-2, 0.67, 0.51), Rotation(yaw=180)).matrix().tolist()}
        }
    }
    m = coords.radar_to_ego_matrix(anno, "RADAR_BACK_RIGHT")
    assert coords.radar_detections_to_ego(det, m, "iso")[0] == pytest.approx([-2.0, 9.33, 0.51])
    # Without the annotation entry the v0 rig mount is used, with its yaw −90 bug: radar right = ego forward,
    # point = (−2 + 10, 0.67, 0.51) ⇒ ISO (8, −0.67, 0.51).
    fallback = coords.radar_to_ego_matrix({"sensors": {}}, "RADAR_BACK_RIGHT")
    assert coords.radar_detections_to_ego(det, fallback, "iso")[0] == pytest.approx([8.0, -0.67, 0.51])


# ------------------------------------------------------------------------------------ fix 9: GNSS vs exact


def test_gnss_versus_exact_pose() -> None:
    # Exact pose: ego at (100, 50, 0.2) yaw 0. GNSS says (101, 50) with compass π/2 (east, yaw 0).
    anno = {
        "x": 101.0, "y": 50.0, "theta": PI / 2,
        "bounding_boxes": [{"location": [100.0, 50.0, 0.2], "world2ego": world2ego_at(100.0, 50.0, 0.2, 0.0)}],
    }  # fmt: skip
    assert coords.ego_to_world(anno, "exact")[:3, 3] == pytest.approx([100.0, 50.0, 0.2])
    assert coords.ego_to_world(anno, "gnss")[:3, 3] == pytest.approx([101.0, 50.0, 0.2])
    # Seen from the exact ego, the GNSS fix is 1 m ahead.
    assert coords.gnss_xy_in_ego(anno) == pytest.approx([1.0, 0.0])
    # NaN compass in the GNSS pose: facing south (CARLA yaw 90°) ⇒ rotation column 0 = (0, 1, 0).
    anno["theta"] = float("nan")
    assert coords.gnss_ego_to_world(anno)[:3, 0] == pytest.approx([0.0, 1.0, 0.0])


def test_relative_pose() -> None:
    # Ego 0 at (0, 0) yaw 0, ego 1 at (5, 2) yaw 0: seen from ego 0, ego 1 is 5 m ahead, 2 m right ⇒ ISO (5, −2).
    a = Transform(Location(0, 0, 0)).matrix()
    b = Transform(Location(5, 2, 0)).matrix()
    assert coords.relative_pose(a, b, "iso")[:3, 3] == pytest.approx([5.0, -2.0, 0.0])


# ------------------------------------------------------------------------------------------- Zoo frame


def test_zoo_conversions() -> None:
    # ego_yaw = π/2 − nan_to_num(θ, nan=π): NaN ⇒ −π/2.
    assert coords.zoo_ego_yaw(float("nan")) == pytest.approx(-PI / 2)
    # Box size (w, l, h) = 2·(ey, ex, ez).
    assert coords.zoo_box_size([2.0, 1.0, 0.75]) == pytest.approx([2.0, 4.0, 1.5])
    assert coords.zoo_lidar_box_yaw(0.0) == pytest.approx(-PI / 2)
    assert coords.zoo_ego_translation({"x": 3.0, "y": 4.0}) == pytest.approx([3.0, -4.0, 0.0])
    assert coords.zoo_ego_accel([1.0, 2.0, 9.8]) == pytest.approx([1.0, -2.0, 9.8])
    # lidar2ego of the released mount (−0.39, 0, 1.84): rows [0,1,0,−0.39], [−1,0,0,0], [0,0,1,1.84].
    l2e = coords.zoo_lidar2ego(Transform(Location(-0.39, 0.0, 1.84)).matrix())
    assert l2e[:3] == pytest.approx(np.array([[0, 1, 0, -0.39], [-1, 0, 0, 0], [0, 0, 1, 1.84]], dtype=float))
    # An ISO point 10 m ahead at LiDAR height ⇒ Zoo lidar (0, 10.39, 0); 5 m to the left ⇒ lidar x = −5.
    assert coords.iso_to_zoo_lidar(np.array([[10.0, 0.0, 1.84]]))[0] == pytest.approx([0.0, 10.39, 0.0])
    assert coords.iso_to_zoo_lidar(np.array([[0.0, 5.0, 1.84]]))[0] == pytest.approx([-5.0, 0.39, 0.0])
    # world2lidar: lefthand_ego_to_lidar · world2lidar · left2right. A lidar at the world origin, yaw 0:
    # ISO-world point (0, −3, 0) is CARLA (0, 3, 0) = 3 m right ⇒ Zoo lidar x = +3.
    w2l = coords.zoo_world2lidar(Transform().inverse_matrix())
    assert (w2l @ [0, -3, 0, 1])[:3] == pytest.approx([3.0, 0.0, 0.0])
    # world2cam: a camera at the origin looking along world +x; ISO-world point (5, −1, 0) (1 m to the right)
    # ⇒ OpenCV (1, 0, 5).
    assert (coords.zoo_world2cam(Transform().inverse_matrix()) @ [5, -1, 0, 1])[:3] == pytest.approx([1, 0, 5])


def test_batched_boxes_equal_single_boxes() -> None:
    # A light (no world2* matrix: rotation + centre), a static vehicle and a dirt-debris prop, ego yawed 30°.
    boxes = [
        {"class": "traffic_light", "center": [5.0, 6.0, 3.0], "rotation": [0.0, 0.0, 45.0], "extent": [0.5, 0.5, 3.0]},
        {"class": "vehicle", "center": [105.0, 3.0, 0.8], "extent": [2.4, 1.0, 0.8],
         "world2vehicle": world2ego_at(105, 3, 0, 90)},
        {"class": "traffic_sign", "type_id": "static.prop.dirtdebris02", "center": [1, 2, 0], "extent": [0.5, 2.0, 0.1],
         "world2sign": world2ego_at(1, 2, 0, -20)},
    ]  # fmt: skip
    w2e = np.array(world2ego_at(3.0, 4.0, 0.0, 30.0))
    batched, _ = coords.boxes_in_ego(boxes, w2e, "iso")
    for got, box in zip(batched, boxes, strict=True):
        assert got == pytest.approx(coords.box_in_ego(box, w2e, "iso"))
    # The light has no world2* matrix: yaw 45° − ego 30° = 15° CARLA ⇒ −15° ISO.
    assert batched[0, 6] == pytest.approx(-math.radians(15))
    # rigid_inverse equals the general inverse on a rigid transform.
    m = Transform(Location(1, 2, 3), Rotation(pitch=10, yaw=20, roll=30)).matrix()
    assert coords.rigid_inverse(m) == pytest.approx(np.linalg.inv(m))


def test_a_trigger_volume_sign_is_oriented_by_its_box_rotation_not_by_world2sign() -> None:
    # A stop sign: its box (the matched level bbox) faces yaw 90°, its actor (world2sign) is turned to yaw 0°, as
    # CARLA's sign actors and ours are (the landmark turned 90°). Ego at the origin, yaw 0: the box's yaw in the ego
    # frame is 90° CARLA = −90° ISO (y flipped), not the actor's 0°.
    sign = {"class": "traffic_sign", "type_id": "traffic.stop", "center": [10.0, 0.0, 2.0], "rotation": [0.0, 0.0, 90.0],
            "extent": [0.05, 0.4, 0.4], "trigger_volume_extent": [1.0, 1.5, 1.0],
            "world2sign": world2ego_at(10, 0, 0, 0)}  # fmt: skip
    w2e = np.array(world2ego_at(0.0, 0.0, 0.0, 0.0))
    assert coords.box_in_ego(sign, w2e, "iso")[6] == pytest.approx(-math.pi / 2)
    batched, poses = coords.boxes_in_ego([sign], w2e, "iso")
    assert batched[0, 6] == pytest.approx(-math.pi / 2)
    assert poses[0, :3, 3] == pytest.approx([10.0, 0.0, 2.0])
    # a prop without a trigger volume (a warning sign) keeps world2sign's orientation: actor yaw −20° ⇒ 20° ISO
    prop = {"class": "traffic_sign", "type_id": "static.prop.warningconstruction", "center": [1, 2, 0],
            "rotation": [0.0, 0.0, 70.0], "extent": [0.5, 0.5, 1.0], "world2sign": world2ego_at(1, 2, 0, -20)}
    assert coords.box_in_ego(prop, w2e, "iso")[6] == pytest.approx(math.radians(20))
