"""Ray casting on the GPU: the same nearest-hit queries as :class:`~.raycast.RayCaster`, in a compute shader.

Each ray walks the tree of the static scene (``bvh.py``, built once) and then that of the dynamic scene (built per
tick) with the static hit distance as its limit, testing triangles with Möller–Trumbore in float32, both faces, as
Embree does; so every ray gets the triangle Embree reports, its distance within float rounding, and that triangle's
tag and actor id. The GPU writes distance, actor id and tag per ray; the host only uploads the rays and reads three
words per ray back, where Embree spent 15–30 CPU ms per 64 k-ray sweep.

The caster works in the renderer's GL context (OpenGL 4.3 for compute shaders) when the rig has one: a rig submits
its casts before it draws the cameras and collects them after the cameras' read-back, by which time the GPU, running
one command stream in order, has long finished them; the host never waits for the rays on their own.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import moderngl
import numpy as np

from b2d_data.sim.builtin.sensors.bvh import Bvh, build_bvh
from b2d_data.sim.builtin.sensors.raycast import RayCaster, RayHits
from b2d_data.sim.builtin.sensors.renderer import create_gl_context, is_hardware
from b2d_data.sim.builtin.sensors.scene_mesh import StaticCache, TriangleMesh

log = logging.getLogger(__name__)

#: Threads per work group.
GROUP = 64

#: The caster: one invocation per ray; the result holds n distances (bits), n actor ids, then n tags + 1 (0: no
#: hit).
RAYCAST_COMPUTE = """
#version 430
layout(local_size_x = %(group)d) in;
layout(std430, binding = 0) readonly buffer Rays { vec4 rays[]; };        // direction xyz
layout(std430, binding = 1) readonly buffer Origins { vec4 origins[]; };  // per-ray origins (u_per_ray_origin)
layout(std430, binding = 2) readonly buffer StaticNodes { vec4 s_nodes[]; };
layout(std430, binding = 3) readonly buffer StaticTris { vec4 s_tris[]; };
layout(std430, binding = 4) readonly buffer StaticLabels { uvec2 s_labels[]; };
layout(std430, binding = 5) readonly buffer DynamicNodes { vec4 d_nodes[]; };
layout(std430, binding = 6) readonly buffer DynamicTris { vec4 d_tris[]; };
layout(std430, binding = 7) readonly buffer DynamicLabels { uvec2 d_labels[]; };
layout(std430, binding = 8) writeonly buffer Result { uint result[]; };

uniform uint u_count;
uniform vec3 u_origin;
uniform mat3 u_rotation;        // sensor → world, applied to every direction
uniform bool u_per_ray_origin;
uniform float u_max_range;
uniform uint u_static_leaves;   // 0: empty layer
uniform uint u_dynamic_leaves;

float box_entry(vec4 lo, vec4 hi, vec3 o, vec3 inv, float limit) {
    // Slab test; returns the entry distance, or a value above ``limit`` when the ray misses the box within it.
    vec3 a = (lo.xyz - o) * inv;
    vec3 b = (hi.xyz - o) * inv;
    vec3 enter = min(a, b);
    vec3 leave = max(a, b);
    float t0 = max(max(enter.x, enter.y), max(enter.z, 0.0));
    float t1 = min(min(leave.x, leave.y), min(leave.z, limit));
    return t0 <= t1 ? t0 : 3.0e38;
}

