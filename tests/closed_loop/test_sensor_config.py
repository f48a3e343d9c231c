"""The Leaderboard's sensor rules (Bench2Drive's values) and the mounts the agent wrapper would spawn."""

from __future__ import annotations

import math
from typing import Any

import pytest

from b2d_data.closed_loop import sensor_config as sc
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.sim.api import SensorMount

SENSORS = sc.Track.SENSORS


def _camera(sensor_id: str, x: float, y: float, yaw: float, fov: float = 70) -> dict[str, Any]:
    return {"type": "sensor.camera.rgb", "x": x, "y": y, "z": 1.60, "roll": 0.0, "pitch": 0.0, "yaw": yaw,
            "width": 1600, "height": 900, "fov": fov, "id": sensor_id}  # fmt: skip


def uniad_rig() -> list[dict[str, Any]]:
    """UniAD's Bench2Drive rig: six cameras, IMU, GPS, speedometer and the top-down 'bev' camera at z = 50."""
    return [
        _camera("CAM_FRONT", 0.80, 0.0, 0.0),
        _camera("CAM_FRONT_LEFT", 0.27, -0.55, -55.0),
        _camera("CAM_FRONT_RIGHT", 0.27, 0.55, 55.0),
        _camera("CAM_BACK", -2.0, 0.0, 180.0, fov=110),
        _camera("CAM_BACK_LEFT", -0.32, -0.55, -110.0),
        _camera("CAM_BACK_RIGHT", -0.32, 0.55, 110.0),
        {"type": "sensor.other.imu", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
         "sensor_tick": 0.05, "id": "IMU"},
        {"type": "sensor.other.gnss", "x": -1.4, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
         "sensor_tick": 0.01, "id": "GPS"},
        {"type": "sensor.speedometer", "reading_frequency": 20, "id": "SPEED"},
        {"type": "sensor.camera.rgb", "x": 0.0, "y": 0.0, "z": 50.0, "roll": 0.0, "pitch": -90.0, "yaw": 0.0,
         "width": 512, "height": 512, "fov": 5 * 10.0, "id": "bev"},
    ]  # fmt: skip


@pytest.fixture(autouse=True)
def _no_save_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SAVE_PATH", raising=False)


def _reject(sensors: list[dict[str, Any]], message: str, track: Any = SENSORS, selected: Any = "SENSORS") -> None:
    with pytest.raises(sc.SensorConfigurationInvalid, match=message):
        sc.validate_sensor_configuration(sensors, track, selected)


def test_limits_are_bench2drives() -> None:
    assert sc.SENSORS_LIMITS == {
        "sensor.camera.rgb": 8, "sensor.lidar.ray_cast": 2, "sensor.other.radar": 4, "sensor.other.gnss": 1,
        "sensor.other.imu": 1, "sensor.opendrive_map": 1, "sensor.speedometer": 1,
    }  # fmt: skip
    assert list(sc.QUALIFIER_SENSORS_LIMITS.values()) == [4, 1, 2, 1, 1, 1, 1]


def test_uniad_rig_needs_save_path_for_its_bev_camera(monkeypatch: pytest.MonkeyPatch) -> None:
    assert sc.max_allowed_radius() == 3.0
    _reject(uniad_rig(), r"Illegal sensor extrinsics used for sensor 'bev'. Max allowed radius is 3.0m")
    sc.validate_sensor_configuration(uniad_rig()[:-1], SENSORS, "SENSORS")  # without bev every mount is within 3 m
    monkeypatch.setenv("SAVE_PATH", "/tmp/eval")
    assert sc.max_allowed_radius() == 100.0
    sc.validate_sensor_configuration(uniad_rig(), SENSORS, "SENSORS")


def test_wrong_track() -> None:
    _reject(uniad_rig()[:-1], r"You are submitting to the wrong track \[Track.MAP\]!", SENSORS, "MAP")


def test_duplicated_id() -> None:
    _reject([_camera("CAM", 0, 0, 0), _camera("CAM", 0, 0, 90)], r"Duplicated sensor tag \[CAM\]")


def test_opendrive_map_only_on_map_tracks() -> None:
    opendrive = {"type": "sensor.opendrive_map", "reading_frequency": 1, "id": "OpenDRIVE"}
    _reject([opendrive], r"Illegal sensor 'sensor.opendrive_map' used for Track \[Track.SENSORS\]!")
    sc.validate_sensor_configuration([opendrive], sc.Track.MAP, "MAP")


def test_illegal_type() -> None:
    depth = {**_camera("DEPTH", 0, 0, 0), "type": "sensor.camera.depth"}
    _reject([depth], r"Illegal sensor 'sensor.camera.depth' used for Track \[Track.SENSORS\]!")


def test_extrinsics_radius() -> None:
    _reject([{**_camera("HIGH", 0, 0, 0), "z": 3.01}], r"extrinsics used for sensor 'HIGH'. Max allowed radius is 3.0m")
    sc.validate_sensor_configuration([{**_camera("EDGE", 0, 0, 0), "x": 1.8, "z": 2.4}], SENSORS, "SENSORS")  # 3.0 m


def test_too_many_of_a_type() -> None:
    cameras = [_camera(f"CAM{i}", 0, 0, 0) for i in range(9)]
    _reject(cameras, "Too many sensor.camera.rgb used! Maximum number allowed is 8, but 9 were requested.")
    sc.validate_sensor_configuration(cameras[:8], SENSORS, "SENSORS")
    qualifier = sc.Track.SENSORS_QUALIFIER
    _reject(cameras[:5], "Maximum number allowed is 4, but 5 were requested", qualifier, "SENSORS_QUALIFIER")
    gnss = {"type": "sensor.other.gnss", "x": 0, "y": 0, "z": 0, "id": "GPS"}
    _reject([gnss, {**gnss, "id": "GPS2"}], "Too many sensor.other.gnss used! Maximum number allowed is 1, but 2")


