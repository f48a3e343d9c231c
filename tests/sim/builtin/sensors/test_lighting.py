"""Lighting of the camera images (issue 24 items 3–5): fog, sun shadows, low beams; labels and depth untouched.

Every expected value is worked out by hand from the formulas in ``lighting.py`` and ``shaders.py`` (comments give
the arithmetic); the rendered pixel must match it within the 8-bit rounding of the images.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import PRESETS, WeatherParameters
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.lighting import Lighting, fog_amount
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.renderer import CameraView, sun_view
from b2d_data.sim.builtin.sensors.scene_mesh import TriangleMesh
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, box_prop, crossroads_layout, flat_scene, snapshot_of
from b2d_data.sim.builtin.sensors.vehicle_lights import (
    NO_BLOCKER,
    SpotLights,
    beam_blockers,
    beams_in_view,
    vehicle_lights,
)

W, H = 161, 91  # odd: the centre pixel's centre lies on the optical axis (cx = 80.5, cy = 45.5)
FRONT_ONLY = RigConfig(width=160, height=90, cameras=("front",), lidar=False, radar=False)


@pytest.fixture(scope="module")
def ground():
    """A suite over flat grass (no lamps, no buildings) whose renderer the tests drive directly."""
    suite = SensorSuite.from_scene(flat_scene(), FRONT_ONLY, seed=0)
    yield suite
    suite.close()


def _centre_view(target: tuple[float, float, float], height: float = 1.6) -> CameraView:
    """A camera at (0, 0, height) whose centre pixel (80, 45) looks exactly at ``target`` on the x axis."""
    pitch = -math.degrees(math.atan2(height - target[2], target[0]))
    return CameraView(Transform(Location(0.0, 0.0, height), Rotation(pitch=pitch)).matrix(), 70.0, W, H)


def _render(suite, view: CameraView, weather: WeatherParameters, lights: SpotLights | None = None):
    """The view over the bare ground (no actors left from another test's capture)."""
    suite.renderer.set_dynamic(TriangleMesh.empty())
    return suite.renderer.render([view], Lighting.from_weather(weather), lights)[0]


# ------------------------------------------------------------------------------------------------------------- fog
def test_fog_amount_by_hand():
    # Uniform fog, 0.05 /m, starting 10 m out, a point 30 m away: 1 − exp(−0.05 · 20) = 1 − e⁻¹ = 0.63212.
    assert fog_amount(np.zeros(3), np.array([30.0, 0.0, 0.0]), 0.05, 0.0, 10.0) == pytest.approx(0.632121, abs=1e-6)
    # Thinning 0.1 /m with height, a horizontal ray at z = 2: density 0.05 · e^−0.2 = 0.0409365, optical depth over
    # 20 m 0.818731, amount 1 − e^−0.818731 = 0.559009.
    cam = np.array([0.0, 0.0, 2.0])
    assert fog_amount(cam, np.array([20.0, 0.0, 2.0]), 0.05, 0.1, 0.0) == pytest.approx(0.559009, abs=1e-6)
    # Straight up 20 m from z = 0: ∫ 0.05 e^(−0.1 z) dz = 0.5 (1 − e⁻²) = 0.432332, amount 1 − e^−0.432332 = 0.351006.
    assert fog_amount(np.zeros(3), np.array([0.0, 0.0, 20.0]), 0.05, 0.1, 0.0) == pytest.approx(0.351006, abs=1e-6)


def test_fog_parameters_follow_carla():
    # UE4 height fog: extinction ln(2)² · FogDensity / 10 per metre, FogDensity = fog_density / 100; falloff
    # ln(2) · fog_falloff / 10 per metre; fog_distance is the start distance.
    light = Lighting.from_weather(WeatherParameters(fog_density=100.0, fog_distance=25.0, fog_falloff=2.0))
    assert light.fog_density == pytest.approx(0.0480453, abs=1e-7)  # 0.693147² / 10
    assert light.fog_falloff == pytest.approx(0.1386294, abs=1e-7)  # 0.693147 · 2 / 10
    assert light.fog_start == 25.0
    # Heavy rain adds 0.012 /m of spray (weather 25: fog 100, rain 100): 0.0480453 + 0.012.
    assert Lighting.from_weather(PRESETS[25]).fog_density == pytest.approx(0.0600453, abs=1e-7)


def _ground_distances(frame, view: CameraView) -> np.ndarray:
    """Euclidean distance (m) from the camera to each pixel's surface point, from its planar depth."""
    k = view.intrinsic()
    v, u = np.mgrid[0:view.height, 0:view.width]
    ray = np.stack([(u + 0.5 - k[0, 2]) / k[0, 0], (v + 0.5 - k[1, 2]) / k[1, 1], np.ones(u.shape)], axis=-1)
    return frame.depth * np.linalg.norm(ray, axis=-1)


def test_fog_blends_each_pixel_towards_the_fog_colour_by_its_distance(ground):
    view = _centre_view((30.0, 0.0, 0.0))
    clear = WeatherParameters(sun_altitude_angle=90.0)
    foggy = clear.replace(fog_density=50.0, fog_distance=10.0)
    c0 = _render(ground, view, clear).rgb.astype(float)
    frame = _render(ground, view, foggy)
    d = _ground_distances(frame, view)
    near = (frame.semantic == 10) & (d > 12.0) & (d < 80.0)
    assert near.sum() > 2000
    # σ = 0.0480453 · 0.5 = 0.0240227 /m after the first 10 m; fog colour (0.7, 0.72, 0.75) by day, no overcast.
    # E.g. 40 m away: 1 − exp(−0.0240227 · 30) = 0.51357.
    f = 1.0 - np.exp(-0.0240227 * np.maximum(d[near] - 10.0, 0.0))
    want = c0[near] * (1.0 - f[:, None]) + np.array([0.7, 0.72, 0.75]) * 255.0 * f[:, None]
    assert np.abs(frame.rgb[near].astype(float) - want).max() <= 1.5  # two 8-bit roundings
    # A far pixel really is mostly fog: contrast falls with distance towards the fog colour, not to black.
    assert f.max() > 0.75


def test_fog_thins_with_height_as_fog_falloff_says(ground):
    view = _centre_view((30.0, 0.0, 0.0))
    clear = WeatherParameters(sun_altitude_angle=90.0)
    foggy = clear.replace(fog_density=80.0, fog_falloff=3.0)
    c0 = _render(ground, view, clear).rgb.astype(float)
    frame = _render(ground, view, foggy)
    d = _ground_distances(frame, view)
    pixel = (45, 80)  # on the optical axis: the ground point (30, 0, 0), 30.0427 m from the camera at z = 1.6
    assert d[pixel] == pytest.approx(math.hypot(30.0, 1.6), abs=0.3)
    # σ0 = 0.0480453 · 0.8 = 0.0384362, k = 0.0693147 · 3 = 0.207944; the ray drops 1.6 m over L = 30.0426 m:
    # slope −0.0532576, x = k · slope · L = −0.332711, g = (1 − e^−x) / x = (1 − e^0.332711) / −0.332711 = 1.18645;
    # density at the camera 0.0384362 · e^(−0.207944 · 1.6) = 0.0275579, optical depth 0.0275579 · 30.0426 ·
    # 1.18645 = 0.982275, amount 1 − e^−0.982275 = 0.625542 (uniform fog of σ0 would give 0.684856).
    f = 0.625542
    want = c0[pixel] * (1.0 - f) + np.array([0.7, 0.72, 0.75]) * 255.0 * f
    np.testing.assert_allclose(frame.rgb[pixel].astype(float), want, atol=1.5)
    assert fog_amount(np.array([0.0, 0.0, 1.6]), np.array([30.0, 0.0, 0.0]), 0.0384362, 0.207944, 0.0) == (
        pytest.approx(f, abs=2e-5)
    )


# --------------------------------------------------------------------------------------------------------- shadows
def _shadow_scene(suite, weather: WeatherParameters, shadows: bool):
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 0.0, role_name="hero")
    block = box_prop(2, 15.0, 0.0, (3.0, 3.0, 2.0))  # 6 × 6 × 4 m, x 12…18, y −3…3
    suite.renderer.shadows = shadows
    try:
        return suite.capture(snapshot_of([ego, block], weather), 1).cameras["front"]
    finally:
        suite.renderer.shadows = True


