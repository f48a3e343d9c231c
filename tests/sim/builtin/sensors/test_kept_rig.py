"""A closed suite's renderer and ray caster serve the process's next suite (kept_rig.py): the same frames as fresh
ones, whichever scene came before, and each static scene built once (StaticCache)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.builtin.sensors import kept_rig
from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.renderer import Renderer
from b2d_data.sim.builtin.sensors.scene_mesh import StaticCache, merge, mesh_digest
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import crossroads_layout, snapshot_of

from .test_determinism_weather import CONFIG, _actors

NIGHT = WeatherParameters(cloudiness=20.0, sun_altitude_angle=-40.0, wetness=30.0)


def _capture(scene, snapshot):
    suite = SensorSuite.from_scene(scene, CONFIG, seed=11)
    try:
        data = suite.capture(snapshot, 1)
        return suite.renderer, suite.caster, data
    finally:
        suite.close()


def _assert_same(a, b) -> None:
    for name, frame in a.cameras.items():
        for field in ("rgb", "depth", "semantic", "instance"):
            va, vb = getattr(frame, field), getattr(b.cameras[name], field)
            assert (va is None) == (vb is None), (name, field)
            if va is not None:
                np.testing.assert_array_equal(va, vb, err_msg=f"{name} {field}")
    for field in ("lidar", "lidar_tags", "lidar_actor_ids"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    assert a.radar.keys() == b.radar.keys()
    for key in a.radar:
        np.testing.assert_array_equal(a.radar[key], b.radar[key], err_msg=key)


def test_a_kept_renderer_and_caster_capture_what_fresh_ones_capture():
    """Town A (street lamps), then town B (other buildings, no lamps) on the kept pair: B's frames equal those of a
    fresh pair, so neither A's static scene nor A's lamp light-map is left behind; back on A, A's frames."""
    lamps = build_static_scene(crossroads_layout(), seed=3)
    other = dataclasses.replace(build_static_scene(crossroads_layout(), seed=8), lamps=lamps.lamps[:0])
    assert len(lamps.lamps) > 0 and mesh_digest(lamps.mesh) != mesh_digest(other.mesh)
    snapshot = snapshot_of(_actors(), NIGHT, frame=5)
    kept_rig.release()
    _, _, fresh_other = _capture(other, snapshot)
    kept_rig.release()
    renderer, caster, fresh_lamps = _capture(lamps, snapshot)
    again, again_caster, on_other = _capture(other, snapshot)
    assert again is renderer and again_caster is caster  # the kept pair served the second suite
    _assert_same(on_other, fresh_other)
    _, _, on_lamps = _capture(lamps, snapshot)
    _assert_same(on_lamps, fresh_lamps)
    # The town's light pools really show at night: the frames of the two scenes differ.
    assert not np.array_equal(on_lamps.cameras["front"].rgb, on_other.cameras["front"].rgb)
    kept_rig.release()


def test_another_config_gets_its_own_renderer_and_the_kept_one_is_closed():
    scene = build_static_scene(crossroads_layout(), seed=3)
    snapshot = snapshot_of(_actors(), NIGHT, frame=5)
    kept_rig.release()
    first, _, _ = _capture(scene, snapshot)
    suite = SensorSuite.from_scene(scene, dataclasses.replace(CONFIG, float_depth=False), seed=11)
    assert suite.renderer is not first and kept_rig.take(suite._kept_key) is None
    suite.close()  # keeping this one releases the first
    with pytest.raises(Exception):  # moderngl: the released context can no longer make objects
        first.ctx.buffer(reserve=4)
    kept_rig.release()


def test_the_renderer_uploads_each_of_its_last_two_static_scenes_once(monkeypatch):
    uploads = []
    build = Renderer._upload_static
    monkeypatch.setattr(Renderer, "_upload_static", lambda self, mesh: (uploads.append(len(mesh)), build(self, mesh))[1])
    a, b, c = (build_static_scene(crossroads_layout(), seed=s).mesh for s in (3, 8, 9))
    b = merge([a, b])  # the town and its fixtures, as a suite's first capture sets it
    assert len({len(a), len(b), len(c)}) == 3
    renderer = Renderer(depth8=True)
    try:
        for mesh in (a, b, a, b, dataclasses.replace(a)):  # a copy with the same arrays counts as the same scene
            renderer.set_static(mesh)
        assert uploads == [len(a), len(b)] and renderer.static_triangles == len(a)
        renderer.set_static(c)  # a third scene pushes out the least recent (b)
        renderer.set_static(b)
        assert uploads == [len(a), len(b), len(c), len(b)] and renderer.static_triangles == len(b)
    finally:
        renderer.close()


def test_static_cache_builds_once_per_digest_and_releases_what_it_drops():
    built, released = [], []
    cache = StaticCache(lambda mesh: (built.append(len(mesh)), object())[1], released.append, keep=2)
    meshes = [build_static_scene(crossroads_layout(), seed=s).mesh for s in (1, 2, 3)]
    assert len({mesh_digest(m) for m in meshes}) == 3
    first = cache.get(meshes[0])
    assert cache.get(meshes[0]) is first and built == [len(meshes[0])]
    cache.get(meshes[1])
    cache.get(meshes[0])  # now the most recent: the next new mesh pushes out meshes[1]
    cache.get(meshes[2])
    assert len(released) == 1 and released[0] is not first
    assert cache.get(meshes[0]) is first
    cache.clear()
    assert len(released) == 3