def test_missing_keys_are_named() -> None:
    camera = _camera("CAM_FRONT", 0.8, 0, 0)
    del camera["width"]
    _reject([camera], r"sensor 'CAM_FRONT' of type 'sensor.camera.rgb' lacks required key\(s\) 'width'")
    _reject([{"type": "sensor.other.radar", "x": 0, "y": 0, "z": 0, "id": "R"}], "'horizontal_fov', 'vertical_fov'")
    _reject([{"type": "sensor.camera.rgb"}], "sensor #0 lacks the required key 'id'")
    _reject([{**_camera("CAM", 0, 0, 0), "x": "front"}], "sensor 'CAM': 'x' must be a number, got 'front'")


def test_preprocess_camera_and_pose() -> None:
    mount = sc.preprocess_sensor_spec(_camera("CAM_FRONT_LEFT", 0.27, -0.55, -55.0))
    assert mount == SensorMount(
        sensor_id="CAM_FRONT_LEFT", type_id="sensor.camera.rgb",
        transform=Transform(Location(0.27, -0.55, 1.60), Rotation(pitch=0.0, yaw=-55.0, roll=0.0)),
        attributes={"image_size_x": "1600", "image_size_y": "900", "fov": "70"},
    )  # fmt: skip
    bare = sc.preprocess_sensor_spec({"type": "sensor.camera.rgb", "x": 1, "y": 2, "z": 3, "width": 8, "height": 6,
                                      "fov": 90, "id": "C"})  # fmt: skip
    assert bare.transform == Transform(Location(1.0, 2.0, 3.0), Rotation())  # roll/pitch/yaw default to 0


def test_preprocess_lidar_radar_gnss_imu() -> None:
    pose = {"x": 0.0, "y": 0.0, "z": 2.5, "roll": 0.0, "pitch": 0.0, "yaw": -90.0}
    lidar = sc.preprocess_sensor_spec({"type": "sensor.lidar.ray_cast", "id": "LIDAR", **pose})
    assert lidar.attributes == {
        "range": "85", "rotation_frequency": "10", "channels": "64", "upper_fov": "10", "lower_fov": "-30",
        "points_per_second": "600000", "atmosphere_attenuation_rate": "0.004", "dropoff_general_rate": "0.45",
        "dropoff_intensity_limit": "0.8", "dropoff_zero_intensity": "0.4",
    }  # fmt: skip
    assert lidar.transform.rotation.yaw == -90.0 and lidar.attribute("channels", 0) == 64.0
    radar = sc.preprocess_sensor_spec({"type": "sensor.other.radar", "id": "R", "horizontal_fov": 30,
                                       "vertical_fov": 10.5, **pose})  # fmt: skip
    assert radar.attributes == {"horizontal_fov": "30", "vertical_fov": "10.5", "points_per_second": "1500",
                                "range": "100"}  # fmt: skip
    gnss = sc.preprocess_sensor_spec({"type": "sensor.other.gnss", "id": "GPS", **pose, "x": -1.4})
    assert gnss.transform == Transform(Location(-1.4, 0.0, 2.5), Rotation())  # the wrapper ignores its rotation
    assert gnss.attributes["noise_lat_stddev"] == "5e-06" and gnss.attributes["noise_alt_bias"] == "0.0"
    assert gnss.attribute("noise_lon_stddev", 0.0) == 0.000005
    imu = sc.preprocess_sensor_spec({"type": "sensor.other.imu", "id": "IMU", **pose})
    assert [imu.attribute(f"noise_accel_stddev_{a}", 0) for a in "xyz"] == [0.001, 0.001, 0.015]
    assert [imu.attribute(f"noise_gyro_stddev_{a}", 0) for a in "xyz"] == [0.001, 0.001, 0.001]
    assert imu.transform.rotation.yaw == -90.0


def test_preprocess_pseudo_sensors() -> None:
    speed = sc.preprocess_sensor_spec({"type": "sensor.speedometer", "reading_frequency": 7, "id": "SPEED"})
    assert speed == sc.PseudoSensor("SPEED", "sensor.speedometer", 20.0)  # forced to 1 / Δt, the spec's 7 ignored
    assert math.isclose(sc.preprocess_sensor_spec({"type": "sensor.speedometer", "id": "S"}, 0.1).reading_frequency,
                        10.0)  # fmt: skip
    opendrive = sc.preprocess_sensor_spec({"type": "sensor.opendrive_map", "reading_frequency": 1e-6, "id": "HD"})
    assert opendrive == sc.PseudoSensor("HD", "sensor.opendrive_map", 1e-6)
    mounts, pseudo = sc.preprocess_sensors(uniad_rig())
    assert [m.sensor_id for m in mounts][-1] == "bev" and [p.sensor_id for p in pseudo] == ["SPEED"]
    assert len(mounts) == 9


def test_track_accepts_names_and_other_enums() -> None:
    sc.validate_sensor_configuration([], "SENSORS", sc.Track.SENSORS)
    with pytest.raises(sc.SensorConfigurationInvalid, match="unknown track 'RACING'"):
        sc.validate_sensor_configuration([], SENSORS, "RACING")