def _umbra(frame, suite) -> np.ndarray:
    """Ground pixels of the 4 m box's shadow well inside its edges (sun from +y at 45°: the shadow is y −3…−7).

    An overcast sky's penumbra (its shadow map is four times coarser on llvmpipe: 256 texels over 140 m, 0.55 m
    across the sun's rays and 0.77 m along them on the ground at 45°, blurred over two by the 2×2 filter) stays
    outside x 13.4…16.6, y −5.5…−4.5.
    """
    from b2d_data.format.rig import CAMERA_BY_FOLDER

    spec = CAMERA_BY_FOLDER["front"]
    w, h = FRONT_ONLY.width, FRONT_ONLY.height
    k = spec.intrinsic(w, h)
    v, u = np.mgrid[0:h, 0:w]
    d = frame.depth
    cam = np.stack([d, (u + 0.5 - k[0, 2]) / k[0, 0] * d, -(v + 0.5 - k[1, 2]) / k[1, 1] * d, np.ones_like(d)], -1)
    ego = np.array(cam @ spec.mount.matrix().T)
    x, y = ego[..., 0], ego[..., 1]
    return (frame.semantic == 10) & (x > 13.4) & (x < 16.6) & (y > -5.5) & (y < -4.5)


def test_a_fragment_in_full_shadow_gets_the_ambient_light_only(ground):
    # Clear sky (cloud 0), sun at 45° from +y: ambient (sky, facing up) 0.42 · (0.95, 1, 1.08) = (0.399, 0.42,
    # 0.4536); sun 0.78 · (1, 0.97, 0.9) · sin 45° = (0.55154, 0.53499, 0.49639); shadow strength 1 − 0.7 · 0 = 1.
    # In full shadow the light falls from ambient + sun to ambient: (0.399 / 0.95054, 0.42 / 0.95499,
    # 0.4536 / 0.94999) = (0.41976, 0.43979, 0.47748) of the sunlit value of the same pixel.
    weather = WeatherParameters(cloudiness=0.0, sun_altitude_angle=45.0, sun_azimuth_angle=90.0)
    lit = _shadow_scene(ground, weather, shadows=False)
    shaded = _shadow_scene(ground, weather, shadows=True)
    umbra = _umbra(shaded, ground)
    assert umbra.sum() > 20
    want = lit.rgb[umbra].astype(float) * np.array([0.41976, 0.43979, 0.47748])
    assert np.abs(shaded.rgb[umbra].astype(float) - want).max() <= 1.0
    # Outside the shadow nothing changes (the ground in front of the box, x 6…10).
    np.testing.assert_array_equal(lit.rgb[:, :][lit.depth < 8.0], shaded.rgb[lit.depth < 8.0])


