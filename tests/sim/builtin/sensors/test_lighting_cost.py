"""What the lighting does per vertex to stay cheap on a software rasteriser (issue 24): distant tiles, road fog, shadows.

Expected values are worked out by hand from the formulas in ``shaders.py`` (comments give the arithmetic); the
rendered pixel must match within the 8-bit rounding of the image.
"""

from __future__ import annotations

import hashlib
import itertools
import math

import moderngl
import numpy as np
import pytest

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.builtin.sensors import shaders
from b2d_data.sim.builtin.sensors.lighting import Lighting
from b2d_data.sim.builtin.sensors.renderer import CameraView, Renderer, _Culling, _Tiles, pack_vertices
from b2d_data.sim.builtin.sensors.scene_mesh import Material, TriangleMesh
from b2d_data.sim.builtin.sensors.vehicle_lights import NO_BLOCKER, SpotLights

W, H = 161, 91  # odd: the centre pixel's centre lies on the optical axis

# ---------------------------------------------------------------------------------------------- distant tile runs
VIEWPROJ = np.diag([0.001, 0.001, 0.001, 1.0])  # everything within ±1000 m is in view


def _tiles(boxes: list[tuple[tuple[float, float], tuple[float, float]]], firsts: list[int]) -> _Tiles:
    """Flat tiles (z = 0) with x and y ranges, 30 vertices each, starting at ``firsts``."""
    lo = np.array([(x[0], y[0], 0.0) for x, y in boxes])
    hi = np.array([(x[1], y[1], 0.0) for x, y in boxes])
    return _Tiles(np.array(firsts), np.full(len(firsts), 30), lo, hi)


def test_runs_split_where_every_later_tile_lies_beyond_the_distance():
    # Seen from the origin: A x 0–10 (centre 5, half diagonal √(25 + 1) = 5.099: nearest point ≤ −0.1 m),
    # B x 40–50 (45 − 5.099 = 39.9), C x 100–110 (99.9), in the buffer one after the other (vertices 0–90).
    a, b, c = ((0, 10), (-1, 1)), ((40, 50), (-1, 1)), ((100, 110), (-1, 1))
    culling = _Culling({1: _tiles([a, b, c], [0, 30, 60])})
    eye = np.zeros(3)
    runs, near = culling.split_runs(VIEWPROJ, eye, None)
    np.testing.assert_array_equal(runs[1], [[0, 90]])  # no split: one run, all of it near
    assert near[1] == 1
    runs, near = culling.split_runs(VIEWPROJ, eye, 30.0)
    np.testing.assert_array_equal(runs[1], [[0, 30], [30, 60]])  # B and C beyond 30 m: a run of their own
    assert near[1] == 1
    runs, near = culling.split_runs(VIEWPROJ, eye, 50.0)
    np.testing.assert_array_equal(runs[1], [[0, 60], [60, 30]])  # only C beyond 50 m
    assert near[1] == 1
    # A wide tile E (x 20–100, y ±40: centre 60, half diagonal √(40² + 40²) = 56.57, nearest point 3.4 m) drawn
    # after B keeps B near: the distant part starts after the last tile that is not wholly beyond 30 m.
    e = ((20, 100), (-40, 40))
    runs, near = _Culling({1: _tiles([a, b, c, e], [0, 30, 60, 90])}).split_runs(VIEWPROJ, eye, 30.0)
    # Order by centre distance: A 5, B 45, E 60, C 105; A and B merge (0 + 30 = 30), E (90) and C (60) do not.
    np.testing.assert_array_equal(runs[1], [[0, 60], [90, 30], [60, 30]])
    assert near[1] == 2
    # And the plain runs are those of the split with nothing distant.
    np.testing.assert_array_equal(_Culling({1: _tiles([a, b, c], [0, 30, 60])}).runs(VIEWPROJ, eye)[1], [[0, 90]])


