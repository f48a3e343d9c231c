"""IMU, GNSS and speedometer: CARLA's compass, gravity in the accelerometer, the map's geo projection, noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format.rig import NoiseSpec
from b2d_data.format.transform import Location
from b2d_data.sim.builtin.sensors.imu_gnss import ImuGnss, carla_geolocation, compass_of, geolocator_of
from b2d_data.sim.builtin.sensors.synthetic import actor_state

NO_NOISE = NoiseSpec(gnss_noise_deg=0.0, gnss_noise_alt=0.0, accel_noise=(0.0, 0.0, 0.0), gyro_noise=(0.0, 0.0, 0.0))

_XODR = """<?xml version="1.0"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="4" name="geo">
    <geoReference><![CDATA[+proj=tmerc +lat_0=48.1 +lon_0=11.5 +k=1 +datum=WGS84 +units=m]]></geoReference>
  </header>
  <road name="r" length="100" id="1" junction="-1">
    <planView><geometry s="0" x="0" y="0" hdg="0" length="100"><line/></geometry></planView>
    <lanes><laneSection s="0">
      <center><lane id="0" type="none" level="false"/></center>
      <right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
    </laneSection></lanes>
  </road>
</OpenDRIVE>
"""


@pytest.mark.parametrize("yaw, expected", [(0.0, math.pi / 2), (90.0, math.pi), (180.0, 3 * math.pi / 2), (270.0, 0.0)])
def test_compass_at_the_four_headings(yaw, expected):
    # format.md §4.1: compass = yaw + π/2 (mod 2π); east-facing is π/2, north (−y) is 0.
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 3.0, 4.0, yaw)
    imu, _, _ = ImuGnss(NO_NOISE).read(ego, 0, carla_geolocation)
    assert math.isclose(imu.compass, expected, abs_tol=1e-9)
    assert math.isclose(compass_of(math.cos(math.radians(yaw)), math.sin(math.radians(yaw))), expected, abs_tol=1e-9)


def test_accelerometer_gravity_and_frame():
    # At rest: gravity reads +9.81 on the sensor z axis, whatever the heading.
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 37.0)
    imu, _, speed = ImuGnss(NO_NOISE).read(ego, 0, carla_geolocation)
    np.testing.assert_allclose(imu.accelerometer, (0.0, 0.0, 9.81), atol=1e-12)
    assert speed == 0.0
    # Heading south (+y) while accelerating at 2 m/s² along +y and yawing at 10°/s.
    ego = actor_state(
        1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 90.0, velocity=(0.0, 8.0, 0.0), acceleration=(0.0, 2.0, 0.0),
        angular_velocity=(0.0, 0.0, 10.0),
    )  # fmt: skip
    imu, _, speed = ImuGnss(NO_NOISE).read(ego, 0, carla_geolocation)
    # Sensor 1.4 m behind the origin: centripetal ω²·1.4 m towards the origin, i.e. +x in the sensor frame.
    w = math.radians(10.0)
    np.testing.assert_allclose(imu.accelerometer, (2.0 + w * w * 1.4, 0.0, 9.81), atol=1e-9)
    np.testing.assert_allclose(imu.gyroscope, (0.0, 0.0, w), atol=1e-12)
    assert math.isclose(speed, 8.0)


def test_noise_is_seeded_with_the_listed_std():
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 0.0)
    a = [ImuGnss(seed=5).read(ego, f, carla_geolocation) for f in range(400)]
    b = [ImuGnss(seed=5).read(ego, f, carla_geolocation) for f in range(3)]
    assert a[:3] == b
    acc = np.array([r[0].accelerometer for r in a])
    lat = np.array([r[1].latitude for r in a])
    # std of accel x/z: 0.001/0.015; of latitude: 5e-6 degrees (±25 % for 400 samples).
    assert 0.00075 < acc[:, 0].std() < 0.00125 and 0.011 < acc[:, 2].std() < 0.019
    assert 3.75e-6 < lat.std() < 6.25e-6


def test_gnss_round_trip_through_the_map_projection():
    from b2d_data.maps import load_opendrive

    town = load_opendrive(_XODR, name="Geo")
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 120.0, -340.0, 30.0, ground_z=2.0)
    reader = ImuGnss(NO_NOISE)
    _, gnss, _ = reader.read(ego, 0, geolocator_of(town))
    sensor = reader.sensor_pose(ego)[:3, 3]  # GNSS at (−1.4, 0, 0) on the ego
    lat, lon, alt = carla_geolocation(Location(*sensor), 48.1, 11.5)
    assert math.isclose(gnss.latitude, lat, abs_tol=1e-12) and math.isclose(gnss.longitude, lon, abs_tol=1e-12)
    assert gnss.latitude > 48.1  # −y is north
    back = town.geolocation_to_location(gnss.latitude, gnss.longitude, gnss.altitude)
    np.testing.assert_allclose(back.to_array(), sensor, atol=1e-6)
    assert math.isclose(alt, 2.0)


def test_sensor_poses_are_the_ego_pose_times_each_mount():
    # The mounts' matrices are worked out once per rig (IMU: once per mount); each pose must still be the ego's
    # matrix times the mount's, also for the v0.0.4 radar mounts and after the IMU's mount changed.
    from dataclasses import replace

    from b2d_data.format.rig import CAMERAS, LIDAR, RADARS_V0, RADARS_V004, TOP_DOWN
    from b2d_data.format.transform import Transform
    from b2d_data.sim.api import RigConfig
    from b2d_data.sim.builtin.sensors.suite import SensorSuite
    from b2d_data.sim.builtin.sensors.synthetic import flat_scene

    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 12.5, -3.25, 37.0)
    ego_m = ego.transform.matrix()
    for v004, radars in ((False, RADARS_V0), (True, RADARS_V004)):
        config = RigConfig(cameras=(), lidar=False, radar=False, radar_v004_mounts=v004)
        suite = SensorSuite.from_scene(flat_scene(20.0), config)
        try:
            poses = suite.sensor_poses(ego)
        finally:
            suite.close()
        specs = [*CAMERAS, TOP_DOWN, *radars, LIDAR]
        assert list(poses) == [s.sensor_id for s in specs]
        for spec in specs:
            assert poses[spec.sensor_id].tobytes() == (ego_m @ spec.mount.matrix()).tobytes()
    imu = ImuGnss(NO_NOISE)
    for mount in (NO_NOISE.imu_mount, replace(NO_NOISE.imu_mount, x=0.5, z=1.25)):
        imu.noise = replace(NO_NOISE, imu_mount=mount)
        want = ego_m @ Transform(Location(mount.x, mount.y, mount.z)).matrix()
        assert imu.sensor_pose(ego).tobytes() == want.tobytes()