def test_an_overcast_sky_makes_the_shadow_shallow(ground):
    # Cloud 60: sun 0.78 · (1 − 0.8 · 0.6) = 0.4056 · (1, 0.97, 0.9) · sin 45° = (0.28680, 0.27820, 0.25812);
    # ambient (0.42 + 0.2 · 0.6) · (0.95, 1, 1.08) = (0.513, 0.54, 0.5832); strength 1 − 0.7 · 0.6 = 0.58, so the
    # shadow keeps 0.42 of the sun: (0.513 + 0.12046, …) / (0.513 + 0.28680, …) = (0.79214, 0.80275, 0.82213).
    weather = WeatherParameters(cloudiness=60.0, sun_altitude_angle=45.0, sun_azimuth_angle=90.0)
    lit = _shadow_scene(ground, weather, shadows=False)
    shaded = _shadow_scene(ground, weather, shadows=True)
    umbra = _umbra(shaded, ground)
    want = lit.rgb[umbra].astype(float) * np.array([0.79214, 0.80275, 0.82213])
    assert np.abs(shaded.rgb[umbra].astype(float) - want).max() <= 1.0


def test_no_shadows_at_night_or_under_a_full_overcast():
    assert Lighting.from_weather(PRESETS[22]).shadow_strength == 0.0  # the sun is 90° below the horizon
    # Cloud 100: the sun is 0.78 · 0.2 = 0.156 and a shadow would take 0.3 of it, 0.047 < 0.06 of the light.
    assert Lighting.from_weather(PRESETS[14]).shadow_strength == 0.0
    assert Lighting.from_weather(PRESETS[0]).shadow_strength == pytest.approx(0.965)  # cloud 5: 1 − 0.7 · 0.05