def test_facades_are_never_lit_as_distant_and_the_distant_road_lights_its_vertices():
    # The header's switches, from vertex_fog and _header: a distant road moves the own beam into the per-vertex
    # loop (OWN 0) and takes pools and fog per vertex; a facade keeps all per pixel.
    road = shaders.scene_vertex(Material.ROAD, True, False, lights=1, own=True, distant=True)
    assert "#define OWN 0\n" in road and "#define VPOOL 1\n" in road and "#define VFOG 1\n" in road
    wall = shaders.scene_vertex(Material.FACADE, True, False, lights=1, own=True, distant=True)
    assert "#define OWN 1\n" in wall and "#define VPOOL 0\n" in wall and "#define VFOG 0\n" in wall
    # Near, a sidewalk (matte) in dense fog keeps its fog per pixel (pools come per vertex on all but facades); in
    # thin fog its fog is per vertex too.
    kerb = shaders.scene_vertex(Material.MATTE, True, False, lights=1, own=True)
    assert "#define VPOOL 1\n" in kerb and "#define VFOG 0\n" in kerb and "#define OWN 1\n" in kerb
    assert shaders.vertex_fog(Material.MATTE, False, thin_fog=True) and not shaders.vertex_fog(Material.ROAD, True, True)


# ------------------------------------------------------------------------------------------------ pixel checks
@pytest.fixture(scope="module")
def renderer():
    r = Renderer()
    yield r
    r.close()


def _quad(x0: float, x1: float, half_width: float) -> np.ndarray:
    """Two ground triangles over x0…x1, y ±half_width: (x0,−w) (x1,−w) (x1,w) and (x0,−w) (x1,w) (x0,w)."""
    p = np.array([[x0, -half_width, 0.0], [x1, -half_width, 0.0], [x1, half_width, 0.0], [x0, half_width, 0.0]])
    return np.stack([p[[0, 1, 2]], p[[0, 2, 3]]])


def _view(target_x: float, height: float = 1.6) -> CameraView:
    """A camera at (0, 0, height) whose centre pixel (80, 45) looks at the ground point (target_x, 0, 0)."""
    pitch = -math.degrees(math.atan2(height, target_x))
    return CameraView(Transform(Location(0.0, 0.0, height), Rotation(pitch=pitch)).matrix(), 70.0, W, H)


