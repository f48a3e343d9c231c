"""GPU time of each camera draw and what it depends on, by OpenGL timer queries, in the profile run of bench_collect.

Every draw of the profiled route is timed (glFinish before and after, so each query holds that draw alone), and the
front camera of every frame is drawn again into scratch targets under variations: the same view, a trivial fragment
shader, facades before roads, only the tiles nearer than 300 / 150 / 80 m, half width and height, no static scene.
The JPEG planes and unpack dispatches and the sun's shadow map are timed too. Arguments are bench_collect's; numbers only mean something on a GPU.

    python scripts/probe_gpu_draw.py --skip-pipeline --frames 24 --warmup 3 --scenario Accident
"""

from __future__ import annotations

import atexit
import copy
import dataclasses
import runpy
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from b2d_data.sim.builtin.sensors import renderer as R
from b2d_data.sim.builtin.sensors import shaders as S
from b2d_data.sim.builtin.sensors.scene_mesh import Material

TRIVIAL_FRAGMENT = """
in vec3 v_color;
in float v_depth;
flat in uvec2 v_ids;
layout(location = 0) out vec4 f_color;
DEPTH_OUT
layout(location = 2) out uvec4 f_labels;
layout(location = 3) out uint f_tag;
void main() {
    f_color = vec4(v_color, 1.0);
    f_depth = depth_out(v_depth);
    f_labels = uvec4(v_ids.x, v_ids.y & 255u, 0u, 255u);
    f_tag = v_ids.x;
}
"""
SCRATCH_SLOT = 23
GPU_MS: defaultdict[str, list[float]] = defaultdict(list)
COUNTS: defaultdict[str, list[float]] = defaultdict(list)
_draw = R.Renderer._draw
_planes = R.Renderer._convert_planes
_unpack = R.Renderer._unpack
_shadow_map = R.Renderer._update_shadow_map
_fragment = S.scene_fragment
_trivial_programs: dict[int, tuple[dict, dict]] = {}


def timed(renderer: R.Renderer, name: str, fn: Any, *args: Any) -> Any:
    """Run ``fn`` between two glFinish calls inside a timer query; record its GPU milliseconds under ``name``."""
    renderer.ctx.finish()
    query = renderer.ctx.query(time=True)
    with query:
        out = fn(renderer, *args)
    renderer.ctx.finish()
    GPU_MS[name].append(query.elapsed / 1e6)
    return out