def test_the_sun_view_maps_the_centre_to_the_middle_of_the_shadow_map():
    sun = Lighting.from_weather(PRESETS[7]).sun_dir
    view = sun_view(sun, np.array([0.0, 0.0, 0.0]), 70.0, 1024)
    # The centre (0, 0, 0) is a whole number of texels from the map's axes: it lands on texel centres' grid, at
    # the middle (0.5, 0.5) to within half a texel (1 / 2048), and a point towards the sun lies nearer (smaller
    # depth) than one away from it.
    s = view.texture @ np.array([0.0, 0.0, 0.0, 1.0])
    assert abs(s[0] - 0.5) <= 1 / 2048 + 1e-9 and abs(s[1] - 0.5) <= 1 / 2048 + 1e-9
    towards = view.texture @ np.array([*(10.0 * sun), 1.0])
    assert towards[2] < s[2]


# ------------------------------------------------------------------------------------------------------- low beams
def _beam(own: bool, blocked: bool = False) -> SpotLights:
    """One white beam (strength 1) from (0, 0, 1) along +x; optionally a vehicle 5 m out covering the x axis.

    ``own``: the cameras' own vehicle's beam, lit per pixel; else another vehicle's, lit per vertex.
    """
    blocker = np.array([[1.0, 0.0, 0.0, math.cos(0.2)]]) if blocked else np.array([[0.0, 0.0, 1.0, 1.0]])
    return SpotLights(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]), np.ones((1, 3)), own, blocker,
                      np.array([5.0 if blocked else NO_BLOCKER]))  # fmt: skip


#: A pixel's light at night (ambient facing up, (0.03, 0.035, 0.05), plus a beam) over its light at noon (ambient
#: (0.399, 0.42, 0.4536) plus the sun overhead 0.78 · (1, 0.97, 0.9)): the albedo cancels.
_NOON_LIGHT = np.array([1.179, 1.1766, 1.1556])
_NIGHT_AMBIENT = np.array([0.03, 0.035, 0.05])


def test_the_own_low_beam_lights_each_pixel_by_the_inverse_square_law(ground):
    # (13, 0, 0) lies inside a ground triangle (the grid's vertices are 10 m apart): only a per-pixel beam gets it.
    view = _centre_view((13.0, 0.0, 0.0))
    day = _render(ground, view, WeatherParameters(sun_altitude_angle=90.0)).rgb[45, 80].astype(float)
    night = WeatherParameters(sun_altitude_angle=-90.0)
    lit = _render(ground, view, night, _beam(own=True)).rgb[45, 80].astype(float)
    dark = _render(ground, view, night, _beam(own=True, blocked=True)).rgb[45, 80].astype(float)
    # Seen from the lamp (0, 0, 1): r = (13, 0, −1), d² = 170, 1/d = 0.0766965.
    # cone: (13 · 0.0766965 − 0.72) / 0.22 = 1.26 → 1; below the cut-off: (0.06 + 0.0766965) / 0.07 → 1;
    # reach 1 / (1 + 170 / 324) = 0.655870; facing: cos = 0.0766965, ramp 0.0766965 · 20 + 0.4 → 1, times
    # 0.45 + 0.55 · 0.0766965 = 0.492183: light 0.655870 · 0.492183 = 0.322808 (u_beams = 1 at night).
    np.testing.assert_allclose(lit, day * (_NIGHT_AMBIENT + 0.322808) / _NOON_LIGHT, atol=1.0)
    # Behind the vehicle standing in the beam (from 5 m on, within 0.2 rad of the axis) only the ambient is left.
    np.testing.assert_allclose(dark, day * _NIGHT_AMBIENT / _NOON_LIGHT, atol=1.0)