def _barycentric(tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Weights of p in a ground triangle (x, y only): perspective-correct interpolation is this, in the world."""
    m = np.array([[tri[0, 0], tri[1, 0], tri[2, 0]], [tri[0, 1], tri[1, 1], tri[2, 1]], [1.0, 1.0, 1.0]])
    return np.linalg.solve(m, np.array([p[0], p[1], 1.0]))


def test_road_fog_is_interpolated_between_the_triangle_corners(renderer):
    # A black road (nothing but fog shows on it) from 2 to 60 m, ±20 m wide: the centre pixel sees (30, 0, 0), in the
    # second triangle (its diagonal crosses x = 30 at y = −20 + 40 · 28 / 58 = −0.69). Fog 100: σ = 0.0480453 /m,
    # fog colour (0.7, 0.72, 0.75) by day.
    tris = _quad(2.0, 60.0, 20.0)
    renderer.set_static(TriangleMesh.from_triangles(tris, (0, 0, 0), 7, material=Material.ROAD))
    renderer.set_dynamic(TriangleMesh.empty())
    weather = WeatherParameters(sun_altitude_angle=90.0, fog_density=100.0)
    rgb = renderer.render([_view(30.0)], Lighting.from_weather(weather))[0].rgb[45, 80].astype(float)
    cam = np.array([0.0, 0.0, 1.6])
    corner_fog = 1.0 - np.exp(-0.0480453 * np.linalg.norm(tris[1] - cam, axis=1))
    # Corners (2, −20), (60, 20), (2, 20): 20.16, 63.27, 20.16 m away: fog 0.6204, 0.9522, 0.6204; weights of
    # (30, 0): 30 = 2 + 58 w1, w1 = 0.4828; 0 = −20 + 40 (w1 + w2), w2 = 0.0172; w0 = 0.5: f = 0.3102 + 0.4597 +
    # 0.0107 = 0.7805, the pixel 0.7805 · 255 · (0.7, 0.72, 0.75).
    f = float(_barycentric(tris[1], np.array([30.0, 0.0])) @ corner_fog)
    assert f == pytest.approx(0.7805, abs=1e-3)
    np.testing.assert_allclose(rgb, 255.0 * f * np.array([0.7, 0.72, 0.75]), atol=1.0)
    # Per pixel it would be 1 − exp(−0.0480453 · 30.043) = 0.7638: 2-3 levels darker, which the check above tells.
    assert abs(f - (1.0 - math.exp(-0.0480453 * math.hypot(30.0, 1.6)))) * 255.0 * 0.7 > 2.5


def _low_beam(x: np.ndarray) -> float:
    """shaders._SPOTS's spot_light on ground (normal +z) at x, lamp (0, 0, 1) looking +x, colour 1, no blocker."""
    r = x - np.array([0.0, 0.0, 1.0])
    d2 = float(r @ r)
    inv = 1.0 / math.sqrt(d2 + 1e-4)
    cone = min(max((r[0] * inv - 0.72) / 0.22, 0.0), 1.0)
    below = min(max((0.06 - r[2] * inv) / 0.07, 0.1), 1.0)
    c = -r[2] * inv
    facing = min(max(c * 20.0 + 0.4, 0.0), 1.0) * (0.45 + 0.55 * max(c, 0.0))
    return cone * below / (1.0 + d2 / 18.0**2) * facing


def test_a_distant_road_gets_the_own_beam_at_its_corners(renderer):
    # A road from 36 to 100 m (±5 m): each triangle's tile lies wholly beyond 30 m (centre 68 m away, half diagonal
    # √(32² + 5²) = 32.39: nearest point 35.6 m), so it is drawn distant: the ego's beam is lit per vertex. The centre
    # pixel sees (75, 0, 0) in the first triangle (the diagonal crosses x = 75 at y = −5 + 10 · 39 / 64 = 1.09).
    tris = _quad(36.0, 100.0, 5.0)
    mesh = TriangleMesh.from_triangles(tris, (200, 200, 200), 7, material=Material.ROAD)
    renderer.set_static(mesh)
    renderer.set_dynamic(TriangleMesh.empty())
    own = SpotLights(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]), np.ones((1, 3)), True,
                     np.array([[0.0, 0.0, 1.0, 1.0]]), np.array([NO_BLOCKER]))  # fmt: skip
    night = Lighting.from_weather(WeatherParameters(sun_altitude_angle=-90.0))
    rgb = renderer.render([_view(75.0)], night, own)[0].rgb[45, 80].astype(float)
    # Each corner's colour: its albedo (the packed, per-vertex varied grey) times the night ambient facing up,
    # (0.03, 0.035, 0.05), plus the beam there (u_beams = 1); no lamps, no fog, no sun.
    albedo = pack_vertices(mesh)["col"][:3, :3].astype(float)  # the first triangle's corners
    beam = np.array([_low_beam(v) for v in tris[0].astype(np.float64)])
    # (36, −5): r = (36, −5, −1), d² = 1322, 1/d = 0.027503; cone (0.99011 − 0.72) / 0.22 → 1, below → 1, reach
    # 1 / (1 + 1322 / 324) = 0.19684, facing min(0.55006 + 0.4, 1) · (0.45 + 0.01513) = 0.44190: 0.08698.
    # (100, ±5): d² = 10026, 1/d = 0.0099870; reach 0.031304, below (0.06 + 0.009987) / 0.07 = 0.99981, facing
    # 0.59974 · 0.45549 = 0.27318: 0.0085500.
    np.testing.assert_allclose(beam, [0.08698, 0.0085500, 0.0085500], atol=2e-5)
    weights = _barycentric(tris[0], np.array([75.0, 0.0]))
    # 75 = 36 + 64 (w1 + w2), 0 = −5 + 10 w2: w2 = 0.5, w1 = 0.10938, w0 = 0.39062.
    np.testing.assert_allclose(weights, [0.39062, 0.10938, 0.5], atol=1e-5)
    want = weights @ (albedo * (np.array([0.03, 0.035, 0.05]) + beam[:, None]))
    np.testing.assert_allclose(rgb, want, atol=1.0)
    # Per pixel the beam at (75, 0, 0) would be 1 / (1 + 5626 / 324) = 0.054448 · facing 0.66664 · 0.45733 = 0.01660,
    # against 0.39062 · 0.08698 + 0.60938 · 0.00855 = 0.03919 from the corners: 0.0226 · ~200 = 4.5 levels apart,
    # which the check above tells.
    assert float(weights @ beam) - _low_beam(np.array([75.0, 0.0, 0.0])) == pytest.approx(0.02258, abs=1e-4)