%(traverse)s
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    vec3 d = u_rotation * rays[i].xyz;
    vec3 o = u_per_ray_origin ? origins[i].xyz : u_origin;
    // Axis-parallel rays: a tiny component instead of zero keeps the slab test free of 0 · inf.
    vec3 safe = mix(d, vec3(1e-30), equal(d, vec3(0.0)));
    vec3 inv = 1.0 / safe;
    float best = u_max_range;
    int found_static = -1;
    int found_dynamic = -1;
    if (u_static_leaves > 0u) traverse_s(o, d, inv, u_static_leaves, best, found_static);
    if (u_dynamic_leaves > 0u) traverse_d(o, d, inv, u_dynamic_leaves, best, found_dynamic);
    uvec2 label = uvec2(0u);
    bool hit = true;
    if (found_dynamic >= 0) label = d_labels[found_dynamic];
    else if (found_static >= 0) label = s_labels[found_static];
    else hit = false;
    result[i] = floatBitsToUint(hit ? best : u_max_range);
    result[u_count + i] = hit ? label.y : 0u;
    result[2u * u_count + i] = hit ? label.x + 1u : 0u;
}
"""

#: The tree walk of one layer (nearest box first; a box is skipped once it starts beyond the best hit so far).
_TRAVERSE = """
void traverse_LAYER(vec3 o, vec3 d, vec3 inv, uint leaves, inout float best, inout int found) {
    uint first_leaf = leaves - 1u;
    uint stack_node[32];
    float stack_t[32];
    int sp = 0;
    uint node = 0u;
    bool live = box_entry(LAYER_nodes[0], LAYER_nodes[1], o, inv, best) <= best;
    while (live) {
        if (node >= first_leaf) {
            uint row = floatBitsToUint(LAYER_nodes[2u * node].w);
            uint end = row + floatBitsToUint(LAYER_nodes[2u * node + 1u].w);
            for (; row < end; ++row) {
                vec3 v0 = LAYER_tris[3u * row].xyz;
                vec3 e1 = LAYER_tris[3u * row + 1u].xyz;
                vec3 e2 = LAYER_tris[3u * row + 2u].xyz;
                vec3 p = cross(d, e2);
                float det = dot(e1, p);
                if (det == 0.0) continue;
                float inv_det = 1.0 / det;
                vec3 s = o - v0;
                float u = dot(s, p) * inv_det;
                if (u < 0.0 || u > 1.0) continue;
                vec3 q = cross(s, e1);
                float v = dot(d, q) * inv_det;
                if (v < 0.0 || u + v > 1.0) continue;
                float t = dot(e2, q) * inv_det;
                if (t > 0.0 && t <= best) { best = t; found = int(row); }
            }
        } else {
            uint l = 2u * node + 1u;
            float tl = box_entry(LAYER_nodes[2u * l], LAYER_nodes[2u * l + 1u], o, inv, best);
            float tr = box_entry(LAYER_nodes[2u * l + 2u], LAYER_nodes[2u * l + 3u], o, inv, best);
            bool hl = tl <= best, hr = tr <= best;
            if (hl && hr) {
                bool left_first = tl <= tr;
                stack_node[sp] = left_first ? l + 1u : l;
                stack_t[sp] = left_first ? tr : tl;
                ++sp;
                node = left_first ? l : l + 1u;
                continue;
            }
            if (hl) { node = l; continue; }
            if (hr) { node = l + 1u; continue; }
        }
        live = false;
        while (sp > 0) {
            --sp;
            if (stack_t[sp] <= best) { node = stack_node[sp]; live = true; break; }
        }
    }
}

"""

RAYCAST_COMPUTE = RAYCAST_COMPUTE % {
    "group": GROUP,
    "traverse": _TRAVERSE.replace("LAYER", "s") + _TRAVERSE.replace("LAYER", "d"),
}


class _Layer:
    """One scene's tree and per-row labels on the GPU."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.leaves = 0
        self.triangles = 0
        self.buffers: list[moderngl.Buffer | None] = [None, None, None]  # nodes, triangles, labels

    def _write(self, slot: int, data: np.ndarray) -> None:
        raw = np.ascontiguousarray(data)
        buffer = self.buffers[slot]
        nbytes = max(raw.nbytes, 16)
        if buffer is None or buffer.size < nbytes:
            # Grown with room to spare: the actor meshes change size from tick to tick.
            reserve = max(nbytes, 2 * buffer.size) if buffer is not None else nbytes
            if buffer is not None:
                buffer.release()
            buffer = self.buffers[slot] = self.ctx.buffer(reserve=reserve, dynamic=True)
        if raw.nbytes:
            buffer.write(raw)

    def upload(self, mesh: TriangleMesh, bvh: Bvh) -> None:
        """Replace the layer by ``mesh`` and its tree."""
        labels = np.empty((len(bvh.order), 2), np.uint32)
        labels[:, 0] = mesh.tags[bvh.order]
        labels[:, 1] = mesh.instance_ids[bvh.order].astype(np.int32).view(np.uint32)
        self._write(0, bvh.nodes)
        self._write(1, bvh.triangles)
        self._write(2, labels)
        self.leaves = bvh.leaves
        self.triangles = len(bvh.order)

    def bind(self, first_binding: int) -> None:
        for k, buffer in enumerate(self.buffers):
            if buffer is not None:
                buffer.bind_to_storage_buffer(first_binding + k)

    def release(self) -> None:
        for buffer in self.buffers:
            if buffer is not None:
                buffer.release()
        self.buffers = [None, None, None]