def test_another_vehicles_low_beam_lights_the_vertices(ground):
    # (10, 0, 0) is a vertex of the ground grid: there the per-vertex light is the beam's own value.
    view = _centre_view((10.0, 0.0, 0.0))
    day = _render(ground, view, WeatherParameters(sun_altitude_angle=90.0)).rgb[45, 80].astype(float)
    lit = _render(ground, view, WeatherParameters(sun_altitude_angle=-90.0), _beam(own=False)).rgb[45, 80]
    # r = (10, 0, −1), d² = 101, 1/d = 0.0995037; cone and cut-off → 1; reach 1 / (1 + 101 / 324) = 0.762353;
    # facing 0.45 + 0.55 · 0.0995037 = 0.504727: light 0.384780.
    np.testing.assert_allclose(lit.astype(float), day * (_NIGHT_AMBIENT + 0.384780) / _NOON_LIGHT, atol=1.0)


def test_every_vehicle_with_lit_lamps_gets_a_beam_and_the_ego_comes_first():
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", 0.0, 0.0, 0.0, role_name="hero")
    ahead = actor_state(2, "vehicle.tesla.model3", 12.0, 0.0, 0.0)
    far = actor_state(3, "vehicle.tesla.model3", 200.0, 0.0, 0.0)  # beyond LOW_BEAM_RANGE (90 m)
    walker = actor_state(4, "walker.pedestrian.0001", 5.0, 4.0, 0.0)
    lights = vehicle_lights([ego, ahead, far, walker], ego, night=True, timestamp=0.0)
    assert len(lights) == 2 and lights.own
    # The ego's beam: the middle of its front face 5 cm out: bounding-box x + extent x + 0.05, at 42 % of the box
    # height (centre z − extent z + 0.84 · extent z).
    bb = ego.bounding_box
    np.testing.assert_allclose(lights.position[0], [bb.location.x + bb.extent.x + 0.05, bb.location.y,
                                                    bb.location.z - 0.16 * bb.extent.z], atol=1e-9)  # fmt: skip
    # The car 12 m ahead stands in the ego's beam: its near face is 12 + its box x − its extent x from the ego
    # origin, i.e. that minus the lamp's x from the lamp, plus 0.3 m.
    near = 12.0 + ahead.bounding_box.location.x - ahead.bounding_box.extent.x - lights.position[0, 0]
    assert lights.block_distance[0] == pytest.approx(near + 0.3, abs=0.05)
    assert lights.block_distance[1] == NO_BLOCKER  # nothing stands ahead of the second car
    # By day (lamps off) there are none.
    assert len(vehicle_lights([ego, ahead], ego, night=False, timestamp=0.0)) == 0


def test_beam_blockers_by_hand():
    # A lamp at the origin looking +x; a 4 × 2 × 1.5 m car centred 10 m ahead, lengthwise: its near face is
    # 10 − 2 = 8 m out, shadow from 8.3 m; its bounding sphere (half width 1, half height 0.75: radius 1.25) covers
    # asin(1.25 / 10) = 0.125328 rad, cos 0.992157.
    car = box_prop(5, 10.0, 0.0, (2.0, 1.0, 0.75))
    blocker, distance = beam_blockers(np.array([[0.0, 0.0, 0.75]]), np.array([[1.0, 0.0, 0.0]]), [1], [car])
    assert distance[0] == pytest.approx(8.3, abs=1e-9)
    np.testing.assert_allclose(blocker[0], [1.0, 0.0, 0.0, 0.992157], atol=1e-6)
    # Behind the lamp it blocks nothing.
    _, distance = beam_blockers(np.array([[0.0, 0.0, 0.75]]), np.array([[-1.0, 0.0, 0.0]]), [1], [car])
    assert distance[0] == NO_BLOCKER