# ------------------------------------------------------------------------------------------ software variants
def _hardware_sources_digest() -> str:
    """sha256 of every hardware scene source over the variant switches (light counts 0 and 2) and the sky's."""
    digest = hashlib.sha256()
    for material in range(7):
        for flags in itertools.product((False, True), repeat=10):
            night, wet, shadow, airlight, falloff, own, own_blocked, thin_fog, distant, fog_start = flags
            for lights in (0, 2):
                variant = {"shadow": shadow, "airlight": airlight, "falloff": falloff, "lights": lights, "own": own,
                           "own_blocked": own_blocked, "thin_fog": thin_fog, "distant": distant,
                           "fog_start": fog_start}  # fmt: skip
                digest.update(shaders.scene_vertex(material, night, wet, **variant).encode())
                for depth8, packed in ((False, False), (True, False), (True, True)):
                    digest.update(shaders.scene_fragment(material, night, wet, depth8, packed, **variant).encode())
    for clouds, falloff, airlight in itertools.product((False, True), repeat=3):
        digest.update(shaders.sky_vertex(clouds, falloff, airlight).encode())
    return digest.hexdigest()


def test_hardware_shader_sources_are_those_the_h100_figures_were_measured_with():
    # Recorded from the sources before the software variants existed (commit b6e03aa): a hardware GPU compiles the
    # same text byte for byte. A deliberate change to the hardware shaders updates this digest and re-measures the
    # H100 (README, "Cost of the camera lighting").
    assert _hardware_sources_digest() == "2a52fe754d269d0ec3cd1343074dea852b98cf44002489294ba03c7995e50d8a"


def test_software_variants_move_the_own_beam_fog_and_glow_samples_to_cheaper_forms():
    night = {"lights": 2, "own": True, "airlight": True}
    # Car paint at night: the own beam per pixel on a GPU (OWN 1), in the vertex loop on a software rasteriser.
    assert "#define OWN 1\n" in shaders.scene_fragment(Material.PAINT, True, False, **night)
    assert "#define OWN 0\n" in shaders.scene_fragment(Material.PAINT, True, False, **night, software=True)
    assert "#define OWN 0\n" in shaders.scene_vertex(Material.GLASS, True, False, **night, software=True)
    # Roads, ground and facades keep it per pixel on both.
    for big in (Material.ROAD, Material.MATTE, Material.FOLIAGE, Material.FACADE):
        assert "#define OWN 1\n" in shaders.scene_fragment(big, True, False, **night, software=True)
    # Dense fog (thin_fog False) on glass and ground: per pixel on a GPU, per vertex on a software rasteriser; never
    # where the fog starts away from the camera or thins with height; facades stay per pixel in fog.
    for material in (Material.GLASS, Material.MATTE, Material.FOLIAGE):
        assert not shaders.vertex_fog(material, False, False)
        assert shaders.vertex_fog(material, False, False, software=True)
        assert not shaders.vertex_fog(material, False, False, fog_start=True, software=True)
        assert not shaders.vertex_fog(material, True, False, software=True)
    assert not shaders.vertex_fog(Material.FACADE, False, True, software=True)
    # At night a software rasteriser fogs facades per vertex as well (not where the fog starts away).
    assert shaders.vertex_fog(Material.FACADE, False, False, software=True, night=True)
    assert not shaders.vertex_fog(Material.FACADE, False, False, night=True)
    assert not shaders.vertex_fog(Material.FACADE, False, False, fog_start=True, software=True, night=True)
    assert "#define VFOG 1\n" in shaders.scene_fragment(Material.FACADE, True, False, **night, software=True)
    # The own beam's glow in the fog: 8 samples on a GPU, 4 on a software rasteriser (scene and sky).
    assert "#define AIRLIGHT_SAMPLES 8\n" in shaders.scene_vertex(Material.ROAD, True, False, **night)
    assert "#define AIRLIGHT_SAMPLES 4\n" in shaders.scene_vertex(Material.ROAD, True, False, **night, software=True)
    assert "#define AIRLIGHT_SAMPLES 4\n" in shaders.sky_vertex(False, False, True, software=True)
    assert "#define AIRLIGHT_SAMPLES 8\n" in shaders.sky_vertex(False, False, True)


