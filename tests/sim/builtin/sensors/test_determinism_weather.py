"""Same seed, same data; weather changes the images the way it should (night darker, fog flatter, wet darker)."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, box_prop, crossroads_layout, snapshot_of

CONFIG = RigConfig(
    width=192, height=108, top_down_width=96, top_down_height=54, lidar_azimuth_steps=180,
    cameras=("front", "back", "top_down"),
)  # fmt: skip
NOON = WeatherParameters(cloudiness=30.0, sun_altitude_angle=60.0, sun_azimuth_angle=45.0)


def _actors():
    return [
        actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero", velocity=(5.0, 0.0, 0.0)),
        actor_state(2, "vehicle.tesla.model3", -15.0, 5.25, 0.0, velocity=(4.0, 0.0, 0.0)),
        actor_state(3, "walker.pedestrian.0001", -20.0, 8.5, 90.0, velocity=(0.0, 1.2, 0.0)),
        # A dark box far down the road: its contrast against the road and sky shows the fog.
        box_prop(4, 40.0, 5.0, (1.0, 2.0, 3.0)),
    ]


@pytest.fixture(scope="module")
def street():
    suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3), CONFIG, seed=11)
    yield suite
    suite.close()


def test_same_seed_same_data(street):
    snap = snapshot_of(_actors(), NOON, frame=7, timestamp=0.35)
    a = street.capture(snap, 1)
    other = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3), CONFIG, seed=11)
    try:
        b = other.capture(snap, 1)
    finally:
        other.close()
    for name in a.cameras:
        for field in ("rgb", "depth", "semantic", "instance"):
            va, vb = getattr(a.cameras[name], field), getattr(b.cameras[name], field)
            if va is None:
                assert vb is None
            else:
                np.testing.assert_array_equal(va, vb)
    np.testing.assert_array_equal(a.lidar, b.lidar)
    np.testing.assert_array_equal(a.lidar_actor_ids, b.lidar_actor_ids)
    for key in a.radar:
        np.testing.assert_array_equal(a.radar[key], b.radar[key])
    assert a.imu == b.imu and a.gnss == b.gnss
    # Another frame draws other radar rays and other sensor noise.
    c = street.capture(snapshot_of(_actors(), NOON, frame=8, timestamp=0.4), 1)
    assert not np.array_equal(a.radar["radar_front"], c.radar["radar_front"]) and a.imu != c.imu


def _luma(rgb: np.ndarray) -> np.ndarray:
    return rgb.astype(np.float64) @ np.array([0.299, 0.587, 0.114])


def test_night_is_darker_than_noon_but_not_black(street):
    noon = street.capture(snapshot_of(_actors(), NOON), 1).cameras["front"]
    night = street.capture(snapshot_of(_actors(), NOON.replace(sun_altitude_angle=-60.0)), 1).cameras["front"]
    assert _luma(night.rgb).mean() < 0.8 * _luma(noon.rgb).mean()
    # Beyond the low beam's reach (and the sky) the night is dark…
    far = noon.depth > 80.0
    assert far.sum() > 2000 and _luma(night.rgb)[far].mean() < 0.3 * _luma(noon.rgb)[far].mean()
    # …while the ego's low beam keeps the road ahead readable: at least half its noon luma (issue 24's goal).
    road = (noon.semantic == 1) & (noon.depth > 5.0) & (noon.depth < 20.0)
    assert road.sum() > 500 and _luma(night.rgb)[road].mean() > 0.5 * _luma(noon.rgb)[road].mean()


def test_fog_lowers_contrast_at_distance(street):
    spread = {}
    for fog in (0.0, 80.0):
        frame = street.capture(snapshot_of(_actors(), NOON.replace(fog_density=fog)), 1).cameras["front"]
        luma = _luma(frame.rgb)
        far = (frame.depth > 40.0) & (frame.depth < 70.0)
        near = frame.depth < 8.0
        assert far.sum() > 300 and near.sum() > 500
        spread[fog] = (luma[far].std(), luma[near].std())
    # Far away the scene fades into the fog colour; close by it keeps most of its contrast.
    assert spread[80.0][0] < 0.5 * spread[0.0][0]
    assert spread[80.0][1] > 0.6 * spread[0.0][1]


def test_wet_road_is_darker(street):
    dry = street.capture(snapshot_of(_actors(), NOON), 1).cameras["front"]
    rainy = NOON.replace(wetness=100.0, precipitation_deposits=80.0)
    wet = street.capture(snapshot_of(_actors(), rainy), 1).cameras["front"]
    road = (dry.semantic == 1) & (dry.depth < 30.0)
    assert _luma(wet.rgb)[road].mean() < 0.85 * _luma(dry.rgb)[road].mean()
    # Weather changes the colours only: labels and depth are identical.
    np.testing.assert_array_equal(dry.semantic, wet.semantic)
    np.testing.assert_array_equal(dry.depth, wet.depth)


def test_a_renderer_that_changes_weather_draws_what_a_fresh_one_draws(street):
    """Uniforms are only re-sent when they change: going back and forth between weathers must not leave stale ones."""
    foggy_night = NOON.replace(sun_altitude_angle=-60.0, fog_density=40.0, wetness=80.0)
    seen = [street.capture(snapshot_of(_actors(), w), 1).cameras for w in (NOON, foggy_night, NOON, foggy_night)]
    for weather, cameras in ((NOON, seen[2]), (foggy_night, seen[3])):
        fresh = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3), CONFIG, seed=11)
        try:
            want = fresh.capture(snapshot_of(_actors(), weather), 1).cameras
        finally:
            fresh.close()
        for name in want:
            np.testing.assert_array_equal(cameras[name].rgb, want[name].rgb, err_msg=name)
    assert np.abs(seen[0]["front"].rgb.astype(int) - seen[1]["front"].rgb.astype(int)).mean() > 5