def test_a_camera_keeps_only_the_beams_that_can_reach_its_view():
    view = _centre_view((30.0, 0.0, 0.0))
    from b2d_data.sim.builtin.sensors.renderer import projection_from_intrinsic

    viewproj = projection_from_intrinsic(view.intrinsic(), W, H, 0.05, 1500.0) @ view.world_to_cv()
    # Beam 0 lights the road ahead of the camera; beam 1 stands 100 m behind it and points away: its lit sphere
    # (centre 20 m further back, radius 28 m) lies wholly behind the camera's near plane.
    lights = SpotLights(np.array([[2.0, 0.0, 0.6], [-100.0, 0.0, 0.6]]), np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]),
                        np.ones((2, 3)), True, np.tile([0.0, 0.0, 1.0, 1.0], (2, 1)), np.full(2, NO_BLOCKER))  # fmt: skip
    kept = beams_in_view(lights, viewproj)
    assert len(kept) == 1 and kept.own
    np.testing.assert_array_equal(kept.position, lights.position[:1])


def test_lamps_are_lit_by_carla_traffic_manager_rule():
    # Sun below 15°, fog denser than 20 or rain heavier than 80 (CARLA's VehicleLight constants).
    assert Lighting.from_weather(PRESETS[22]).vehicle_lights_on  # night
    assert Lighting.from_weather(PRESETS[12]).vehicle_lights_on  # day, fog 50
    assert Lighting.from_weather(PRESETS[8]).vehicle_lights_on  # day, rain 100
    assert not Lighting.from_weather(PRESETS[7]).vehicle_lights_on  # clear day, sun 45°
    # The beams show only against the dark: 1 − smoothstep(−5, 15, altitude): at 0° 1 − 0.15625 = 0.84375.
    assert Lighting.from_weather(PRESETS[10]).beams == pytest.approx(0.84375)
    assert Lighting.from_weather(PRESETS[12]).beams == 0.0


# ------------------------------------------------------------------------------------------------ labels untouched
def test_depth_and_labels_do_not_depend_on_the_lighting():
    """Shadows, fog, beams and wet roads change the colour only: depth, tags and ids are the same in every weather."""
    config = RigConfig(width=160, height=90, top_down_width=96, top_down_height=54, lidar=False, radar=False,
                       cameras=("front", "back", "front_left"))  # fmt: skip
    actors = [
        actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero"),
        actor_state(2, "vehicle.tesla.model3", -15.0, 5.25, 0.0),
        actor_state(3, "vehicle.audi.a2", -45.0, 5.25, 0.0),
        actor_state(4, "walker.pedestrian.0001", -20.0, 8.5, 90.0),
    ]
    weathers = [
        WeatherParameters(sun_altitude_angle=60.0),  # clear: hard shadows
        PRESETS[3],  # overcast, wet: soft shadows
        PRESETS[22],  # night, fog 60: beams and their glow in the fog
        PRESETS[25],  # night, dense fog, wet
        WeatherParameters(sun_altitude_angle=20.0, fog_density=70.0, fog_distance=15.0, fog_falloff=2.0),
    ]
    suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3), config, seed=1)
    try:
        frames = [suite.capture(snapshot_of(actors, w), 1).cameras for w in weathers]
    finally:
        suite.close()
    first = frames[0]
    for other in frames[1:]:
        for name in first:
            for field in ("depth", "semantic", "instance", "labels"):
                np.testing.assert_array_equal(getattr(first[name], field), getattr(other[name], field),
                                              err_msg=f"{name} {field}")  # fmt: skip
    # …while the colours do differ (the weathers were not all drawn alike).
    assert np.abs(first["front"].rgb.astype(int) - frames[2]["front"].rgb.astype(int)).mean() > 10


