"""An agent's own sensors (``MountedSensors``, ``attach_sensors``): CARLA's data forms, poses, sweep, drop-off, noise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from b2d_data.format.rig import ALL_CAMERAS, LIDAR
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.sim.api import (
    CAMERA_RGB,
    GNSS,
    IMU,
    LIDAR_RAY_CAST,
    RADAR,
    ActorSpec,
    RigConfig,
    SensorMount,
    SimulatorError,
)
from b2d_data.sim.builtin.sensors.lidar import round_half_away_from_zero
from b2d_data.sim.builtin.sensors.mounted import MountedSensors, bgra_in_place
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, box_prop, flat_scene, snapshot_of

W, H = 64, 48
EGO = "vehicle.lincoln.mkz_2020"

#: A LiDAR whose rays all come back over flat ground: 5 channels at +10, 0, −10, −20, −30°, 3600 points/s →
#: 3600 · 0.05 / 5 = 36 rays per channel and tick, 5° apart over the 180° of a tick; 10 m range; no drop-off
#: (zero_intensity 0 makes the intensity keep probability 0 · I + 1).
NO_DROP = {
    "channels": 5, "upper_fov": 10, "lower_fov": -30, "points_per_second": 3600, "rotation_frequency": 10,
    "range": 10, "atmosphere_attenuation_rate": 0.004, "dropoff_general_rate": 0.0, "dropoff_intensity_limit": 0.8,
    "dropoff_zero_intensity": 0.0,
}  # fmt: skip
#: What the Leaderboard's agent wrapper forces on every LiDAR.
WRAPPER_LIDAR = {
    "range": 85, "rotation_frequency": 10, "channels": 64, "upper_fov": 10, "lower_fov": -30,
    "points_per_second": 600000, "atmosphere_attenuation_rate": 0.004, "dropoff_general_rate": 0.45,
    "dropoff_intensity_limit": 0.8, "dropoff_zero_intensity": 0.4,
}  # fmt: skip
WRAPPER_IMU = {"noise_accel_stddev_x": 0.001, "noise_accel_stddev_y": 0.001, "noise_accel_stddev_z": 0.015,
               "noise_gyro_stddev_x": 0.001, "noise_gyro_stddev_y": 0.001, "noise_gyro_stddev_z": 0.001}  # fmt: skip
WRAPPER_GNSS = {"noise_alt_stddev": 5e-6, "noise_lat_stddev": 5e-6, "noise_lon_stddev": 5e-6, "noise_alt_bias": 0.0,
                "noise_lat_bias": 0.0, "noise_lon_bias": 0.0}  # fmt: skip


def _at(x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw: float = 0.0, pitch: float = 0.0) -> Transform:
    return Transform(Location(x, y, z), Rotation(pitch=pitch, yaw=yaw))


def _mount(sensor_id: str, type_id: str, transform: Transform, attributes: dict) -> SensorMount:
    return SensorMount(sensor_id, type_id, transform, {k: str(v) for k, v in attributes.items()})


def _camera(sensor_id: str, transform: Transform, fov: float, width: int = W, height: int = H) -> SensorMount:
    return _mount(sensor_id, CAMERA_RGB, transform, {"image_size_x": width, "image_size_y": height, "fov": fov})


def _lidar(transform: Transform, sensor_id: str = "LIDAR", **changes: float) -> SensorMount:
    return _mount(sensor_id, LIDAR_RAY_CAST, transform, {**NO_DROP, **changes})


def _unit_xy(azimuth_deg: np.ndarray) -> np.ndarray:
    a = np.radians(azimuth_deg)
    return np.stack([np.cos(a), np.sin(a)], axis=1)


@pytest.fixture(scope="module")
def scene():
    return flat_scene(half_size=120.0)


# ------------------------------------------------------------------------------------------------ cameras
def test_cameras_are_the_rigs_rgb_as_bgra(scene, noon):
    # Every Bench2Drive camera pose mounted by an agent at the rig's size sees exactly the rig's pixels, as BGRA.
    cfg = RigConfig(width=W, height=H, top_down_width=W, top_down_height=H, lidar=False, radar=False)
    suite = SensorSuite.from_scene(scene, cfg)
    rig = MountedSensors.from_scene(scene, [_camera(c.sensor_id, c.mount.transform(), c.fov) for c in ALL_CAMERAS])
    try:
        ego = actor_state(1, EGO, 3.0, -2.0, 20.0, role_name="hero")
        others = [box_prop(5, 15.0, 2.0, (1.0, 1.5, 1.0), tag=20), actor_state(6, "vehicle.tesla.model3", -9.0, -4.0)]
        snap = snapshot_of([ego, *others], noon)
        expected = suite.capture(snap, 1).cameras
        got = rig.capture(snap, 1)
        assert list(got) == [c.sensor_id for c in ALL_CAMERAS]
        for c in ALL_CAMERAS:
            img = got[c.sensor_id]
            assert img.shape == (H, W, 4) and img.dtype == np.uint8
            assert (img[..., 3] == 255).all()
            rgb = expected[c.folder].rgb
            assert (rgb[..., 0] != rgb[..., 2]).any()  # a missing swap would show
            np.testing.assert_array_equal(img[..., 2::-1], rgb)
        # Read back through one pixel-pack buffer (the hardware GPU path), the cameras share one block of memory.
        rig.renderer.pixel_buffer = True
        again = rig.capture(snap, 1)
        for c in ALL_CAMERAS:
            np.testing.assert_array_equal(again[c.sensor_id], got[c.sensor_id])
    finally:
        suite.close()
        rig.close()


def test_bgra_swaps_in_place_inside_a_shared_block():
    # Two 2×3 RGBA images packed in one block (as the pixel-pack buffer reads them), handed over as RGB views.
    block = np.arange(64 + 24, dtype=np.uint8)
    rgba = block[64:].reshape(2, 3, 4)
    before = rgba.copy()
    out = bgra_in_place(rgba[..., :3])
    np.testing.assert_array_equal(out, before[..., [2, 1, 0, 3]])
    assert np.shares_memory(out, block)
    # An RGB image of its own becomes a new BGRA image with alpha 255.
    rgb = np.arange(18, dtype=np.uint8).reshape(2, 3, 3)
    out = bgra_in_place(rgb)
    np.testing.assert_array_equal(out[..., :3], rgb[..., ::-1])
    assert (out[..., 3] == 255).all()


def test_camera_turned_back_sees_what_a_camera_facing_back_sees(scene, noon):
    # 3 m up (the ego's body, under 1.51 m, stays below a 60° camera's view); a box 12 m behind the ego.
    back, front = _camera("back", _at(z=3.0, yaw=180.0), 60.0), _camera("front", _at(z=3.0), 60.0)
    rig = MountedSensors.from_scene(scene, [back, front])
    try:
        box = box_prop(5, -12.0, 1.0, (1.0, 1.5, 1.0))
        facing_east = rig.capture(snapshot_of([actor_state(1, EGO, 0.0, 0.0, 0.0), box], noon), 1)
        facing_west = rig.capture(snapshot_of([actor_state(1, EGO, 0.0, 0.0, 180.0), box], noon), 1)
        a, b = facing_east["back"], facing_west["front"]
        # The same view; the two poses' matrices differ in the last bits (cos 180° vs products), a pixel or so.
        assert (a != b).any(axis=-1).mean() < 0.01
        assert (a != facing_east["front"]).any(axis=-1).mean() > 0.05  # the box is in view, behind the ego
    finally:
        rig.close()


# ------------------------------------------------------------------------------------------------ LiDAR
def test_round_half_away_from_zero():
    assert [round_half_away_from_zero(x) for x in (36.5, -2.5, 468.75, 2.4999, 0.0)] == [37, -3, 469, 2, 0]


def test_lidar_on_flat_ground_sweeps_half_a_turn_per_tick(scene, noon):
    # Sensor 2 m above the ground. Of the five channels only −20° (ground 2 / sin 20° = 5.85 m away) and −30° (4 m)
    # hit within 10 m: +10° and 0° never meet the ground, −10° meets it at 2 / sin 10° = 11.5 m.
    rig = MountedSensors.from_scene(scene, [_lidar(_at(0.5, 0.0, 2.0))], start_frame=10)
    ego = actor_state(1, EGO, 5.0, -3.0, 30.0)
    expected_half = {11: -180.0, 12: 0.0, 14: 0.0, 15: -180.0}  # frame 13 is skipped: the turn goes on
    try:
        for frame, first in expected_half.items():
            pts = rig.capture(snapshot_of([ego], noon, frame=frame), 1)["LIDAR"]
            assert pts.dtype == np.float32 and pts.shape == (2 * 36, 4)
            np.testing.assert_allclose(pts[:, 2], -2.0, atol=1e-5)
            # Channel-major: 36 points of −20°, then 36 of −30°, at horizontal distances 2 / tan(elevation).
            horizontal = np.hypot(pts[:, 0], pts[:, 1])
            np.testing.assert_allclose(horizontal[:36], 2.0 / math.tan(math.radians(20.0)), rtol=1e-5)
            np.testing.assert_allclose(horizontal[36:], 2.0 / math.tan(math.radians(30.0)), rtol=1e-5)
            # Azimuths first, first + 5°, … first + 175° (towards +y), in casting order in each channel.
            azimuths = first + 5.0 * np.arange(36)
            for ring in (pts[:36], pts[36:]):
                np.testing.assert_allclose(ring[:, :2] / np.hypot(ring[:, 0], ring[:, 1])[:, None],
                                           _unit_xy(azimuths), atol=1e-5)  # fmt: skip
            np.testing.assert_allclose(pts[:, 3], np.exp(-0.004 * np.linalg.norm(pts[:, :3], axis=1)), rtol=1e-6)
    finally:
        rig.close()


def test_wrapper_lidar_count_and_half_turn(scene, noon):
    # 600000 · 0.05 / 64 = 468.75 → 469 rays per channel and tick; the first tick covers azimuths [−180°, 0°).
    rig = MountedSensors.from_scene(scene, [_lidar(LIDAR.mount.transform(), **WRAPPER_LIDAR)])
    try:
        lidar = rig.lidars[0][1]
        assert (lidar.points_per_channel, lidar.tick_angle) == (469, 180.0)
        first = rig.capture(snapshot_of([actor_state(1, EGO, 0.0, 0.0)], noon, frame=1), 1)["LIDAR"]
        second = rig.capture(snapshot_of([actor_state(1, EGO, 0.0, 0.0)], noon, frame=2), 1)["LIDAR"]
        assert (first[:, 1] <= 0.0).all() and (second[:, 1] >= 0.0).all()
        assert 0 < len(first) < 64 * 469
    finally:
        rig.close()


@pytest.mark.parametrize("attenuation", [0.004, 0.03])
def test_general_and_intensity_drop_off_rates(scene, noon, attenuation):
    # The wrapper's drop-off against the same LiDAR without any: the kept points are a subset of the undropped
    # hits, and their number is Σ 0.55 · p(I) over those hits, where p(I) = 1 above the 0.8 limit and
    # 0.4 / 0.8 · I + (1 − 0.4) at or below it. At 0.03/m intensities fall to the limit 7.4 m away.
    forced = {**WRAPPER_LIDAR, "atmosphere_attenuation_rate": attenuation, "channels": 32}
    free = {**forced, "dropoff_general_rate": 0.0, "dropoff_zero_intensity": 0.0}
    pose = LIDAR.mount.transform()
    rig = MountedSensors.from_scene(scene, [_lidar(pose, "forced", **forced), _lidar(pose, "free", **free)], seed=4)
    ego = actor_state(1, EGO, 0.0, 0.0, 0.0)
    box = box_prop(5, 12.0, 3.0, (2.0, 2.0, 1.5))
    kept = {"bright": 0, "dim": 0}
    expected = {"bright": 0.0, "dim": 0.0}
    dim_hits = 0
    try:
        for frame in range(1, 9):
            data = rig.capture(snapshot_of([ego, box], noon, frame=frame), 1)
            got, all_hits = data["forced"], data["free"]
            rows = {r.tobytes() for r in all_hits}
            assert all(r.tobytes() in rows for r in got)
            intensity = all_hits[:, 3].astype(np.float64)
            bright = intensity > 0.8
            expected["bright"] += 0.55 * bright.sum()
            expected["dim"] += 0.55 * (0.5 * intensity[~bright] + 0.6).sum()
            dim_hits += int((~bright).sum())
            kept["bright"] += int((got[:, 3] > 0.8).sum())
            kept["dim"] += int((got[:, 3] <= 0.8).sum())
    finally:
        rig.close()
    assert sum(kept.values()) == pytest.approx(sum(expected.values()), rel=0.02)
    for part in ("bright", "dim"):
        assert kept[part] == pytest.approx(expected[part], rel=0.03), part
    if attenuation == 0.03:  # many hits are dim: the intensity drop-off takes a visible share of them
        assert dim_hits > 10000 and kept["dim"] / dim_hits < 0.55 * 0.9


def test_lidar_yawed_90_degrees_reports_the_same_world_points_rotated(scene, noon):
    # Two LiDARs at one place, one yawed 90°: over a full turn (two ticks of 36 azimuths 5° apart) both cast the
    # same world rays (90° is 18 steps). A box breaks the ground's symmetry.
    pose = {"x": 0.3, "y": 0.2, "z": 2.0}
    rig = MountedSensors.from_scene(scene, [_lidar(_at(**pose), "a", range=30, channels=9, lower_fov=-20),
                                            _lidar(_at(**pose, yaw=90.0), "b", range=30, channels=9, lower_fov=-20)])  # fmt: skip
    actors = [actor_state(1, EGO, 4.0, 2.0, 25.0), box_prop(5, 12.0, 9.0, (2.0, 1.0, 3.0), yaw=10.0)]
    try:
        turn = [rig.capture(snapshot_of(actors, noon, frame=f), 1) for f in (1, 2)]
    finally:
        rig.close()
    a = np.concatenate([t["a"] for t in turn])
    b = np.concatenate([t["b"] for t in turn])
    # b's frame is a's turned by yaw 90° (x → y): a point p_b reads R(90°) · p_b in a's frame.
    b_in_a = b[:, :3] @ _at(yaw=90.0).matrix()[:3, :3].T
    assert len(a) > 150 and abs(len(a) - len(b)) <= 2
    dist, _ = cKDTree(a[:, :3]).query(b_in_a)
    assert (dist < 1e-3).mean() > 0.995
    # Box hits (above the ground) are in both.
    assert (a[:, 2] > -1.9).sum() > 10


# ------------------------------------------------------------------------------------------------ radar
def _directions(det: np.ndarray) -> np.ndarray:
    alt, az = det[:, 1], det[:, 2]
    return np.stack([np.cos(alt) * np.cos(az), np.cos(alt) * np.sin(az), np.sin(alt)], axis=1)


def test_radar_columns_and_radial_velocity_sign(scene, noon):
    # A parked ego; a box ahead drives at it (−10 m/s), one behind drives away (−6 m/s along x, away from the
    # back radar that looks along −x). Columns: depth, altitude, azimuth, velocity.
    attrs = {"horizontal_fov": 30, "vertical_fov": 30, "points_per_second": 1500, "range": 100}
    front = _mount("front", RADAR, _at(2.27, 0.0, 0.48), attrs)
    back = _mount("back", RADAR, _at(-2.0, 0.0, 0.5, yaw=180.0), attrs)
    rig = MountedSensors.from_scene(scene, [front, back])
    ahead = box_prop(5, 21.0, 0.0, (1.0, 6.0, 4.0), velocity=(-10.0, 0.0, 0.0))
    behind = box_prop(6, -17.0, 0.0, (1.0, 6.0, 4.0), velocity=(-6.0, 0.0, 0.0))
    try:
        data = rig.capture(snapshot_of([actor_state(1, EGO, 0.0, 0.0), ahead, behind], noon), 1)
    finally:
        rig.close()
    for key, face, speed in (("front", 20.0 - 2.27, -10.0), ("back", 16.0 - 2.0, 6.0)):
        det = data[key]
        assert det.dtype == np.float32 and det.shape[1] == 4 and 0 < len(det) <= 75  # int(1500 · 0.05)
        d = _directions(det)
        on_box = np.isclose(det[:, 0] * d[:, 0], face, rtol=1e-4)
        assert on_box.sum() > 20
        # Radial velocity (target − radar) · direction: the box's speed along the ray; the ground's 0.
        np.testing.assert_allclose(det[on_box, 3], speed * d[on_box, 0], atol=1e-4)
        assert np.sign(det[on_box, 3]).tolist() == [np.sign(speed)] * int(on_box.sum())
        np.testing.assert_allclose(det[~on_box, 3], 0.0, atol=1e-5)


# ------------------------------------------------------------------------------------------------ GNSS / IMU
#: A town of no roads whose geo-reference is (48.1°, 11.5°).
_GEO_XODR = """<?xml version="1.0"?>
<OpenDRIVE><header revMajor="1" revMinor="4" name="geo">
<geoReference><![CDATA[+proj=tmerc +lat_0=48.1 +lon_0=11.5]]></geoReference></header></OpenDRIVE>
"""


def test_gnss_and_imu_at_their_mounts(noon):
    from b2d_data.maps import load_opendrive

    town = load_opendrive(_GEO_XODR, name="Geo")
    # The GNSS mount's rotation is ignored; the IMU's counts (yawed 90° on the ego: compass of yaw 30 + 90).
    mounts = [
        _mount("GPS", GNSS, _at(-1.4, 0.5, 0.3, yaw=45.0), WRAPPER_GNSS),
        _mount("BIASED", GNSS, _at(-1.4, 0.5, 0.3), {"noise_lat_bias": 0.001, "noise_alt_bias": -2.0}),
        _mount("IMU", IMU, _at(-1.4, 0.0, 0.0), WRAPPER_IMU),
        _mount("IMU_SIDE", IMU, _at(yaw=90.0), {}),
    ]
    rig = MountedSensors(town, mounts, seed=2)
    try:
        assert rig.renderer is None and rig.caster is None  # nothing to mesh for these
        ego = actor_state(1, EGO, 120.0, -340.0, 30.0, ground_z=2.0)
        data = rig.capture(snapshot_of([ego], noon), 1)
    finally:
        rig.close()
    # Mount (−1.4, 0.5, 0.3) on an ego at (120, −340, 2) with yaw 30°: world = ego + R(30°) · mount.
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    where = Location(120.0 + c * -1.4 - s * 0.5, -340.0 + s * -1.4 + c * 0.5, 2.3)
    geo = town.transform_to_geolocation(where)
    gps = data["GPS"]
    assert gps.dtype == np.float64 and gps.shape == (3,)
    np.testing.assert_allclose(gps, [geo.latitude, geo.longitude, geo.altitude], rtol=0, atol=4 * 5e-6)
    np.testing.assert_allclose(data["BIASED"], [geo.latitude + 0.001, geo.longitude, geo.altitude - 2.0], atol=1e-12)
    imu = data["IMU"]
    assert imu.dtype == np.float64 and imu.shape == (7,)
    # At rest and level: gravity on the sensor's z, no rotation, compass = yaw + π/2 (within 5 noise stds).
    stds = np.array([0.001, 0.001, 0.015, 0.001, 0.001, 0.001])
    assert (np.abs(imu[:6] - [0.0, 0.0, 9.81, 0.0, 0.0, 0.0]) < 5 * stds).all()
    assert imu[6] == pytest.approx(math.radians(30.0) + math.pi / 2, abs=1e-9)
    np.testing.assert_allclose(data["IMU_SIDE"], [0.0, 0.0, 9.81, 0.0, 0.0, 0.0, math.radians(120.0) + math.pi / 2],
                               atol=1e-12)  # fmt: skip


# ------------------------------------------------------------------------------------------------ determinism
def test_same_seed_and_frame_give_identical_data(scene, noon):
    mounts = [
        _camera("cam", _at(0.8, 0.0, 1.6), 70.0, 32, 24),
        _lidar(LIDAR.mount.transform(), **{**WRAPPER_LIDAR, "channels": 16, "points_per_second": 100000}),
        _mount("radar", RADAR, _at(2.27, 0.0, 0.48), {}),
        _mount("imu", IMU, _at(-1.4), WRAPPER_IMU),
        _mount("gps", GNSS, _at(-1.4), WRAPPER_GNSS),
    ]
    actors = [actor_state(1, EGO, 0.0, 0.0, 10.0, velocity=(4.0, 0.0, 0.0)), box_prop(5, 15.0, 1.0, (1.0, 2.0, 1.0))]
    runs = []
    for seed, frame in ((3, 7), (3, 7), (3, 8), (4, 7)):
        rig = MountedSensors.from_scene(scene, mounts, seed=seed)
        try:
            runs.append(rig.capture(snapshot_of(actors, noon, frame=frame), 1))
        finally:
            rig.close()
    for key in runs[0]:
        np.testing.assert_array_equal(runs[0][key], runs[1][key])
    for other in runs[2:]:  # another frame or seed draws other drop-offs, radar rays and noise
        for key in ("LIDAR", "radar", "imu", "gps"):
            assert not np.array_equal(runs[0][key], other[key]), key


# ------------------------------------------------------------------------------------------------ the world
def test_world_attach_read_and_release(flat_world):
    with pytest.raises(SimulatorError, match="attach_sensors"):
        flat_world.read_attached_sensors()
    ego = flat_world.spawn_actor(ActorSpec(EGO, role_name="hero"), _at())
    with pytest.raises(SimulatorError, match=r"'DEPTH'.*sensor\.camera\.depth.*sensor\.camera\.rgb"):
        flat_world.attach_sensors(ego, [SensorMount("DEPTH", "sensor.camera.depth")])
    with pytest.raises(SimulatorError, match="'IMU' is used twice"):
        flat_world.attach_sensors(ego, [SensorMount("IMU", IMU), SensorMount("IMU", GNSS)])
    flat_world.tick()
    # Attached at frame 1: the tick to frame 2 is the sensor's first, from horizontal angle 0 (azimuths −180…−5).
    flat_world.attach_sensors(ego, [_lidar(_at(z=2.0)), _mount("IMU", IMU, _at(-1.4), {})])
    flat_world.attach_rig(ego, RigConfig(cameras=(), radar=False, lidar_azimuth_steps=36))
    flat_world.tick()
    data = flat_world.read_attached_sensors()
    assert list(data) == ["LIDAR", "IMU"]
    assert data["LIDAR"].shape == (72, 4) and (data["LIDAR"][:, 1] <= 0.0).all()
    np.testing.assert_allclose(data["IMU"][:3], [0.0, 0.0, 9.81], atol=1e-9)
    assert len(flat_world.read_sensors().lidar) > 0  # the Bench2Drive rig runs alongside
    flat_world.tick()
    assert (flat_world.read_attached_sensors()["LIDAR"][:, 1] >= 0.0).all()
    flat_world.destroy_actor(ego)
    with pytest.raises(SimulatorError):
        flat_world.read_attached_sensors()
