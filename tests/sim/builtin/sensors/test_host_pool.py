"""Read-back memory is reused only once no array of an earlier frame views it."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.builtin.sensors import renderer as renderer_module
from b2d_data.sim.builtin.sensors.host_pool import HostPool, MappedPool
from b2d_data.sim.builtin.sensors.lighting import Lighting
from b2d_data.sim.builtin.sensors.renderer import CameraView, Renderer
from b2d_data.sim.builtin.sensors.scene_mesh import Material, TriangleMesh


#: Two triangles of ground from 2 to 60 m ahead of the camera.
GROUND = np.array([[[2.0, -30.0, 0.0], [60.0, -30.0, 0.0], [60.0, 30.0, 0.0]],
                   [[2.0, -30.0, 0.0], [60.0, 30.0, 0.0], [2.0, 30.0, 0.0]]])  # fmt: skip


def _view(width: int, height: int) -> CameraView:
    return CameraView(Transform(Location(0.0, 0.0, 1.6), Rotation(pitch=-10.0)).matrix(), 90.0, width, height)


def _set_ground(renderer: Renderer, colour: tuple[int, int, int], tag: int) -> None:
    """The scene: nothing but the ground, of one colour and tag."""
    renderer.set_dynamic(TriangleMesh.empty())
    renderer.set_static(TriangleMesh.from_triangles(GROUND, colour, tag, material=Material.MATTE))


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


@pytest.mark.parametrize("pixel_buffer", [False, True])
def test_a_held_frame_keeps_its_pixels_when_the_next_one_is_rendered(pixel_buffer):
    # Two captures of different scenes: the first frame's arrays, still held, must not be overwritten by the second
    # read-back (its block is in use), and a released frame's block is written again. With a pixel buffer the blocks
    # are mapped GL buffers (MappedPool).
    renderer = Renderer(depth8=True, pixel_buffer=pixel_buffer)
    try:
        assert (renderer._mapped is not None) is pixel_buffer
        view, light = _view(64, 36), Lighting.from_weather(WeatherParameters(sun_altitude_angle=60.0))
        _set_ground(renderer, (200, 30, 30), 7)
        red = renderer.render([view], light)[0]
        if pixel_buffer:  # the arrays view mapped memory
            assert any(np.shares_memory(red.depth, block) for block in renderer._mapped._blocks)
        kept = red.rgb.copy(), red.depth.copy(), red.semantic.copy()
        _set_ground(renderer, (30, 30, 200), 1)
        blue = renderer.render([view], light)[0]
        assert not np.array_equal(blue.semantic, kept[2])  # the second scene differs where the ground shows
        for held, copy in zip((red.rgb, red.depth, red.semantic), kept):
            np.testing.assert_array_equal(held, copy)
        del red
        again = renderer.render([view], light)[0]
        np.testing.assert_array_equal(again.semantic, blue.semantic)
    finally:
        renderer.close()


def test_mapped_memory_outlives_a_closed_renderer_while_viewed():
    """A frame's arrays stay readable after the renderer closes; its context goes once they are gone."""
    renderer = Renderer(depth8=True, pixel_buffer=True)
    _set_ground(renderer, (200, 30, 30), 7)
    frame = renderer.render([_view(32, 18)], Lighting.from_weather(WeatherParameters(sun_altitude_angle=60.0)))[0]
    semantic = frame.semantic.copy()
    assert 7 in semantic
    renderer.close()
    assert any(ctx is renderer.ctx for ctx, _ in renderer_module._KEPT_OPEN)
    np.testing.assert_array_equal(frame.semantic, semantic)  # still mapped
    del frame
    renderer_module._release_kept_open()
    assert not any(ctx is renderer.ctx for ctx, _ in renderer_module._KEPT_OPEN)


def test_a_mapped_block_comes_back_only_when_no_view_of_it_is_left():
    renderer = Renderer(depth8=True, pixel_buffer=True)
    try:
        with renderer.ctx:
            pool = MappedPool(renderer.ctx, keep=2)
            buffer, first = pool.take(1000)
            camera = first[10:20]
            del first
            second = pool.take(1000)
            assert second is not None and second[0].glo != buffer.glo
            assert pool.take(1000) is None  # both kept blocks viewed: none to give
            assert not pool.release()  # and none may be unmapped
            del second, camera
            again = pool.take(800)
            assert again is not None and again[1].nbytes == 800
            del again
            assert pool.release() and pool._blocks == []
    finally:
        renderer.close()
