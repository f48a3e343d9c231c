"""The static scene drawn with one multi-draw per material gives the pixels of one draw call per tile run."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.sim.builtin.sensors.map_mesh import build_static_scene
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import actor_state, crossroads_layout, snapshot_of

from .conftest import SMALL
from .test_determinism_weather import NOON


@pytest.fixture(scope="module")
def street():
    suite = SensorSuite.from_scene(build_static_scene(crossroads_layout(), seed=3), SMALL, seed=11)
    yield suite
    suite.close()


def test_multi_draw_matches_per_run_draws(street):
    renderer = street.renderer
    if not renderer.multi_draw:
        pytest.skip(f"OpenGL {renderer.ctx.version_code} has no glMultiDrawElementsIndirect")
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero")
    other = actor_state(2, "vehicle.tesla.model3", -15.0, 5.25, 0.0)
    snap = snapshot_of([ego, other], NOON)
    batched: list[int] = []
    upload = renderer._indirect_commands

    def counting(runs, slot):
        batched.append(max(len(r) for r in runs.values()))
        return upload(runs, slot)

    renderer._indirect_commands = counting
    try:
        multi = street.capture(snap, 1).cameras
    finally:
        del renderer._indirect_commands
    renderer.multi_draw = False
    try:
        single = street.capture(snap, 1).cameras
    finally:
        renderer.multi_draw = True
    assert len(multi) == 7
    for name in multi:
        for field in ("rgb", "depth", "semantic", "instance"):
            a, b = getattr(multi[name], field), getattr(single[name], field)
            if a is None:
                assert b is None
            else:
                np.testing.assert_array_equal(a, b, err_msg=f"{name} {field}")
    # Every camera and the sun's shadow map (drawn once for the frame) went through the multi-draw, and some
    # material had several tile runs in one call.
    assert len(batched) == 7 + 1 and max(batched) > 1


def test_packed_labels_are_the_semantic_and_instance_planes(street):
    ego = actor_state(1, "vehicle.lincoln.mkz_2020", -30.0, 5.25, 0.0, role_name="hero")
    other = actor_state(300, "vehicle.tesla.model3", -15.0, 5.25, 0.0)  # id 300: high byte 1, low byte 44
    frame = street.capture(snapshot_of([ego, other], NOON), 1).cameras["front"]
    labels = frame.labels
    assert labels.shape == frame.semantic.shape + (4,) and frame.semantic.flags.c_contiguous
    np.testing.assert_array_equal(labels[..., 0], frame.semantic)
    np.testing.assert_array_equal(labels[..., 1].astype(np.uint16) | (labels[..., 2].astype(np.uint16) << 8),
                                  frame.instance)  # fmt: skip
    assert (labels[..., 3] == 255).all()
    car = frame.instance == 300
    assert car.sum() > 20 and (labels[car][:, 1:3] == (44, 1)).all()
    assert street.capture(snapshot_of([ego, other], NOON), 1).cameras["top_down"].labels is None


def test_shared_vertices_keeps_first_use_order():
    """Two triangles sharing an edge: six vertices, four distinct; indices rebuild the array exactly."""
    from b2d_data.sim.builtin.sensors.renderer import VERTEX_DTYPE, shared_vertices

    data = np.zeros(6, VERTEX_DTYPE)
    corners = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]  # a, b, c, b, d, c
    data["pos"] = corners
    data["ids"] = (7, 3)
    unique, indices = shared_vertices(data)
    # First uses: a → 0, b → 1, c → 2, d → 3 (worked out by hand from the corner list).
    np.testing.assert_array_equal(indices, [0, 1, 2, 1, 3, 2])
    assert indices.dtype == np.uint32
    np.testing.assert_array_equal(unique["pos"], [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)])
    np.testing.assert_array_equal(unique[indices], data)
    # A vertex that differs in any attribute (here the instance id) is not shared.
    data["ids"][3] = (7, 4)
    unique, indices = shared_vertices(data)
    np.testing.assert_array_equal(indices, [0, 1, 2, 3, 4, 2])
