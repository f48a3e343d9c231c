"""Facade walls facing away from a camera (or the sun) are culled: closed blocks wound alike, no label or depth moved.

Issue 24's throughput: a street view shades every building's hidden back walls before the front walls cover them;
culling them spares those fragments on a software rasteriser. It is exact only if every block is wound as
``box_triangles`` winds it, mirrored frames included.
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.semantic import SemanticTag
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.builtin.sensors.lighting import Lighting
from b2d_data.sim.builtin.sensors.map_mesh import _building
from b2d_data.sim.builtin.sensors.renderer import CameraView, Renderer
from b2d_data.sim.builtin.sensors.scene_mesh import Material, TriangleMesh, box_triangles, merge

W, H = 240, 136


def _inward(tris: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Per triangle: whether its winding's normal, (v1 − v0) × (v2 − v0), points into the block."""
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    return np.einsum("ij,ij->i", normal, tris.mean(axis=1) - centre) < 0.0


def test_box_triangles_wind_every_face_the_same_way():
    # The unit box's +x face is (1,1,1) (1,1,−1) (1,−1,−1): (0,0,−2) × (0,−2,−2) = (−4, 0, 0), into the box; every
    # face does the same, so a box seen from outside shows its near faces with one winding.
    tris = box_triangles((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    assert _inward(tris, np.zeros(3)).all()


@pytest.mark.parametrize("across", [(0.0, 1.0), (0.0, -1.0)], ids=["turning-left", "mirrored"])
def test_a_block_keeps_the_box_winding_in_a_mirrored_frame(across):
    # Along +x with across −y is a mirrored frame (determinant −1): before the fix its walls turned outward-wound.
    block = _building(np.array([10.0, 5.0]), np.array([1.0, 0.0]), np.array(across), 6.0, 4.0, 0.0, 12.0, (1, 2, 3))
    walls = block.vertices[block.materials == Material.FACADE]
    assert len(walls) == 8
    assert _inward(walls.astype(np.float64), np.array([10.0, 5.0, 6.0])).all()


def _street() -> TriangleMesh:
    """A ground plane with four blocks around the origin, two of them built in mirrored frames."""
    ground = np.array([[[-80.0, -80.0, 0.0], [80.0, -80.0, 0.0], [80.0, 80.0, 0.0]],
                       [[-80.0, -80.0, 0.0], [80.0, 80.0, 0.0], [-80.0, 80.0, 0.0]]])  # fmt: skip
    parts = [TriangleMesh.from_triangles(ground, (90, 90, 90), 1, material=Material.ROAD)]
    blocks = (((20.0, 12.0), (1.0, 0.0), (0.0, 1.0)), ((20.0, -14.0), (1.0, 0.0), (0.0, -1.0)),
              ((-18.0, 15.0), (0.6, 0.8), (0.8, -0.6)), ((-22.0, -12.0), (0.0, 1.0), (-1.0, 0.0)))  # fmt: skip
    for k, (centre, along, across) in enumerate(blocks):
        parts.append(_building(np.array(centre), np.array(along), np.array(across), 7.0, 5.0, 0.0, 10.0 + 4 * k,
                               (150, 120, 100)))  # fmt: skip
    return merge(parts)


def _views() -> list[CameraView]:
    """Four cameras at the origin, 1.6 m up, looking at the four blocks, and one high above looking down."""
    views = [CameraView(Transform(Location(0.0, 0.0, 1.6), Rotation(yaw=yaw, pitch=5.0)).matrix(), 90.0, W, H)
             for yaw in (30.0, -35.0, 140.0, -150.0)]  # fmt: skip
    views.append(CameraView(Transform(Location(0.0, 0.0, 60.0), Rotation(pitch=-90.0)).matrix(), 90.0, W, H))
    return views


def _render(cull: bool, weather: WeatherParameters) -> tuple[list, int]:
    """The views' frames and the fragments that passed the depth test, with facade culling on or off."""
    r = Renderer(cull_facades=cull)
    try:
        r.set_static(_street())
        r.set_dynamic(TriangleMesh.empty())
        with r.ctx:  # the query and the draws in one context, which the wrapped method would leave on return
            query = r.ctx.query(samples=True)
            with query:
                frames = Renderer.render.__wrapped__(r, _views(), Lighting.from_weather(weather), centre=np.zeros(3))
            return frames, query.samples
    finally:
        r.close()


@pytest.mark.parametrize("weather", [
    WeatherParameters(sun_altitude_angle=35.0, sun_azimuth_angle=60.0, cloudiness=10.0),  # sharp shadows
    WeatherParameters(sun_altitude_angle=-40.0, cloudiness=30.0),  # night: no shadow map
], ids=["sun", "night"])  # fmt: skip
def test_culling_the_hidden_walls_moves_no_label_or_depth_and_shades_fewer_fragments(weather):
    culled, culled_samples = _render(True, weather)
    drawn, drawn_samples = _render(False, weather)
    for a, b in zip(culled, drawn):
        # Float depth: a pixel on the edge a hidden wall shares with the roof may now take the roof's depth, the
        # same point to within a millimetre (the collected uint8 depth PNG cannot tell).
        np.testing.assert_allclose(a.depth, b.depth, rtol=0.0, atol=1e-3)
        np.testing.assert_array_equal(a.labels, b.labels)
        np.testing.assert_array_equal(a.semantic, b.semantic)
        # The sun's map keeps the nearest depth either way; only texels on a block's silhouette, which a back wall
        # covered by the rasteriser's edge rule, may fall to the ground behind: a handful of pixels.
        changed = np.abs(a.rgb.astype(int) - b.rgb.astype(int)).max(axis=-1) > 2
        assert changed.mean() < 2e-3
    # Every camera sees walls (a check that cannot pass on an empty view).
    assert all((frame.semantic == SemanticTag.BUILDING).mean() > 0.05 for frame in drawn)
    # Each block shows a camera at most two of its four walls; the hidden ones no longer reach the depth test.
    assert culled_samples < drawn_samples
