"""Ray casting on the GPU: the same nearest-hit queries as :class:`~.raycast.RayCaster`, in a compute shader.

Each ray walks the tree of the static scene (``bvh.py``, built once) and then that of the dynamic scene (built per
tick) with the static hit distance as its limit, testing triangles with Möller–Trumbore in float32, both faces, as
Embree does; so every ray gets the triangle Embree reports, its distance within float rounding, and that triangle's
tag and actor id. The GPU writes distance, actor id and tag per ray; the host only uploads the rays and reads three
words per ray back, where Embree spent 15–30 CPU ms per 64 k-ray sweep.

The caster owns its own GL context (OpenGL 4.3 for compute shaders), so that it can cast on the rig's worker thread
while the renderer draws the cameras on the main thread.
"""

from __future__ import annotations

import logging
import threading

import moderngl
import numpy as np

from b2d_data.sim.builtin.sensors.bvh import Bvh, build_bvh
from b2d_data.sim.builtin.sensors.raycast import RayHits
from b2d_data.sim.builtin.sensors.scene_mesh import TriangleMesh

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
    vec3 near = min(a, b);
    vec3 far = max(a, b);
    float t0 = max(max(near.x, near.y), max(near.z, 0.0));
    float t1 = min(min(far.x, far.y), min(far.z, limit));
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


class GpuRayCaster:
    """Nearest-hit queries against static + dynamic triangle meshes, on the GPU (the interface of ``RayCaster``).

    ``ctx`` defaults to a new EGL context on the GPU the renderer would take (``create_gl_context``).
    """

    def __init__(self, static: TriangleMesh | None = None, ctx: moderngl.Context | None = None) -> None:
        if ctx is None:
            from b2d_data.sim.builtin.sensors.renderer import create_gl_context

            ctx = create_gl_context()
        self.ctx = ctx
        if ctx.version_code < 430:
            raise RuntimeError(f"GPU ray casting needs OpenGL 4.3 compute shaders; {ctx.info.get('GL_RENDERER')} "
                               f"offers OpenGL {ctx.version_code}")  # fmt: skip
        # set_dynamic runs on the capture's thread and cast on the ray worker: never both at once in one context.
        self._lock = threading.Lock()
        with self._lock, self.ctx:
            self._program = ctx.compute_shader(RAYCAST_COMPUTE)
            self._static = _Layer(ctx)
            self._dynamic = _Layer(ctx)
            self._rays = ctx.buffer(reserve=16, dynamic=True)
            self._origins = ctx.buffer(reserve=16, dynamic=True)
            self._result = ctx.buffer(reserve=16, dynamic=True)
        self._uploaded: np.ndarray | None = None  # the directions now in ``_rays`` (cast_turned's fixed rays)
        self.set_static(static if static is not None else TriangleMesh.empty())
        self.set_dynamic(TriangleMesh.empty())

    @property
    def gl_renderer(self) -> str:
        """The GL renderer string of the caster's context."""
        return self.ctx.info.get("GL_RENDERER", "")

    def set_static(self, mesh: TriangleMesh) -> None:
        """Build and upload the static scene (once per map)."""
        bvh = build_bvh(mesh.vertices)
        with self._lock, self.ctx:
            self._static.upload(mesh, bvh)

    def set_dynamic(self, mesh: TriangleMesh) -> None:
        """Build and upload the dynamic scene (once per tick); no leaf spans two actors."""
        bvh = build_bvh(mesh.vertices, groups=mesh.instance_ids)
        with self._lock, self.ctx:
            self._dynamic.upload(mesh, bvh)

    @staticmethod
    def _grow(ctx: moderngl.Context, buffer: moderngl.Buffer, nbytes: int) -> moderngl.Buffer:
        if buffer.size >= nbytes:
            return buffer
        buffer.release()
        return ctx.buffer(reserve=nbytes, dynamic=True)

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_range: float) -> RayHits:
        """Cast unit-direction rays; the nearest hit within ``max_range`` of either scene wins."""
        return self._cast(origins, directions, max_range, None)

    def cast_turned(self, sensor_to_world: np.ndarray, directions: np.ndarray, max_range: float) -> RayHits:
        """Cast sensor-frame unit ``directions`` from a sensor pose (4×4 sensor → world), turned on the GPU.

        The directions are uploaded only when they are not the array of the previous call (a LiDAR's fixed rays).
        """
        pose = np.asarray(sensor_to_world, np.float64)
        return self._cast(pose[:3, 3][None, :], directions, max_range, pose[:3, :3])

    def _cast(self, origins: np.ndarray, directions: np.ndarray, max_range: float,
              rotation: np.ndarray | None) -> RayHits:  # fmt: skip
        n = len(directions)
        o = np.asarray(origins, np.float32).reshape(-1, 3)
        if n == 0 or (self._static.leaves == 0 and self._dynamic.leaves == 0):
            return RayHits(np.zeros(n, bool), np.full(n, max_range, np.float32), np.zeros(n, np.uint8),
                           np.zeros(n, np.int32))  # fmt: skip
        per_ray = len(o) == n and n > 1 and not (o == o[0]).all()
        out = np.empty(3 * n, np.uint32)
        turn = np.eye(3, dtype=np.float32) if rotation is None else np.asarray(rotation, np.float32)
        with self._lock, self.ctx:
            if directions is not self._uploaded:
                rays = np.zeros((n, 4), np.float32)
                rays[:, :3] = np.asarray(directions, np.float32).reshape(-1, 3)
                self._rays = self._grow(self.ctx, self._rays, rays.nbytes)
                self._rays.write(rays)
                # Kept alive with the reference, so that no other array can take its place under the same identity.
                self._uploaded = directions if rotation is not None else None
            if per_ray:
                o4 = np.zeros((n, 4), np.float32)
                o4[:, :3] = o
                self._origins = self._grow(self.ctx, self._origins, o4.nbytes)
                self._origins.write(o4)
            self._result = self._grow(self.ctx, self._result, out.nbytes)
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
            self._rays.bind_to_storage_buffer(0)
            self._origins.bind_to_storage_buffer(1)
            self._static.bind(2)
            self._dynamic.bind(5)
            self._result.bind_to_storage_buffer(8)
            prog.run((n + GROUP - 1) // GROUP)
            self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
            self._result.read_into(out, size=out.nbytes)
        t = out[:n].view(np.float32)
        ids = out[n : 2 * n].view(np.int32)
        word = out[2 * n :]
        hit = word != 0
        tags = (np.maximum(word, 1) - 1).astype(np.uint8)
        return RayHits(hit, t, tags, ids)

    def close(self) -> None:
        """Release the GPU buffers and the context."""
        with self._lock:
            with self.ctx:
                self._static.release()
                self._dynamic.release()
                for buffer in (self._rays, self._origins, self._result):
                    buffer.release()
                self._program.release()
            self.ctx.release()