def variations(renderer: R.Renderer, view: R.CameraView, light: Any, uniforms: dict, lights: Any) -> None:
    """Draw the front camera again under each variation."""
    args = (light, uniforms, SCRATCH_SLOT, lights)
    timed(renderer, "same view again", _draw, view, *args)
    programs, vaos = renderer._programs, renderer._vaos
    renderer._programs, renderer._vaos = _trivial_programs.setdefault(id(renderer), ({}, {}))
    S.scene_fragment = lambda m, n, w, d8=False, packed=False, **variant: (S._header(m, n, w, **variant)
                                                                           + S._fragment(TRIVIAL_FRAGMENT, d8, packed))
    try:
        timed(renderer, "trivial fragment shader", _draw, view, *args)
    finally:
        S.scene_fragment = _fragment
        renderer._programs, renderer._vaos = programs, vaos
    order = R.DRAW_ORDER
    R.DRAW_ORDER = (Material.EMISSIVE, Material.PAINT, Material.GLASS, Material.FACADE, Material.ROAD, Material.MATTE,
                    Material.FOLIAGE)  # fmt: skip
    try:
        timed(renderer, "facades before roads", _draw, view, *args)
    finally:
        R.DRAW_ORDER = order
    culling = renderer._static_culling
    eye = view.sensor_to_world[:3, 3]
    for metres in (300.0, 150.0, 80.0):
        near = copy.copy(culling)
        keep = np.linalg.norm(culling.centres - eye, axis=1) < metres
        for field in ("first", "count", "centres", "half", "material"):
            setattr(near, field, getattr(culling, field)[keep])
        renderer._static_culling = near
        try:
            timed(renderer, f"tiles nearer than {metres:.0f} m", _draw, view, *args)
        finally:
            renderer._static_culling = culling
    half = R.CameraView(view.sensor_to_world, view.fov, view.width // 2, view.height // 2, view.labels)
    timed(renderer, "half width and height", _draw, half, light, uniforms, SCRATCH_SLOT + 1, lights)
    renderer._static_culling = R._Culling({})
    try:
        timed(renderer, "no static scene (actors + sky)", _draw, view, *args)
    finally:
        renderer._static_culling = culling
    vao = renderer._vao

    class _NoDraw:
        def render(self, *args: Any, **kwargs: Any) -> None:
            pass

    renderer._vao = lambda key, kind: _NoDraw() if kind == "sky" else vao(key, kind)  # type: ignore[method-assign]
    try:
        timed(renderer, "without the sky pass", _draw, view, *args)
    finally:
        del renderer._vao
    batches = renderer._dyn_batches
    renderer._dyn_batches = {}
    try:
        timed(renderer, "no actors (static scene + sky)", _draw, view, *args)
    finally:
        renderer._dyn_batches = batches
    if light.night > 0.0:
        day = dataclasses.replace(light, night=0.0, beams=0.0)
        timed(renderer, "night drawn with the day programs", _draw, view, day, uniforms, SCRATCH_SLOT, None)
        timed(renderer, "night without vehicle lights", _draw, view, light, uniforms, SCRATCH_SLOT, None)
    renderer.ctx.enable(R.moderngl.RASTERIZER_DISCARD)
    try:
        timed(renderer, "rasterizer discard (vertices only)", _draw, view, *args)
    finally:
        renderer.ctx.disable(R.moderngl.RASTERIZER_DISCARD)
    targets = renderer._targets_for(view.width, view.height, view.labels, SCRATCH_SLOT)
    if targets.packed is None:  # four targets: how much of the draw the three label targets cost
        full = targets.all_color
        off = (False, False, False, False)
        targets.all_color = ((True, True, True, True), off, off, off)
        try:
            timed(renderer, "colour target only", _draw, view, *args)
        finally:
            targets.all_color = full
    vp = R.projection_from_intrinsic(view.intrinsic(), view.width, view.height, renderer.near, renderer.far)
    runs = culling.runs(vp @ view.world_to_cv(), eye)
    COUNTS["static vertices per view (thousands)"].append(sum(int(r[:, 1].sum()) for r in runs.values()) / 1e3)
    COUNTS["static vertices in the scene (thousands)"].append(int(culling.count.sum()) / 1e3)


def draw(renderer: R.Renderer, view: R.CameraView, light: Any, uniforms: dict, slot: int = 0,
         lights: Any = None) -> Any:  # fmt: skip
    out = timed(renderer, f"draw {view.width}x{view.height}{' labelled' if view.labels else ''}", _draw, view, light,
                uniforms, slot, lights)  # fmt: skip
    if slot == 0 and view.labels:
        variations(renderer, view, light, uniforms, lights)
    return out


def planes(renderer: R.Renderer, targets: Any) -> None:
    timed(renderer, "JPEG planes dispatch", _planes, targets)


def unpack(renderer: R.Renderer, targets: Any) -> None:
    timed(renderer, "unpack dispatch", _unpack, targets)


def shadow_map(renderer: R.Renderer, *args: Any) -> None:
    timed(renderer, "sun's shadow map", _shadow_map, *args)


@atexit.register
def report() -> None:
    print("\nGPU ms per call (timer query between glFinish calls):")
    for name, values in sorted(GPU_MS.items()):
        print(f"  {name:<34} {np.median(values):7.3f} median of {len(values)}")
    for name, values in sorted(COUNTS.items()):
        print(f"  {name:<34} {np.median(values):9.1f} median of {len(values)}")


if __name__ == "__main__":
    R.Renderer._draw = draw  # type: ignore[method-assign]
    R.Renderer._convert_planes = planes  # type: ignore[method-assign]
    R.Renderer._unpack = unpack  # type: ignore[method-assign]
    R.Renderer._update_shadow_map = shadow_map  # type: ignore[method-assign]
    sys.argv = ["bench_collect.py", *sys.argv[1:]]
    runpy.run_path(str(Path(__file__).with_name("bench_collect.py")), run_name="__main__")
