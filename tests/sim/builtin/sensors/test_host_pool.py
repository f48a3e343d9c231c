"""Read-back memory is reused only once no array of an earlier frame views it."""

from __future__ import annotations

import numpy as np

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.builtin.sensors.host_pool import HostPool
from b2d_data.sim.builtin.sensors.lighting import Lighting
from b2d_data.sim.builtin.sensors.renderer import CameraView, Renderer
from b2d_data.sim.builtin.sensors.scene_mesh import Material, TriangleMesh


def test_a_block_comes_back_only_when_no_view_of_it_is_left():
    pool = HostPool(keep=2)
    first = pool.take(100)
    owner = id(first.base)
    camera = first[10:20].view(np.uint16)  # what a frame hands out: views of the block
    del first
    second = pool.take(100)
    assert id(second.base) != owner  # the camera view still holds the first block
    del camera
    third = pool.take(80)
    assert id(third.base) == owner and third.nbytes == 80
    # Both kept blocks viewed: a third one is handed out, not kept.
    fourth = pool.take(100)
    assert id(fourth.base) not in (owner, id(second.base))
    assert len(pool._blocks) == 2


def test_a_held_frame_keeps_its_pixels_when_the_next_one_is_rendered():
    # Two captures of different scenes: the first frame's arrays, still held, must not be overwritten by the second
    # read-back (its block is in use), and a released frame's block is written again.
    renderer = Renderer(depth8=True)
    try:
        view = CameraView(Transform(Location(0.0, 0.0, 1.6), Rotation(pitch=-10.0)).matrix(), 90.0, 64, 36)
        light = Lighting.from_weather(WeatherParameters(sun_altitude_angle=60.0))
        ground = np.array([[[2.0, -30.0, 0.0], [60.0, -30.0, 0.0], [60.0, 30.0, 0.0]],
                           [[2.0, -30.0, 0.0], [60.0, 30.0, 0.0], [2.0, 30.0, 0.0]]])  # fmt: skip
        renderer.set_dynamic(TriangleMesh.empty())
        renderer.set_static(TriangleMesh.from_triangles(ground, (200, 30, 30), 7, material=Material.MATTE))
        red = renderer.render([view], light)[0]
        kept = red.rgb.copy(), red.depth.copy(), red.semantic.copy()
        renderer.set_static(TriangleMesh.from_triangles(ground, (30, 30, 200), 1, material=Material.MATTE))
        blue = renderer.render([view], light)[0]
        assert not np.array_equal(blue.semantic, kept[2])  # the second scene differs where the ground shows
        for held, copy in zip((red.rgb, red.depth, red.semantic), kept):
            np.testing.assert_array_equal(held, copy)
        del red
        again = renderer.render([view], light)[0]
        np.testing.assert_array_equal(again.semantic, blue.semantic)
    finally:
        renderer.close()