@pytest.mark.parametrize(("hardware", "cloudiness", "coarse", "filtering"), [
    (False, 0.0, False, moderngl.NEAREST),  # software, sharp sun: the nearest texel (the cheap lookup)
    (False, 60.0, True, moderngl.LINEAR),  # software, partial overcast: the coarse map stays filtered (soft edges)
    (True, 0.0, False, moderngl.LINEAR),  # a GPU filters both
    (True, 60.0, True, moderngl.LINEAR),
])  # fmt: skip
def test_the_shadow_map_is_read_at_the_nearest_texel_only_for_a_sharp_sun_in_software(renderer, hardware, cloudiness,
                                                                                       coarse, filtering):  # fmt: skip
    # Penumbra 0.12 + 1.2 · overcast: 0.12 m with no cloud (the sharp map), 0.84 m at cloudiness 60 (> 0.4: the map
    # a quarter as fine, 1024 / 4 = 256 texels on llvmpipe, 2048 / 4 = 512 on a GPU). The sun still casts shadows
    # there: strength 1 − 0.7 · 0.6 = 0.58 times the sun's 0.78 · (1 − 0.8 · 0.6) = 0.41 is above 0.06.
    light = Lighting.from_weather(WeatherParameters(sun_altitude_angle=50.0, cloudiness=cloudiness))
    assert (light.shadow_softness > 0.4) == coarse and light.shadow_strength > 0.0
    renderer.set_static(TriangleMesh.from_triangles(_quad(-5.0, 5.0, 5.0), (100, 100, 100), 7, material=Material.ROAD))
    renderer.set_dynamic(TriangleMesh.empty())
    was = renderer.hardware
    with renderer.ctx:  # other renderers of the test session may have made their context current
        try:
            renderer.hardware = hardware
            renderer._update_shadow_map(light, np.zeros(3))
        finally:
            renderer.hardware = was
    texture = renderer._shadow_map
    assert texture is not None
    assert texture.size[0] == (renderer.shadow_size // 4 if coarse else renderer.shadow_size)
    assert texture.filter == (filtering, filtering)
    assert texture.compare_func == "<="


def test_without_fog_a_software_rasteriser_fogs_facades_per_vertex_and_draws_the_same_pixels(monkeypatch):
    # No fog (no fog_density, no rain: extinction exactly 0) makes every fog amount exactly 1 − exp(−0) = 0, per pixel
    # or per vertex, so the software variant's per-vertex fog on facades cannot change a pixel.
    assert "#define VFOG 1\n" in shaders.scene_fragment(Material.FACADE, False, False, software=True, fogless=True)
    assert "#define VFOG 0\n" in shaders.scene_fragment(Material.FACADE, False, False, fogless=True)  # a GPU's
    assert "#define VFOG 0\n" in shaders.scene_fragment(Material.FACADE, False, False, software=True)
    wall = np.array([[[20.0, -30.0, 0.0], [20.0, 30.0, 0.0], [20.0, 30.0, 25.0]],
                     [[20.0, -30.0, 0.0], [20.0, 30.0, 25.0], [20.0, -30.0, 25.0]]])  # fmt: skip
    mesh = TriangleMesh.from_triangles(wall, (150, 140, 130), 1, material=Material.FACADE)
    noon = Lighting.from_weather(WeatherParameters(sun_altitude_angle=50.0, sun_azimuth_angle=200.0))
    assert noon.fog_density == 0.0

    def draw() -> np.ndarray:
        r = Renderer()
        try:
            if r.hardware:
                pytest.skip("a hardware GPU draws the hardware variants")
            r.set_static(mesh)
            r.set_dynamic(TriangleMesh.empty())
            return r.render([_view(20.0, height=6.0)], noon)[0].rgb
        finally:
            r.close()

    per_vertex = draw()
    vertex_fog = shaders.vertex_fog
    # The header passes (material, falloff, thin_fog, distant, fog_start, software, fogless, night): fogless False.
    monkeypatch.setattr(shaders, "vertex_fog", lambda *args: vertex_fog(*args[:6], False, *args[7:]))
    assert "#define VFOG 0\n" in shaders.scene_fragment(Material.FACADE, False, False, software=True, fogless=True)
    per_pixel = draw()
    assert (per_vertex[..., 0] > 0).mean() > 0.5  # the wall fills most of the view
    np.testing.assert_array_equal(per_vertex, per_pixel)