def _blockers_every_pair(position, direction, owners, vehicles):
    """beam_blockers' tests on every (beam, vehicle) pair, none skipped beforehand (the reference)."""
    blocker = np.tile(np.array([0.0, 0.0, 1.0, 1.0]), (len(position), 1))
    distance = np.full(len(position), NO_BLOCKER)
    for i in range(len(position)):
        best = NO_BLOCKER
        for v in vehicles:
            m, e = v.transform.matrix(), v.bounding_box.extent
            centre, forward = m[:3, :3] @ v.bounding_box.location.to_array() + m[:3, 3], m[:3, 0]
            if v.id == owners[i]:
                continue
            offset = centre - position[i]
            d = float(np.linalg.norm(offset))
            if d > 45.0 or d < 1e-3:
                continue
            towards = offset / d
            half = math.asin(min(1.0, float(np.hypot(e.y, e.z)) / d))
            if math.acos(float(np.clip(towards @ direction[i], -1.0, 1.0))) > math.acos(0.72) + half:
                continue
            c = abs(float(forward[:2] @ towards[:2]))
            near = d - (e.x * c + e.y * math.sqrt(max(0.0, 1.0 - float(forward[:2] @ towards[:2]) ** 2)))
            if near < best:
                best = near
                blocker[i] = (*towards, math.cos(half))
                distance[i] = max(0.0, near) + 0.3
    return blocker, distance


def test_beam_blockers_skip_only_pairs_that_cannot_block():
    # beam_blockers tests only the pairs a vectorised pass leaves (vehicle_lights._maybe_in_beam); the blockers
    # must be those of every pair tested, bit for bit: random traffic, and lamps far from it with one car each just
    # inside or just outside the range or the edge of the cone.
    rng = np.random.default_rng(7)
    vehicles = [
        actor_state(10 + k, "vehicle.tesla.model3", *rng.uniform(-70.0, 70.0, 2), float(rng.uniform(-180.0, 180.0)))
        for k in range(60)
    ]
    position = list(rng.uniform(-60.0, 60.0, (12, 3)) * [1.0, 1.0, 0.0] + [0.0, 0.0, 0.7])
    angles = list(rng.uniform(-math.pi, math.pi, 12))
    owners = [v.id for v in vehicles[:12]]
    bb = vehicles[0].bounding_box
    radius = math.hypot(bb.extent.y, bb.extent.z)
    edge = math.acos(0.72) + math.asin(radius / 20.0)  # the cone's edge for a car's centre 20 m from the lamp
    # (distance, angle) of the car's box centre from its lamp, which looks along +x from 1000 m further each time.
    for k, (d, a) in enumerate([(45.0 - 1e-6, 0.0), (45.0 + 1e-6, 0.0), (20.0, edge - 1e-7), (20.0, edge + 1e-7)]):
        lamp = np.array([1000.0 * (k + 1), 0.0, bb.location.z])
        x, y = lamp[0] + d * math.cos(a) - bb.location.x, d * math.sin(a) - bb.location.y
        vehicles.append(actor_state(90 + k, "vehicle.tesla.model3", x, y))
        position.append(lamp)
        angles.append(0.0)
        owners.append(1)
    direction = np.stack([np.cos(angles), np.sin(angles), np.zeros(len(angles))], axis=1)
    got = beam_blockers(np.array(position), direction, owners, vehicles)
    want = _blockers_every_pair(np.array(position), direction, owners, vehicles)
    assert got[0].tobytes() == want[0].tobytes() and got[1].tobytes() == want[1].tobytes()
    # The edge cases fall as placed (inside, outside, inside, outside), and most random beams have a blocker.
    np.testing.assert_array_equal(want[1][-4:] < NO_BLOCKER, [True, False, True, False])
    assert (want[1][:12] < NO_BLOCKER).sum() >= 4