class _Slot:
    """The buffers of one cast in flight: its rays, per-ray origins and result."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.rays = ctx.buffer(reserve=16, dynamic=True)
        self.origins = ctx.buffer(reserve=16, dynamic=True)
        self.result = ctx.buffer(reserve=16, dynamic=True)
        self.uploaded: np.ndarray | None = None  # the directions now in ``rays`` (a LiDAR's fixed rays)

    def release(self) -> None:
        for buffer in (self.rays, self.origins, self.result):
            buffer.release()


@dataclass
class PendingCast:
    """A cast submitted to the GPU; :meth:`GpuRayCaster.collect` reads its hits."""

    slot: _Slot | None
    count: int
    max_range: float


def _grown(ctx: moderngl.Context, buffer: moderngl.Buffer, nbytes: int) -> moderngl.Buffer:
    """``buffer``, or a larger one in its place."""
    if buffer.size >= nbytes:
        return buffer
    buffer.release()
    return ctx.buffer(reserve=nbytes, dynamic=True)


def _missed(n: int, max_range: float) -> RayHits:
    return RayHits(np.zeros(n, bool), np.full(n, max_range, np.float32), np.zeros(n, np.uint8), np.zeros(n, np.int32))


class GpuRayCaster:
    """Nearest-hit queries against static + dynamic triangle meshes, on the GPU (the interface of ``RayCaster``).

    ``ctx`` is the context to work in: the renderer's, so that casts submitted before the cameras are drawn are done
    when the cameras' read-back returns (one command stream, executed in order); by default a new EGL context on the
    GPU the renderer would take (``create_gl_context``). Every call must come from the thread that uses ``ctx``.
    :meth:`submit` starts a cast and :meth:`collect` waits for it; :meth:`cast` does both.
    """

    def __init__(self, static: TriangleMesh | None = None, ctx: moderngl.Context | None = None) -> None:
        self._owns_ctx = ctx is None
        self.ctx = create_gl_context() if ctx is None else ctx
        if self.ctx.version_code < 430:
            version = self.ctx.version_code
            if self._owns_ctx:
                self.ctx.release()
            raise RuntimeError(f"GPU ray casting needs OpenGL 4.3 compute shaders; {self.gl_renderer} offers "
                               f"OpenGL {version}")  # fmt: skip
        with self.ctx:
            self._program = self.ctx.compute_shader(RAYCAST_COMPUTE)
            self._static = _Layer(self.ctx)
            self._dynamic = _Layer(self.ctx)
        self._free: list[_Slot] = []
        self._slots: list[_Slot] = []
        self._statics: StaticCache[_Layer] = StaticCache(self._upload_static, _Layer.release)
        self.set_static(static if static is not None else TriangleMesh.empty())
        self.set_dynamic(TriangleMesh.empty())

    @property
    def gl_renderer(self) -> str:
        """The GL renderer string of the caster's context."""
        return self.ctx.info.get("GL_RENDERER", "")

    def set_static(self, mesh: TriangleMesh) -> None:
        """Build and upload the static scene (once per map: the last two stay on the GPU, ``StaticCache``)."""
        self._static = self._statics.get(mesh)

    def _upload_static(self, mesh: TriangleMesh) -> _Layer:
        bvh = build_bvh(mesh.vertices)
        with self.ctx:
            layer = _Layer(self.ctx)
            layer.upload(mesh, bvh)
        return layer

    def set_dynamic(self, mesh: TriangleMesh) -> None:
        """Build and upload the dynamic scene (once per tick); no leaf spans two actors."""
        bvh = build_bvh(mesh.vertices, groups=mesh.instance_ids)
        with self.ctx:
            self._dynamic.upload(mesh, bvh)

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_range: float) -> RayHits:
        """Cast unit-direction rays; the nearest hit within ``max_range`` of either scene wins."""
        return self.collect(self.submit(origins, directions, max_range))

    def cast_turned(self, sensor_to_world: np.ndarray, directions: np.ndarray, max_range: float) -> RayHits:
        """Cast sensor-frame unit ``directions`` from a sensor pose (4×4 sensor → world), turned on the GPU."""
        return self.collect(self.submit_turned(sensor_to_world, directions, max_range))

    def submit_turned(self, sensor_to_world: np.ndarray, directions: np.ndarray, max_range: float) -> PendingCast:
        """Start casting sensor-frame ``directions`` from a sensor pose; they are uploaded only when they are not
        the array a previous cast uploaded (a LiDAR's fixed rays go up once)."""
        pose = np.asarray(sensor_to_world, np.float64)
        return self.submit(pose[:3, 3][None, :], directions, max_range, pose[:3, :3])

    def _slot_for(self, directions: np.ndarray) -> _Slot:
        for k, slot in enumerate(self._free):
            if slot.uploaded is directions:
                return self._free.pop(k)
        if self._free:
            return self._free.pop()
        slot = _Slot(self.ctx)
        self._slots.append(slot)
        return slot

    def submit(self, origins: np.ndarray, directions: np.ndarray, max_range: float,
               rotation: np.ndarray | None = None) -> PendingCast:  # fmt: skip
        """Start casting unit ``directions`` (turned by ``rotation`` when given) from ``origins`` (one, or one per
        ray); returns without waiting for the GPU."""
        n = len(directions)
        if n == 0 or (self._static.leaves == 0 and self._dynamic.leaves == 0):
            return PendingCast(None, n, max_range)
        o = np.asarray(origins, np.float32).reshape(-1, 3)
        per_ray = len(o) == n and n > 1 and not (o == o[0]).all()
        turn = np.eye(3, dtype=np.float32) if rotation is None else np.asarray(rotation, np.float32)
        with self.ctx:
            slot = self._slot_for(directions)
            if directions is not slot.uploaded:
                rays = np.zeros((n, 4), np.float32)
                rays[:, :3] = np.asarray(directions, np.float32).reshape(-1, 3)
                slot.rays = _grown(self.ctx, slot.rays, rays.nbytes)
                slot.rays.write(rays)
                # Kept alive by the reference, so that no other array can take its identity; only fixed sensor-frame
                # rays (turned here) are worth recognising.
                slot.uploaded = directions if rotation is not None else None
            if per_ray:
                o4 = np.zeros((n, 4), np.float32)
                o4[:, :3] = o
                slot.origins = _grown(self.ctx, slot.origins, o4.nbytes)
                slot.origins.write(o4)
            slot.result = _grown(self.ctx, slot.result, 12 * n)
            prog = self._program
            prog["u_count"].value = n
            if "u_origin" in prog:
                prog["u_origin"].value = tuple(float(x) for x in o[0])
            if "u_per_ray_origin" in prog:
                prog["u_per_ray_origin"].value = per_ray
            # GLSL matrices are column-major: the transpose's rows are the columns.
            prog["u_rotation"].write(np.ascontiguousarray(turn.T).tobytes())
            prog["u_max_range"].value = float(max_range)
            prog["u_static_leaves"].value = self._static.leaves
            prog["u_dynamic_leaves"].value = self._dynamic.leaves
            slot.rays.bind_to_storage_buffer(0)
            slot.origins.bind_to_storage_buffer(1)
            self._static.bind(2)
            self._dynamic.bind(5)
            slot.result.bind_to_storage_buffer(8)
            prog.run((n + GROUP - 1) // GROUP)
            # The result is read with glGetBufferSubData: the shader's writes must be visible to it.
            self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
        return PendingCast(slot, n, max_range)

    def collect(self, pending: PendingCast) -> RayHits:
        """The hits of a submitted cast (waits for the GPU if it is not done)."""
        n, slot = pending.count, pending.slot
        if slot is None:
            return _missed(n, pending.max_range)
        out = np.empty(3 * n, np.uint32)
        with self.ctx:
            slot.result.read_into(out, size=out.nbytes)
        self._free.append(slot)
        word = out[2 * n :]
        hit = word != 0
        tags = (np.maximum(word, 1) - 1).astype(np.uint8)
        return RayHits(hit, out[:n].view(np.float32), tags, out[n : 2 * n].view(np.int32))

    def close(self) -> None:
        """Release the GPU buffers (and the context when the caster opened it)."""
        with self.ctx:
            self._statics.clear()
            self._dynamic.release()
            for slot in self._slots:
                slot.release()
            self._slots.clear()
            self._free.clear()
            self._program.release()
        if self._owns_ctx:
            self.ctx.release()


#: What ``RigConfig.gpu_rays`` may say (``B2D_GPU_RAYS`` in the environment overrides it for a collection's rig).
GPU_RAYS_MODES = ("off", "on", "gpu")


def make_ray_caster(mode: str = "gpu", renderer_ctx: moderngl.Context | None = None) -> RayCaster | GpuRayCaster:
    """The rig's ray caster: Embree, or the GPU caster with ``mode`` "on", or with "gpu" on a hardware GPU only.

    With ``renderer_ctx`` (the renderer's context) the GPU caster works in it; without, it opens its own and keeps
    it only where the mode allows. On llvmpipe the shader runs on the CPU, slower than Embree: "gpu" keeps Embree.
    """
    if mode not in GPU_RAYS_MODES:
        raise ValueError(f"gpu_rays must be one of {GPU_RAYS_MODES}, got {mode!r}")
    if mode == "off" or (mode == "gpu" and renderer_ctx is not None and not is_hardware(renderer_ctx)):
        return RayCaster()
    try:
        caster = GpuRayCaster(ctx=renderer_ctx)
    except Exception as exc:  # no EGL device or no OpenGL 4.3: moderngl raises plain Exception subclasses
        if mode == "on":
            raise
        log.warning("GPU ray casting unavailable, casting with Embree: %s", exc)
        return RayCaster()
    if mode == "gpu" and not is_hardware(caster.ctx):
        caster.close()
        return RayCaster()
    log.info("casting rays on the GPU: %s", caster.gl_renderer)
    return caster
