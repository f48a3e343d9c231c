"""Camera renderer: one moderngl EGL context, one pass per camera.

Each camera is drawn once into an RGBA8 colour target, an R32F planar-depth target (R8UI uint8 metres with
``depth8``), an RGBA8UI target holding tag and instance id as instance-PNG pixels and an R8UI tag target. On a
hardware GPU (``packed``) the pass writes one RG32UI target instead and a compute pass spreads it over those four; the
static scene is drawn by index (shared vertices shaded once); and every read-back of a frame goes into one pixel-pack
buffer that is copied out with a single wait for the GPU (``pixel_buffer``). With ``jpeg_planes`` a compute shader
turns the colour into the JPEG's Y, Cb, Cr planes, which are read back instead of the colour. The
projection is built from the camera's K exactly as ``CameraSpec.intrinsic`` gives it (principal point at the image
centre), with image row 0 at the top, so a world point projected with K and the world→camera matrix lands on the
pixel where it is drawn and every read-back is already in image order.
"""

from __future__ import annotations

import functools
import logging
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, TypeVar

import moderngl
import numpy as np

from b2d_data.format.label_pixels import label_views
from b2d_data.format.record import CameraFrame
from b2d_data.sim.builtin.sensors import shaders
from b2d_data.sim.builtin.sensors.host_pool import HostPool, MappedPool
from b2d_data.sim.builtin.sensors.lighting import FOG_BASE_HEIGHT, Lighting
from b2d_data.sim.builtin.sensors.scene_mesh import Material, StaticCache, TriangleMesh, grid_triangles
from b2d_data.sim.builtin.sensors.texture_pack import TexturePacker
from b2d_data.sim.builtin.sensors.vehicle_lights import MAX_LIGHTS, NO_BLOCKER, SpotLights, beams_in_view

log = logging.getLogger(__name__)

#: Interleaved vertex layout: position, normal, RGB + material byte, (tag, instance id).
VERTEX_DTYPE = np.dtype([("pos", "<f4", 3), ("nrm", "<f4", 3), ("col", "u1", 4), ("ids", "<u2", 2)])
# (attribute, format when the program uses it, padding when it does not)
_VERTEX_ATTRS = (
    ("in_pos", "3f", "12x"), ("in_normal", "3f", "12x"), ("in_color", "4f1", "4x"), ("in_ids", "2u2", "4x"),
)  # fmt: skip


def _vertex_layout(program: moderngl.Program) -> tuple[str, ...]:
    """Buffer format and attribute names for ``program``; attributes it does not use become padding."""
    fmt, names = [], []
    for name, used, skipped in _VERTEX_ATTRS:
        if name in program:
            fmt.append(used)
            names.append(name)
        else:
            fmt.append(skipped)
    return (" ".join(fmt), *names)

#: UE sensor axes (x fwd, y right, z up) → OpenCV camera axes (x right, y down, z fwd).
UE_TO_CV = np.array([[0, 1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0], [0, 0, 0, 1]], dtype=np.float64)

_SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "software")


def is_hardware(ctx: moderngl.Context) -> bool:
    """Whether a GL context runs on a hardware GPU (not on one of Mesa's software rasterisers)."""
    return not any(name in ctx.info.get("GL_RENDERER", "").lower() for name in _SOFTWARE_RENDERERS)

#: When the renderer hands colour over as JPEG planes: never, always, or on a hardware GPU only.
JpegPlanes = Literal["off", "on", "gpu"]


def _egl_context(index: int | None) -> moderngl.Context:
    """An EGL context of OpenGL 4.3 or later where the driver has one (for multi-draw), else of 3.3."""
    kwargs = {"backend": "egl"} if index is None else {"backend": "egl", "device_index": index}
    try:
        # Without ``require`` the NVIDIA driver hands out a 3.3 core context, which lacks glMultiDrawElementsIndirect.
        return moderngl.create_standalone_context(require=430, **kwargs)
    except Exception as exc:  # glcontext / moderngl raise plain Exception subclasses
        if "found" in str(exc):  # no such device: let the caller's device scan end
            raise
        return moderngl.create_standalone_context(**kwargs)


def create_gl_context() -> moderngl.Context:
    """An EGL context on a hardware GPU when one is present, else on Mesa's software rasteriser.

    ``B2D_EGL_DEVICE=<index>`` forces one EGL device. ``B2D_GPU_SLOT=<k>`` (set per route process by the collection's
    pools) picks the hardware device k modulo their number (at most as many as ``CUDA_VISIBLE_DEVICES`` leaves), so
    that a machine's route processes spread over all its GPUs; without it the first hardware device is taken.
    """
    # The NVIDIA driver spins a core while it waits for the GPU (glFinish, read-backs); sleeping instead frees that
    # core for the other route processes. Read when the driver loads, i.e. before the first context.
    os.environ.setdefault("__GL_YIELD", "USLEEP")
    forced = os.environ.get("B2D_EGL_DEVICE")
    if forced is not None:
        return _egl_context(int(forced))
    slot = os.environ.get("B2D_GPU_SLOT")
    fallback: moderngl.Context | None = None
    hardware: list[int] = []
    for index in range(16):
        try:
            ctx = _egl_context(index)
        except Exception as exc:  # glcontext raises plain Exception subclasses per failure kind
            if "found" in str(exc):  # "requested device index i, but found n devices"
                break
            log.debug("EGL device %d unusable: %s", index, exc)
            continue
        renderer = ctx.info.get("GL_RENDERER", "").lower()
        if not any(name in renderer for name in _SOFTWARE_RENDERERS):
            if slot is None:
                if fallback is not None:
                    fallback.release()
                log.info("rendering on EGL device %d: %s", index, ctx.info.get("GL_RENDERER"))
                return ctx
            hardware.append(index)
            ctx.release()
            continue
        if fallback is None:
            fallback = ctx
        else:
            ctx.release()
    if hardware:
        if fallback is not None:
            fallback.release()
        from b2d_data.collection.layout import count_gpus  # the layout's GPU count (CUDA_VISIBLE_DEVICES)

        visible = count_gpus()
        usable = hardware[:visible] if visible > 0 else hardware
        index = usable[int(slot or 0) % len(usable)]
        ctx = _egl_context(index)
        log.info("rendering on EGL device %d of %d (slot %s): %s", index, len(usable), slot, ctx.info.get("GL_RENDERER"))
        return ctx
    if fallback is None:
        return _egl_context(None)
    log.info("rendering on software EGL: %s", fallback.info.get("GL_RENDERER"))
    return fallback


def intrinsic_matrix(fov: float, width: int, height: int) -> np.ndarray:
    """K of a CARLA pinhole camera (horizontal FOV in degrees, square pixels, centred principal point)."""
    f = width / (2.0 * math.tan(math.radians(fov) / 2.0))
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


def projection_from_intrinsic(k: np.ndarray, width: int, height: int, near: float, far: float) -> np.ndarray:
    """GL clip matrix for OpenCV camera coordinates; NDC y = 2·v/H − 1 so GL row 0 is image row 0."""
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    return np.array(
        [
            [2.0 * fx / width, 0.0, 2.0 * cx / width - 1.0, 0.0],
            [0.0, 2.0 * fy / height, 2.0 * cy / height - 1.0, 0.0],
            [0.0, 0.0, (far + near) / (far - near), -2.0 * far * near / (far - near)],
            [0.0, 0.0, 1.0, 0.0],
        ]
    )


@dataclass(frozen=True)
class SunView:
    """The sun's orthographic view of the ground around a centre, for the shadow map.

    ``viewproj`` maps world points to GL clip coordinates, ``texture`` to shadow-map texture coordinates and depth
    (all in [0, 1]); ``texel`` is the larger side of one shadow-map texel on the ground (m).
    """

    viewproj: np.ndarray
    texture: np.ndarray
    texel: float
    half_extent: tuple[float, float]


def sun_view(sun_dir: np.ndarray, centre: np.ndarray, radius: float, size: int, height: float = 30.0,
             towards_sun: float = 300.0) -> SunView:  # fmt: skip
    """The sun's view of a disc of ``radius`` m around ``centre`` and what stands on it up to ``height`` m.

    Casters up to ``towards_sun`` m from the centre towards the sun are kept. The centre is snapped to whole
    texels so that a moving ego does not make the shadow edges crawl.
    """
    f = -np.asarray(sun_dir, np.float64)
    f /= np.linalg.norm(f)
    up = np.array([0.0, 0.0, 1.0]) if abs(f[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
    u = np.cross(f, up)
    u /= np.linalg.norm(u)
    w = np.cross(u, f)
    sin_alt = abs(float(f[2]))
    half = (radius, radius * sin_alt + height * math.sqrt(max(0.0, 1.0 - sin_alt * sin_alt)))
    c = np.asarray(centre, np.float64)
    a, b = float(c @ u), float(c @ w)
    step_a, step_b = 2.0 * half[0] / size, 2.0 * half[1] / size
    c = c + u * (round(a / step_a) * step_a - a) + w * (round(b / step_b) * step_b - b)
    far = radius + height
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = u / half[0], w / half[1], f * (2.0 / (far + towards_sun))
    view[:3, 3] = -view[:3, :3] @ c
    view[2, 3] += (towards_sun - far) / (far + towards_sun)
    bias = np.array([[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]])
    return SunView(view, bias @ view, max(step_a, step_b), half)


def _set(program: moderngl.Program, name: str, value: object) -> None:
    """Set a uniform if the program uses it (GLSL compilers drop unused ones); matrices go column-major."""
    if name not in program:
        return
    if isinstance(value, bytes):  # a uniform array of vec4, already laid out: as many as the program kept
        uniform = program[name]
        program[name].write(value[: 16 * uniform.array_length])
    elif isinstance(value, np.ndarray):
        program[name].write(np.ascontiguousarray(value.T, dtype="f4").tobytes())
    else:
        program[name].value = value


@dataclass(frozen=True)
class CameraView:
    """One camera to render: its world pose (4×4 sensor→world, CARLA axes), FOV, size and whether labels are read."""

    sensor_to_world: np.ndarray
    fov: float
    width: int
    height: int
    labels: bool = True

    def intrinsic(self) -> np.ndarray:
        """The camera's K."""
        return intrinsic_matrix(self.fov, self.width, self.height)

    def world_to_cv(self) -> np.ndarray:
        """World → OpenCV camera 4×4."""
        return UE_TO_CV @ np.linalg.inv(self.sensor_to_world)


#: Per-vertex brightness variation by material (relative amplitude), so that large surfaces are not flat colour.
_VARIATION = {int(Material.ROAD): 0.12, int(Material.FOLIAGE): 0.4, int(Material.MATTE): 0.06}


def _hash01(cells: np.ndarray) -> np.ndarray:
    """A deterministic pseudo-random value in [0, 1) per integer 2-D cell."""
    h = (cells[:, 0].astype(np.uint64) * np.uint64(73856093)) ^ (cells[:, 1].astype(np.uint64) * np.uint64(19349663))
    h ^= h >> np.uint64(13)
    h *= np.uint64(0x5BD1E995)
    h ^= h >> np.uint64(15)
    return (h & np.uint64(0xFFFF)).astype(np.float64) / 65536.0


def pack_vertices(mesh: TriangleMesh) -> np.ndarray:
    """The mesh as an interleaved vertex array (3 vertices per triangle)."""
    t = len(mesh)
    out = np.empty(3 * t, dtype=VERTEX_DTYPE)
    if t == 0:
        return out
    pos = mesh.vertices.reshape(-1, 3)
    out["pos"] = pos
    out["nrm"] = mesh.normals.reshape(-1, 3)
    col = np.empty((t, 4), np.uint8)
    col[:, :3] = mesh.colors
    col[:, 3] = mesh.materials
    vcol = np.repeat(col, 3, axis=0)
    amp = np.zeros(len(vcol))
    for material, a in _VARIATION.items():
        amp[vcol[:, 3] == material] = a
    varied = amp > 0
    if varied.any():
        # Hashed on the vertex position, so vertices shared by neighbouring triangles vary alike (smooth shading).
        p = pos[varied].astype(np.float64)
        fine = _hash01(np.floor(p[:, :2] * 0.5).astype(np.int64))
        coarse = _hash01(np.floor(p[:, :2] / 16.0).astype(np.int64) + 7919)
        factor = 1.0 + amp[varied] * (0.6 * fine + 0.4 * coarse - 0.5) * 2.0
        vcol[varied, :3] = np.clip(vcol[varied, :3] * factor[:, None], 0, 255).astype(np.uint8)
    out["col"] = vcol
    ids = np.empty((t, 2), np.uint16)
    ids[:, 0] = mesh.tags
    ids[:, 1] = (mesh.instance_ids & 0xFFFF).astype(np.uint16)
    out["ids"] = np.repeat(ids, 3, axis=0)
    return out


def shared_vertices(data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A packed vertex array as its distinct vertices (in order of first use) and a uint32 index per vertex."""
    if len(data) == 0:
        return data, np.zeros(0, np.uint32)
    records = np.ascontiguousarray(data).view(np.dtype((np.void, data.dtype.itemsize)))
    _, first, inverse = np.unique(records, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty(len(order), np.uint32)
    rank[order] = np.arange(len(order), dtype=np.uint32)
    return data[first[order]], rank[inverse.reshape(-1)]


#: Materials in drawing order: small near things first, the terrain last, so early depth tests skip hidden work.
DRAW_ORDER: tuple[int, ...] = (
    Material.EMISSIVE, Material.PAINT, Material.GLASS, Material.ROAD, Material.MATTE, Material.FACADE,
    Material.FOLIAGE,
)


#: The GL face (by its winding on screen) of a facade wall that faces away from a camera or from the sun: blocks are
#: wound as ``scene_mesh.box_triangles`` winds a box, and both projections keep that winding's sense.
FACADE_CULL = "front"

_NO_RUNS = np.zeros((0, 2), np.int64)
_UNSET = object()


@dataclass
class _Tiles:
    """Triangles of one material sorted by ground tile: vertex ranges and boxes for frustum culling."""

    first: np.ndarray  # (n,) first vertex
    count: np.ndarray  # (n,) vertex count
    lo: np.ndarray  # (n, 3) bounding box minimum
    hi: np.ndarray  # (n, 3) bounding box maximum


def _batch_mesh(mesh: TriangleMesh, tile: float | None) -> tuple[TriangleMesh, dict[int, _Tiles]]:
    """Sort triangles by material, then (when ``tile`` is given) by the ground tile of their centroid.

    Each (material, tile) batch becomes one contiguous vertex range with its bounding box.
    """
    if len(mesh) == 0:
        return mesh, {}
    mat = mesh.materials.astype(np.int64)
    if tile is None:
        tkey = np.zeros(len(mesh), np.int64)
    else:
        centroid = mesh.vertices.mean(axis=1)
        ix = np.floor(centroid[:, 0] / tile).astype(np.int64)
        iy = np.floor(centroid[:, 1] / tile).astype(np.int64)
        tkey = (ix - ix.min()) * (iy.max() - iy.min() + 1) + (iy - iy.min())
    key = mat * (int(tkey.max()) + 1) + tkey
    order = np.argsort(key, kind="stable")
    mesh = mesh.subset(order)
    key, mat = key[order], mat[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    ends = np.r_[starts[1:], len(key)]
    # Element-wise over the three vertices: a reduction over the short middle axis costs several times more (the
    # same minimum, taken in the same order).
    v = mesh.vertices
    lo = np.minimum.reduceat(np.minimum(np.minimum(v[:, 0], v[:, 1]), v[:, 2]), starts, axis=0)
    hi = np.maximum.reduceat(np.maximum(np.maximum(v[:, 0], v[:, 1]), v[:, 2]), starts, axis=0)
    batches: dict[int, _Tiles] = {}
    for m in np.unique(mat[starts]).tolist():
        sel = mat[starts] == m
        batches[m] = _Tiles(starts[sel] * 3, (ends[sel] - starts[sel]) * 3, lo[sel], hi[sel])
    return mesh, batches


class _Culling:
    """Every static tile of every material in one set of arrays, so that a view is culled in one numpy pass."""

    def __init__(self, batches: dict[int, _Tiles]) -> None:
        self.materials = list(batches)
        tiles = [batches[m] for m in self.materials]
        self.first = np.concatenate([t.first for t in tiles]) if tiles else np.zeros(0, np.int64)
        self.count = np.concatenate([t.count for t in tiles]) if tiles else np.zeros(0, np.int64)
        lo = np.concatenate([t.lo for t in tiles]) if tiles else np.zeros((0, 3))
        hi = np.concatenate([t.hi for t in tiles]) if tiles else np.zeros((0, 3))
        # Centres as the mean of the eight corners (not (lo + hi) / 2): the same rounding as the per-material culling
        # this replaced, so tiles at equal distances keep their draw order and every pixel stays as it was.
        signs = np.array([(sx, sy, sz) for sx in (0, 1) for sy in (0, 1) for sz in (0, 1)], np.float64)
        self.centres = (lo[:, None, :] + signs[None] * (hi - lo)[:, None, :]).mean(axis=1)
        self.half = (hi - lo) / 2.0
        self.material = np.repeat(np.arange(len(tiles)), [len(t.first) for t in tiles])

    def runs(self, viewproj: np.ndarray, eye: np.ndarray) -> dict[int, np.ndarray]:
        """Per material, (first, count) vertex runs of the tiles not entirely outside one clip plane, nearest first.

        Front-to-back order lets the early depth test skip the shading of hidden pixels; tiles that follow each other
        in the buffer after sorting merge into one run.
        """
        return self.split_runs(viewproj, eye, None)[0]

    def split_runs(self, viewproj: np.ndarray, eye: np.ndarray, distant_from: float | None
                   ) -> tuple[dict[int, np.ndarray], dict[int, int]]:  # fmt: skip
        """:meth:`runs`, and per material the index of its first run whose tiles (and all after it) lie entirely
        farther than ``distant_from`` m from ``eye`` (the number of runs where none does, or ``distant_from`` is
        None). The order of the tiles is that of :meth:`runs`; a run only ends at that index as well."""
        if len(self.first) == 0:
            return {}, {}
        # A box lies outside a clip plane (x < −w, x > w, …) when its corner furthest along the plane's normal does,
        # i.e. when all eight corners do: two small products for all tiles.
        rows, w = viewproj[:3], viewproj[3]
        planes = np.concatenate([w + rows, w - rows])  # (6, 4): w ± x, w ± y, w ± z ≥ 0 inside
        reach = self.centres @ planes[:, :3].T + planes[:, 3] + self.half @ np.abs(planes[:, :3]).T
        visible = np.flatnonzero((reach >= 0.0).all(axis=1))
        if len(visible) == 0:
            return {m: _NO_RUNS for m in self.materials}, {m: 0 for m in self.materials}
        distance = np.linalg.norm(self.centres[visible] - eye, axis=1)
        order = np.lexsort((distance, self.material[visible]))  # by material, then distance (stable)
        visible, distance = visible[order], distance[order]
        first, count, material = self.first[visible], self.count[visible], self.material[visible]
        far = np.zeros(len(visible), bool)
        if distant_from is not None:
            # A tile is wholly beyond the distance when its centre is farther than that plus its half diagonal; the
            # distant part of a material starts after its last tile that is not (the drawing order stays).
            clear = distance - np.linalg.norm(self.half[visible], axis=1)
            for m in np.unique(material).tolist():
                sel = np.flatnonzero(material == m)
                far[sel] = np.minimum.accumulate(clear[sel][::-1])[::-1] > distant_from
        starts = np.flatnonzero(np.r_[True, (first[1:] != first[:-1] + count[:-1]) | (material[1:] != material[:-1])
                                      | (far[1:] != far[:-1])])  # fmt: skip
        runs = np.stack([first[starts], np.add.reduceat(count, starts)], axis=1)
        bounds = np.searchsorted(material[starts], np.arange(len(self.materials) + 1))
        near = ~far[starts]
        split = {m: int(near[bounds[i] : bounds[i + 1]].sum()) for i, m in enumerate(self.materials)}
        return {m: runs[bounds[i] : bounds[i + 1]] for i, m in enumerate(self.materials)}, split


def sky_grid(columns: int = 48, rows: int = 27) -> np.ndarray:
    """Triangles (x, y pairs in NDC, float32) of a grid covering the screen, for the per-vertex sky."""
    xs = np.linspace(-1.0, 1.0, columns + 1)
    ys = np.linspace(-1.0, 1.0, rows + 1)
    gx, gy = np.meshgrid(xs, ys)
    return grid_triangles(np.stack([gx, gy], axis=-1)).astype("f4")


def noise_texture(size: int = 256, seed: int = 7) -> np.ndarray:
    """(size, size, 2) uint8 tileable smooth noise: R fine grain, G coarse blobs (FFT low-pass of white noise)."""
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(size)
    radius = np.hypot(f[:, None], f[None, :])
    out = np.empty((size, size, 2), np.uint8)
    for channel, cutoff in ((0, 0.12), (1, 0.03)):
        spectrum = np.fft.fft2(rng.standard_normal((size, size))) * np.exp(-((radius / cutoff) ** 2))
        field = np.real(np.fft.ifft2(spectrum))
        field = (field - field.min()) / max(field.max() - field.min(), 1e-9)
        out[..., channel] = np.clip(field * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return out


@dataclass
class _StaticUpload:
    """A static scene on the GPU: vertices, indices, and its tiles for culling."""

    vbo: moderngl.Buffer
    ibo: moderngl.Buffer
    culling: _Culling
    triangles: int

    def release(self) -> None:
        self.vbo.release()
        self.ibo.release()


class _Targets:
    """Colour (and, for labelled cameras, depth, tag and id) targets plus a depth buffer of one resolution."""

    def __init__(self, ctx: moderngl.Context, width: int, height: int, labels: bool, depth8: bool,
                 planes: bool = False, packed: bool = False, png_rows: bool = False) -> None:  # fmt: skip
        self.color = ctx.texture((width, height), 4, dtype="f1")
        # With ``packed`` the scene is drawn into one RG32UI target (shaders.UNPACK_COMPUTE), whose pixels a compute
        # pass spreads over the targets below; they are then only read back, through ``read_fbo``.
        self.packed = ctx.texture((width, height), 2, dtype="u4") if packed else None
        # The JPEG's planes (``planes``): full-size Y, half-size Cb and Cr, each its own one-byte target.
        self.planes: tuple[moderngl.Texture, ...] = ()
        self.luma_fbo = self.chroma_fbo = None
        if planes:
            half = (width // 2, height // 2)
            self.planes = (ctx.texture((width, height), 1, dtype="u1"), ctx.texture(half, 1, dtype="u1"),
                           ctx.texture(half, 1, dtype="u1"))  # fmt: skip
            self.luma_fbo = ctx.framebuffer([self.planes[0]])
            self.chroma_fbo = ctx.framebuffer(list(self.planes[1:]))
        # With ``png_rows`` (packed targets only) the unpack pass writes depth, labels and tags as PNG scanlines: a
        # zero filter byte, then the row; the labels as a one-byte target four bytes per pixel. Read back, they are
        # deflated where they lie (``codecs.png.png_rows``), without a filtering pass on the CPU.
        self.png_rows = png_rows and self.packed is not None and labels and depth8
        lead = 1 if self.png_rows else 0
        # Unlabelled cameras (top-down) bind only the colour target: the other outputs are dropped unwritten.
        self.depth = ctx.texture((width + lead, height), 1, dtype="u1" if depth8 else "f4") if labels else None
        # Tag and instance id in one RGBA8UI target, in the byte order of an instance PNG pixel.
        if self.png_rows:
            self.labels = ctx.texture((4 * width + 1, height), 1, dtype="u1")
        else:
            self.labels = ctx.texture((width, height), 4, dtype="u1") if labels else None
        # The tags once more, alone: the semantic PNG wants a contiguous plane, and a one-channel read of the
        # RGBA8UI target takes the NVIDIA driver's slow conversion path (9.9 ms per 1600×900 camera on an H100,
        # against 0.34 ms for a read of a one-byte target).
        self.tags = ctx.texture((width + lead, height), 1, dtype="u1") if labels else None
        self.zbuf = ctx.depth_renderbuffer((width, height))
        attachments = [self.color, self.depth, self.labels, self.tags] if labels else [self.color]
        # The scanline targets are wider than the image: each width gets its own read framebuffer.
        self.rows_fbo = self.labels_fbo = None
        if self.png_rows:
            self.rows_fbo = ctx.framebuffer([self.depth, self.tags])
            self.labels_fbo = ctx.framebuffer([self.labels])
            attachments = [self.color]
        if self.packed is not None:
            self.read_fbo = ctx.framebuffer(attachments)
            attachments = [self.packed]
            self.fbo = ctx.framebuffer(attachments, self.zbuf)
        else:
            self.fbo = self.read_fbo = ctx.framebuffer(attachments, self.zbuf)
        self.all_color = self.fbo.color_mask
        off = (False, False, False, False)
        self.no_color = (off,) * len(attachments) if len(attachments) > 1 else off

    def release(self) -> None:
        fbos = (self.fbo,) if self.read_fbo is self.fbo else (self.fbo, self.read_fbo)
        for obj in (*fbos, self.luma_fbo, self.chroma_fbo, self.rows_fbo, self.labels_fbo, *self.planes, self.color,
                    self.depth, self.labels, self.tags, self.packed, self.zbuf):  # fmt: skip
            if obj is not None:
                obj.release()


class _Readback:
    """The read-backs of one frame: straight into host arrays, or all into one pixel-pack buffer with a single wait
    for the GPU: a buffer mapped into host memory (``MappedPool``), which the arrays then view, or else a driver
    buffer copied out.

    With many route processes sharing a GPU, every synchronous glReadPixels waits for the process's context to get
    the GPU again; a frame of seven cameras made 31 such waits. Through the buffer the reads are queued behind the
    draws and the frame waits once. With a ``packer`` (mapped buffers only), the one-byte targets go into a GPU
    buffer by a compute pass instead of glReadPixels, and that buffer is copied to the mapped one.
    """

    #: Offsets of the reads in the buffer are rounded up to this many bytes (aligned float32 views).
    ALIGN = 64
    #: moderngl's read types: normalised bytes (colour), integer bytes (the R8UI / RGBA8UI targets), float.
    ARRAY_TYPE = {"f1": np.uint8, "u1": np.uint8, "f4": np.float32}

    def __init__(self, ctx: moderngl.Context, buffer: moderngl.Buffer | None, use_buffer: bool = True,
                 host: HostPool | None = None, mapped: MappedPool | None = None,
                 packer: TexturePacker | None = None) -> None:  # fmt: skip
        self.ctx = ctx
        self.use_buffer = use_buffer
        self.buffer = buffer
        self.host = host or HostPool(keep=0)
        self.mapped = mapped
        self.packer = packer
        self._reads: list[tuple[moderngl.Framebuffer, int, tuple[int, ...], str, int]] = []
        self._size = 0

    def add(self, fbo: moderngl.Framebuffer, attachment: int, shape: tuple[int, ...], dtype: str) -> None:
        """Queue the read of one attachment as an array of ``shape`` (rows, columns[, 4 components]); ``dtype`` is
        moderngl's name of the read type (``ARRAY_TYPE``)."""
        self._reads.append((fbo, attachment, shape, dtype, self._size))
        nbytes = int(np.prod(shape)) * np.dtype(self.ARRAY_TYPE[dtype]).itemsize
        self._size += -(-nbytes // self.ALIGN) * self.ALIGN

    @staticmethod
    def _read(fbo: moderngl.Framebuffer, attachment: int, shape: tuple[int, ...], dtype: str,
              into: np.ndarray | moderngl.Buffer, offset: int = 0) -> None:  # fmt: skip
        fbo.read_into(into, viewport=(0, 0, shape[1], shape[0]), components=shape[2] if len(shape) > 2 else 1,
                      attachment=attachment, dtype=dtype, write_offset=offset)  # fmt: skip

    def finish(self) -> list[np.ndarray]:
        """The arrays, in the order they were added."""
        taken = self.mapped.take(self._size) if self.use_buffer and self.mapped is not None else None
        if taken is not None:
            # Straight into mapped host memory: one wait for the GPU, then the arrays view what it wrote.
            buffer, mapped = taken
            packer = self.packer
            packable = [packer is not None and packer.packable(fbo.color_attachments[attachment], shape, dtype)
                        for fbo, attachment, shape, dtype, _ in self._reads]  # fmt: skip
            # Nothing to pack (an agent's RGB cameras): no detour through a GPU buffer.
            if packer is None or not any(packable):
                for fbo, attachment, shape, dtype, offset in self._reads:
                    self._read(fbo, attachment, shape, dtype, buffer, offset)
            else:
                # One-byte targets packed by a compute pass, the rest read by glReadPixels, all into a GPU buffer
                # that is then copied to the mapped one at once.
                packer.begin(self._size)
                for (fbo, attachment, shape, dtype, offset), pack in zip(self._reads, packable):
                    if pack:
                        packer.pack(fbo.color_attachments[attachment], offset)
                    else:
                        self._read(fbo, attachment, shape, dtype, packer.device, offset)
                packer.copy_to(buffer, self._size)
            self.ctx.finish()
            return [self._view(mapped, shape, dtype, offset) for _, _, shape, dtype, offset in self._reads]
        # One block of host memory for the frame: its arrays are views of it.
        host = self.host.take(self._size)
        if not self.use_buffer:
            out = []
            for fbo, attachment, shape, dtype, offset in self._reads:
                array = self._view(host, shape, dtype, offset)
                self._read(fbo, attachment, shape, dtype, array)
                out.append(array)
            return out
        if self.buffer is None or self.buffer.size < self._size:
            if self.buffer is not None:
                self.buffer.release()
            self.buffer = self.ctx.buffer(reserve=max(self._size, 1), dynamic=True)
        for fbo, attachment, shape, dtype, offset in self._reads:
            self._read(fbo, attachment, shape, dtype, self.buffer, offset)
        self.buffer.read_into(host, size=self._size)
        return [self._view(host, shape, dtype, offset) for _, _, shape, dtype, offset in self._reads]

    @classmethod
    def _view(cls, host: np.ndarray, shape: tuple[int, ...], dtype: str, offset: int) -> np.ndarray:
        array_type = np.dtype(cls.ARRAY_TYPE[dtype])
        return host[offset : offset + int(np.prod(shape)) * array_type.itemsize].view(array_type).reshape(shape)


#: Contexts of closed renderers whose mapped read-back memory some arrays still viewed (``Renderer.close``).
_KEPT_OPEN: list[tuple[moderngl.Context, MappedPool]] = []


def _release_kept_open() -> None:
    """Release the kept contexts whose mapped memory nothing views any more."""
    for ctx, mapped in list(_KEPT_OPEN):
        with ctx:
            free = mapped.release()
        if free:
            ctx.release()
            _KEPT_OPEN.remove((ctx, mapped))


_F = TypeVar("_F", bound=Callable)


def _current(method: _F) -> _F:
    """Run a Renderer method with its GL context current (several renderers may live in one process)."""

    @functools.wraps(method)
    def wrapper(self: Renderer, *args, **kwargs):
        with self.ctx:
            return method(self, *args, **kwargs)

    return wrapper  # type: ignore[return-value]


class Renderer:
    """Renders camera views of a static mesh (uploaded once) plus a per-frame dynamic mesh."""

    #: Texture unit of the shadow map (0: lamp light-map, 1: noise, 2: the JPEG planes' colour input).
    SHADOW_UNIT = 3
    #: Radius (m) around the ego within which the sun's shadows are drawn; they fade out at its edge.
    SHADOW_RADIUS = 70.0
    #: Indirect-command slot of the shadow pass (cameras use 0, 1, …).
    SHADOW_SLOT = -1

    def __init__(
        self, near: float = 0.05, far: float = 1500.0, tile_size: float = 48.0, depth8: bool = False,
        jpeg_planes: JpegPlanes = "off", packed: bool | None = None, pixel_buffer: bool | None = None,
        shadows: bool = True, shadow_size: int | None = None, cull_facades: bool = True, png_rows: bool = False,
        pack_reads: bool | None = None,
    ) -> None:
        self.ctx = create_gl_context()
        # uint8 depth (what the depth PNG stores, rounded on the GPU): a quarter of the float target's read-back.
        self.depth8 = depth8
        self._planes_program: moderngl.ComputeShader | None = None
        self.near = near
        self.far = far
        self.tile_size = tile_size
        self.gl_renderer = self.ctx.info.get("GL_RENDERER", "")
        self.hardware = is_hardware(self.ctx)
        if jpeg_planes not in ("off", "on", "gpu"):
            raise ValueError(f"jpeg_planes must be 'off', 'on' or 'gpu', got {jpeg_planes!r}")
        # Colour handed over as the JPEG's 4:2:0 planes (``CameraFrame.jpeg_planes``, no RGB) where the size is even.
        # "gpu": only on a hardware GPU; llvmpipe spends more CPU on the conversion pass than libjpeg does.
        self.jpeg_planes = jpeg_planes == "on" or (jpeg_planes == "gpu" and self.hardware)
        if self.jpeg_planes and self.ctx.version_code < 430:
            # The planes are computed by a compute shader (OpenGL 4.3).
            if jpeg_planes == "on":
                raise RuntimeError(f"jpeg_planes='on' needs OpenGL 4.3 compute shaders; {self.gl_renderer} "
                                   f"offers OpenGL {self.ctx.version_code}")  # fmt: skip
            self.jpeg_planes = False
        # One packed target per camera (``shaders.UNPACK_COMPUTE``): by default on a hardware GPU with compute
        # shaders, where the four colour writes per fragment cost a third of the draw; uint8 depth only.
        if packed is None:
            packed = self.hardware and self.depth8 and self.ctx.version_code >= 430
        elif packed and (not self.depth8 or self.ctx.version_code < 430):
            raise RuntimeError(f"packed targets need depth8 and OpenGL 4.3 compute shaders; {self.gl_renderer} "
                               f"offers OpenGL {self.ctx.version_code}, depth8={self.depth8}")  # fmt: skip
        self.packed = packed
        # Depth, labels and tags read back as PNG scanlines (``_Targets``; packed targets only): for a writer that
        # encodes them as PNG and nothing else. The arrays handed out are then views whose rows lie one byte apart.
        self.png_rows = png_rows and packed
        # Read-backs through one pixel-pack buffer per frame (``_Readback``): by default on a hardware GPU; on
        # llvmpipe the buffer is one more copy in host memory.
        self.pixel_buffer = self.hardware if pixel_buffer is None else pixel_buffer
        self._pack_buffer: moderngl.Buffer | None = None
        self._host = HostPool()
        # With a pixel buffer, read-backs land in buffers mapped into host memory where the driver can (GL 4.4).
        self._mapped = MappedPool(self.ctx) if self.pixel_buffer and MappedPool.supported(self.ctx) else None
        # One-byte targets read back by a compute pass and a buffer copy (texture_pack.py): by default on a hardware
        # GPU with mapped buffers, where glReadPixels converts on the few graphics units; on llvmpipe the pass would
        # run on the CPU, slower than glReadPixels' copy.
        can_pack = self._mapped is not None and self.ctx.version_code >= 430
        if pack_reads and not can_pack:
            raise RuntimeError(f"pack_reads needs mapped read-back buffers and OpenGL 4.3 compute shaders; "
                               f"{self.gl_renderer} offers OpenGL {self.ctx.version_code}, "
                               f"pixel_buffer={self.pixel_buffer}")  # fmt: skip
        self.pack_reads = can_pack and (self.hardware if pack_reads is None else pack_reads)
        self._packer = TexturePacker(self.ctx) if self.pack_reads else None
        self._unpack_programs: dict[tuple[bool, bool], moderngl.ComputeShader] = {}
        self._programs: dict[tuple, moderngl.Program] = {}
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        self._sky_vbo = self.ctx.buffer(sky_grid().tobytes())
        # The static scene's tiles as the draws cull them (the uploaded scene's; probe_gpu_draw.py swaps them).
        self._static_culling = _Culling({})
        # Uniform values each program was last given: weather and lighting stay the same for every view of a frame.
        self._uniform_values: dict[int, dict[str, object]] = {}
        self._dyn_vbo = self.ctx.buffer(reserve=1 << 20, dynamic=True)
        self._dyn_batches: dict[int, _Tiles] = {}
        self._targets: dict[tuple[int, int, bool, int], _Targets] = {}
        noise = noise_texture()
        self._noise = self.ctx.texture((noise.shape[1], noise.shape[0]), 2, noise.tobytes(), dtype="f1")
        self._noise.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._lightmap = self.ctx.texture((1, 1), 1, np.zeros(1, np.uint8).tobytes(), dtype="f1")
        self._lightmap_rect = (0.0, 0.0, 1.0, 1.0)
        self._static: _StaticUpload | None = None  # the static scene drawn, one of those StaticCache keeps
        self._statics: StaticCache[_StaticUpload] = StaticCache(self._upload_static, _StaticUpload.release)
        # The sun's shadow map, drawn once per frame (the first render after the scene, actors or sun changed) and
        # read by every camera of it. llvmpipe draws a quarter of the texels: its shadow pass costs CPU.
        self.shadows = shadows
        # Facades are closed blocks (Material.FACADE): the walls facing away from a view lie behind those facing it,
        # so skipping them changes no label or depth and spares about a sixth of a street view's fragments.
        self.cull_facades = cull_facades
        self.shadow_size = shadow_size or (2048 if self.hardware else 1024)
        self._shadow_maps: dict[tuple[int, bool], tuple[moderngl.Texture, moderngl.Framebuffer]] = {}
        self._shadow_map: moderngl.Texture | None = None
        self._sun_view: SunView | None = None
        self._shadow_key: tuple | None = None
        self._scene_version = 0  # counts static and dynamic uploads: a new one makes the shadow map stale
        # glMultiDrawElementsIndirect is core in OpenGL 4.3 (llvmpipe and the NVIDIA driver both have it).
        self.multi_draw = self.ctx.version_code >= 430
        self._indirect: dict[int, moderngl.Buffer] = {}

    # ------------------------------------------------------------------------------------------ programs
    def _program(self, key: tuple) -> moderngl.Program:
        """A scene program ("scene", material, night, wet, shadow, airlight, falloff, light count, own beam, own
        beam blocked, thin fog, distant, fog starts away, no fog), the sky
        program ("sky", clouds, falloff, airlight) or the shadow-map program ("shadow",), compiled once."""
        prog = self._programs.get(key)
        if prog is None:
            if key[0] == "sky":
                prog = self.ctx.program(vertex_shader=shaders.sky_vertex(*key[1:], software=not self.hardware),
                                        fragment_shader=shaders.sky_fragment(self.depth8, self.packed))  # fmt: skip
            elif key[0] == "shadow":
                prog = self.ctx.program(vertex_shader=shaders.SHADOW_VERTEX, fragment_shader=shaders.SHADOW_FRAGMENT)
            else:
                _, material, night, wet, shadow, airlight, falloff, lights, own, own_blocked, thin_fog, distant, \
                    fog_start, fogless = key
                variant = {"shadow": shadow, "airlight": airlight, "falloff": falloff, "lights": lights, "own": own,
                           "own_blocked": own_blocked, "thin_fog": thin_fog, "distant": distant,
                           "fog_start": fog_start, "software": not self.hardware, "fogless": fogless}  # fmt: skip
                prog = self.ctx.program(
                    vertex_shader=shaders.scene_vertex(material, night, wet, **variant),
                    fragment_shader=shaders.scene_fragment(material, night, wet, self.depth8, self.packed, **variant),
                )
            _set(prog, "u_noise", 1)
            _set(prog, "u_lightmap", 0)
            _set(prog, "u_shadow_map", self.SHADOW_UNIT)
            self._programs[key] = prog
        return prog

    def _vao(self, program_key: tuple, which: str) -> moderngl.VertexArray:
        """The vertex array binding ``which`` buffer (static / dynamic / sky) to a program."""
        key = (program_key, which)
        vao = self._vaos.get(key)
        if vao is None:
            prog = self._program(program_key)
            if which == "sky":
                vao = self.ctx.vertex_array(prog, [(self._sky_vbo, "2f", "in_xy")])
            elif which == "static":
                assert self._static is not None, "set_static() first"
                vao = self.ctx.vertex_array(prog, [(self._static.vbo, *_vertex_layout(prog))],
                                            index_buffer=self._static.ibo, index_element_size=4)  # fmt: skip
            else:
                vao = self.ctx.vertex_array(prog, [(self._dyn_vbo, *_vertex_layout(prog))])
            self._vaos[key] = vao
        return vao

    def _drop_vaos(self, which: str) -> None:
        for key in [k for k in self._vaos if k[1] == which]:
            self._vaos.pop(key).release()

    # ------------------------------------------------------------------------------------------ scene
    @_current
    def set_static(self, mesh: TriangleMesh) -> None:
        """Upload the static scene, batched by material and ground tile (for culling); the last two scenes stay on
        the GPU (``StaticCache``), and setting one of them again uploads nothing."""
        upload = self._statics.get(mesh)
        if upload is self._static:
            return
        self._static = upload
        self._static_culling = upload.culling
        self._drop_vaos("static")
        self._scene_version += 1

    @property
    def static_triangles(self) -> int:
        """Triangles of the static scene drawn (0 before any)."""
        return self._static.triangles if self._static is not None else 0

    def _upload_static(self, mesh: TriangleMesh) -> _StaticUpload:
        mesh, batches = _batch_mesh(mesh, self.tile_size)
        # Drawn by index: the same triangles in the same order (the tiles' vertex ranges become index ranges), but a
        # vertex shared by neighbouring triangles is shaded once. About half of a town's vertices are shared, and an
        # H100 runs vertex shaders on the few SMs that rasterise.
        data, indices = shared_vertices(pack_vertices(mesh))
        vbo = self.ctx.buffer(data.tobytes() if len(data) else b"\0" * VERTEX_DTYPE.itemsize)
        ibo = self.ctx.buffer(indices.tobytes() if len(indices) else b"\0" * 4)
        return _StaticUpload(vbo, ibo, _Culling(batches), len(mesh))

    @_current
    def set_lightmap(self, image: np.ndarray, origin: tuple[float, float], size: tuple[float, float]) -> None:
        """Street-lamp light pools: (H, W) intensities in [0, 1] covering ``origin`` + ``size`` metres (x, y)."""
        img = np.clip(np.asarray(image, np.float32) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        self._lightmap.release()
        h, w = img.shape
        self._lightmap = self.ctx.texture((w, h), 1, np.ascontiguousarray(img).tobytes(), dtype="f1")
        self._lightmap.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._lightmap.repeat_x = False
        self._lightmap.repeat_y = False
        self._lightmap_rect = (origin[0], origin[1], 1.0 / size[0], 1.0 / size[1])

    @_current
    def set_dynamic(self, mesh: TriangleMesh) -> None:
        """Replace the per-frame mesh."""
        mesh, self._dyn_batches = _batch_mesh(mesh, None)
        data = pack_vertices(mesh)
        capacity = self._dyn_vbo.size
        if data.nbytes > capacity:
            # grow geometrically: the actor count rises over a route, and each regrowth rebuilds the VAOs
            self._drop_vaos("dynamic")
            self._dyn_vbo.release()
            self._dyn_vbo = self.ctx.buffer(reserve=max(data.nbytes, 2 * capacity), dynamic=True)
        if data.nbytes:
            self._dyn_vbo.write(data.tobytes())
        self._scene_version += 1

    # ------------------------------------------------------------------------------------------ drawing
    def _set_uniforms(self, program: moderngl.Program, values: dict[str, object]) -> None:
        """Set the uniforms whose values changed since this program last got them (matrices are always set)."""
        last = self._uniform_values.setdefault(id(program), {})
        for name, value in values.items():
            if not isinstance(value, np.ndarray) and last.get(name, _UNSET) == value:
                continue
            _set(program, name, value)
            last[name] = value

    @staticmethod
    def _light_uniforms(lights: SpotLights) -> dict[str, object]:
        """The low beams of one view (padded with dark ones to the compiled count, shaders.light_count)."""
        n = min(len(lights), MAX_LIGHTS)
        pos, direction, color, block = (np.zeros((MAX_LIGHTS, 4), "f4") for _ in range(4))
        pos[:n, :3] = lights.position[:n]
        pos[:, 3] = NO_BLOCKER
        block[:, 2:] = 1.0
        if lights.blocker is not None and lights.block_distance is not None:
            pos[:n, 3] = lights.block_distance[:n]
            block[:n] = lights.blocker[:n]
        direction[:n, :3] = lights.direction[:n]
        color[:n, :3] = lights.color[:n]
        return {
            "u_light_pos": pos.tobytes(),
            "u_light_dir": direction.tobytes(),
            "u_light_col": color.tobytes(),
            "u_light_block": block.tobytes(),
        }

    def _weather_uniforms(self, light: Lighting) -> dict[str, object]:
        sun = self._sun_view
        return {
            "u_sky_zenith": tuple(map(float, light.sky_zenith)),
            "u_sky_horizon": tuple(map(float, light.sky_horizon)),
            "u_sun_dir": tuple(map(float, light.sun_dir)),
            "u_sun_color": tuple(map(float, light.sun_color)),
            "u_cloudiness": float(light.cloudiness),
            "u_fog_color": tuple(map(float, light.fog_color)),
            "u_fog_density": float(light.fog_density),
            "u_fog_falloff": float(light.fog_falloff),
            "u_fog_start": float(light.fog_start),
            "u_fog_base": float(FOG_BASE_HEIGHT),
            "u_ambient_sky": tuple(map(float, light.ambient_sky)),
            "u_ambient_ground": tuple(map(float, light.ambient_ground)),
            "u_wetness": float(light.wetness),
            "u_puddles": float(light.puddles),
            "u_night": float(light.night),
            "u_beams": float(light.beams),
            "u_lightmap_rect": tuple(map(float, self._lightmap_rect)),
            # Street lamps light the fog around them the more, the denser it is (its share within 20 m).
            "u_lamp_glow": float(1.0 - math.exp(-20.0 * light.fog_density)),
            "u_shadow_matrix": sun.texture if sun is not None else np.eye(4),
            # Along the normal by up to a texel (no more than 15 cm: a coarse map leans on the polygon offset).
            "u_shadow_offset": min(float(sun.texel), 0.15) if sun is not None else 0.0,
            "u_shadow_strength": float(light.shadow_strength),
            "u_sky_depth": shaders.SKY_DEPTH,
            "u_sky_tag": shaders.SKY_TAG,
        }  # fmt: skip

    def _wants_shadows(self, light: Lighting) -> bool:
        return self.shadows and light.shadow_strength > 0.0

    def _shadow_target(self, size: int, coarse: bool = False) -> tuple[moderngl.Texture, moderngl.Framebuffer]:
        """The depth texture (compared and filtered: 2×2 PCF on a hardware GPU and for the ``coarse`` map of an
        overcast sky, the nearest texel for a software rasteriser's sharp-sun map) and framebuffer of a map size."""
        filtered = self.hardware or coarse
        target = self._shadow_maps.get((size, filtered))
        if target is None:
            texture = self.ctx.depth_texture((size, size))
            texture.compare_func = "<="
            # llvmpipe fetches and compares four texels per pixel for the filtered lookup: the nearest one saves
            # ~25 ms a frame of the rig in sharp sunlight (bench_lighting, weather 12), at the price of stepped edges.
            # The coarse map keeps the filter: its filtered texels are what makes an overcast sky's shadows soft,
            # and its nearest texel would draw them as blocks four times the sharp map's.
            filtering = moderngl.LINEAR if filtered else moderngl.NEAREST
            texture.filter = (filtering, filtering)
            texture.repeat_x = False
            texture.repeat_y = False
            target = (texture, self.ctx.framebuffer(depth_attachment=texture))
            self._shadow_maps[(size, filtered)] = target
        return target

    def _update_shadow_map(self, light: Lighting, centre: np.ndarray) -> None:
        """Draw the sun's shadow map around ``centre`` unless the one drawn last still holds (same scene and sun).

        Under partial overcast the map is four times coarser: its filtered texels blur the shadow's edge over about
        the penumbra (:attr:`Lighting.shadow_softness`) at the cost of one lookup, where taps a penumbra apart would
        cost four on a software rasteriser.
        """
        coarse = light.shadow_softness > 0.4
        size = max(128, self.shadow_size // 4) if coarse else self.shadow_size
        sun = sun_view(light.sun_dir, centre, self.SHADOW_RADIUS, size)
        key = (self._scene_version, size, coarse, tuple(sun.viewproj.ravel().tolist()))
        texture, fbo = self._shadow_target(size, coarse)
        self._sun_view, self._shadow_map = sun, texture
        if key == self._shadow_key:
            return
        self._shadow_key = key
        prog = self._program(("shadow",))
        _set(prog, "u_sun_viewproj", sun.viewproj)
        fbo.use()
        fbo.viewport = (0, 0, size, size)
        fbo.clear(depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)
        self.ctx.depth_func = "<"
        # Slope-scaled offset: a face lit at a grazing angle would otherwise shadow itself in stripes.
        self.ctx.polygon_offset = (2.0, 4.0)
        try:
            total = sum(int(t.count.sum()) for t in self._dyn_batches.values())
            if total:
                self._vao(("shadow",), "dynamic").render(moderngl.TRIANGLES, vertices=total, first=0)
            runs = self._static_culling.runs(sun.viewproj, np.asarray(centre, np.float64))
            # The map keeps only the nearest depth, whatever the order: facades go last, without the walls facing
            # away from the sun (behind those facing it).
            facades = runs.get(Material.FACADE, _NO_RUNS) if self.cull_facades else _NO_RUNS
            rest = [r for m, r in runs.items() if len(r) and not (self.cull_facades and m == Material.FACADE)]
            groups = {0: np.concatenate(rest) if rest else _NO_RUNS, 1: facades}
            if not any(len(group_runs) for group_runs in groups.values()):
                return
            vao = self._vao(("shadow",), "static")
            buffer, offsets = self._indirect_commands(groups, self.SHADOW_SLOT) if self.multi_draw else (None, {})
            for group, group_runs in groups.items():
                if not len(group_runs):
                    continue
                if group == 1:
                    self.ctx.enable(moderngl.CULL_FACE)
                    self.ctx.cull_face = FACADE_CULL
                if buffer is not None:
                    vao.render_indirect(buffer, moderngl.TRIANGLES, count=len(group_runs), first=offsets[group])
                else:
                    for first, count in group_runs.tolist():
                        vao.render(moderngl.TRIANGLES, vertices=count, first=first)
        finally:
            self.ctx.polygon_offset = (0.0, 0.0)
            self.ctx.disable(moderngl.CULL_FACE)

    def _indirect_commands(self, runs: dict[int, np.ndarray], slot: int) -> tuple[moderngl.Buffer, dict[int, int]]:
        """Upload the draw commands of every material's runs for view ``slot``; returns the buffer and offsets.

        Each command is five integers (count, instances, first index, base vertex, base instance), the layout of
        glMultiDrawElementsIndirect. Each view of a frame has its own buffer, so no upload waits for an earlier draw.
        """
        total = sum(len(r) for r in runs.values())
        commands = np.zeros((max(total, 1), 5), np.uint32)
        offsets: dict[int, int] = {}
        row = 0
        for material, material_runs in runs.items():
            offsets[material] = row
            if len(material_runs):
                block = material_runs
                commands[row : row + len(block), 0] = block[:, 1]
                commands[row : row + len(block), 2] = block[:, 0]
                row += len(block)
        commands[:, 1] = 1
        buffer = self._indirect.get(slot)
        if buffer is None or buffer.size < commands.nbytes:
            if buffer is not None:
                buffer.release()
            buffer = self.ctx.buffer(reserve=max(commands.nbytes, 4096), dynamic=True)
            self._indirect[slot] = buffer
        buffer.write(commands.tobytes())
        return buffer, offsets

    def _targets_for(self, width: int, height: int, labels: bool, slot: int) -> _Targets:
        """The targets of the ``slot``-th view of a batch (created on first use, then reused every frame)."""
        key = (width, height, labels, slot)
        if key not in self._targets:
            planes = self.jpeg_planes and width % 2 == 0 and height % 2 == 0
            self._targets[key] = _Targets(self.ctx, width, height, labels, self.depth8, planes, self.packed,
                                          self.png_rows)  # fmt: skip
        return self._targets[key]

    def _unpack(self, targets: _Targets) -> None:
        """Spread the packed target over the colour (and depth, label and tag) targets (one dispatch)."""
        labels = targets.labels is not None
        program = self._unpack_programs.get((labels, targets.png_rows))
        if program is None:
            program = self.ctx.compute_shader(shaders.unpack_compute(labels, targets.png_rows))
            self._unpack_programs[labels, targets.png_rows] = program
        assert targets.packed is not None
        targets.packed.bind_to_image(0, read=True, write=False)
        outputs = (targets.color, targets.depth, targets.labels, targets.tags) if labels else (targets.color,)
        for unit, texture in enumerate(outputs, start=1):
            texture.bind_to_image(unit, read=False, write=True)
        w, h = targets.packed.size  # the image's size (the scanline targets are wider)
        gx, gy = shaders.UNPACK_GROUP
        program.run((w + gx - 1) // gx, (h + gy - 1) // gy, 1)
        # Read next by the planes pass (texel fetches) and by glReadPixels through the read framebuffer.
        self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.FRAMEBUFFER_BARRIER_BIT
                                | moderngl.PIXEL_BUFFER_BARRIER_BIT)  # fmt: skip

    def _convert_planes(self, targets: _Targets) -> None:
        """Compute the colour target's Y, Cb, Cr planes into their targets (one dispatch)."""
        if self._planes_program is None:
            self._planes_program = self.ctx.compute_shader(shaders.PLANES_COMPUTE)
            _set(self._planes_program, "u_color", 2)
        targets.color.use(2)
        for unit, texture in enumerate(targets.planes, start=1):
            texture.bind_to_image(unit, read=False, write=True)
        w, h = targets.planes[1].size
        gx, gy = shaders.PLANES_GROUP
        self._planes_program.run((w + gx - 1) // gx, (h + gy - 1) // gy, 1)
        # The planes are read back through framebuffers: their image stores must be visible to glReadPixels.
        self.ctx.memory_barrier(moderngl.FRAMEBUFFER_BARRIER_BIT | moderngl.PIXEL_BUFFER_BARRIER_BIT)

    def _draw(self, view: CameraView, light: Lighting, uniforms: dict[str, object], slot: int = 0,
              lights: SpotLights | None = None) -> _Targets:  # fmt: skip
        k = view.intrinsic()
        viewproj = projection_from_intrinsic(k, view.width, view.height, self.near, self.far) @ view.world_to_cv()
        targets = self._targets_for(view.width, view.height, view.labels, slot)
        targets.fbo.use()
        targets.fbo.viewport = (0, 0, view.width, view.height)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)
        self.ctx.depth_func = "<"
        # Only the depth buffer is cleared: the sky pass writes every pixel the scene left uncovered, and clearing
        # the integer id target with glClear would be undefined behaviour.
        targets.fbo.color_mask = targets.no_color
        targets.fbo.clear(depth=1.0)
        targets.fbo.color_mask = targets.all_color
        targets.fbo.use()  # moderngl applies a framebuffer's colour mask when it is bound
        pose = view.sensor_to_world
        self._lightmap.use(0)
        self._noise.use(1)
        # The night programs: street lamps (night) or vehicle beams (twilight, lamps lit) to light.
        night = light.night > 0.0 or (light.beams > 0.0 and lights is not None and len(lights) > 0)
        wet = light.wetness > 0.0 or light.puddles > 0.0
        shadow = self._wants_shadows(light) and self._shadow_map is not None
        if shadow:
            assert self._shadow_map is not None
            self._shadow_map.use(self.SHADOW_UNIT)
        # Only the beams that can light what this camera sees, and only at night.
        seen = beams_in_view(lights, viewproj) if night and lights is not None else SpotLights.empty()
        beams = self._light_uniforms(seen)
        # The ego's low beam lights the fog when there is fog to light.
        airlight = night and light.fog_density > 0.005 and seen.own
        falloff = light.fog_falloff > 0.0
        own = night and seen.own
        # Whether a vehicle stands in the own beam (the per-pixel test of what it hides is compiled only then).
        own_blocked = own and seen.block_distance is not None and float(seen.block_distance[0]) < NO_BLOCKER
        thin_fog = light.fog_density <= shaders.THIN_FOG
        fog_start = light.fog_start > 0.0
        fogless = light.fog_density == 0.0 and not self.hardware  # (a hardware GPU compiles no variant for it)
        variant = (shadow, airlight, falloff, shaders.light_count(len(seen)) if night else 0, own, own_blocked,
                   thin_fog)  # fmt: skip
        # Far static tiles get the distant programs (lit per vertex) where those differ: at night, or in fog too
        # dense to be fogged per vertex everywhere (and fogged per vertex at all).
        per_vertex_fog_far = not (thin_fog or falloff or light.fog_start > 0.0)
        distant_from = shaders.DISTANT_FROM if night or per_vertex_fog_far else None
        per_camera = {
            "u_viewproj": viewproj,
            "u_cam_pos": tuple(map(float, pose[:3, 3])),
            "u_cam_fwd": tuple(map(float, pose[:3, 0])),
            "u_pixel_ray": (1.0 / float(k[0, 0]), 1.0 / float(k[1, 1]), float(k[0, 2]), float(k[1, 2])),
            **beams,
        }
        camera_uniforms = {**uniforms, **per_camera}
        static_runs, near_runs = self._static_culling.split_runs(viewproj, pose[:3, 3], distant_from)
        indirect = self._indirect_commands(static_runs, slot) if self.multi_draw else None
        for material in DRAW_ORDER:
            dyn = self._dyn_batches.get(material)
            runs = static_runs.get(material, _NO_RUNS)
            if dyn is None and not len(runs):
                continue
            near = near_runs.get(material, len(runs)) if material != Material.FACADE else len(runs)
            # The near runs (and the actors) first, then the distant ones: the drawing order of the triangles stays.
            for distant, part in ((False, slice(0, near)), (True, slice(near, len(runs)))):
                key = ("scene", int(material), night, wet, *variant, distant, fog_start, fogless)
                if distant and part.start == part.stop:
                    continue
                prog = self._program(key)
                self._set_uniforms(prog, camera_uniforms)
                if material == Material.FACADE and self.cull_facades:
                    self.ctx.enable(moderngl.CULL_FACE)
                    self.ctx.cull_face = FACADE_CULL
                else:
                    self.ctx.disable(moderngl.CULL_FACE)
                if dyn is not None and not distant:
                    vao = self._vao(key, "dynamic")
                    vao.render(moderngl.TRIANGLES, vertices=int(dyn.count.sum()), first=int(dyn.first[0]))
                if part.stop > part.start:
                    vao = self._vao(key, "static")
                    if indirect is not None:
                        # One multi-draw per material (and part) instead of one call per visible tile run: the same
                        # triangles in the same order (identical pixels), without hundreds of driver calls per view.
                        buffer, offsets = indirect
                        vao.render_indirect(buffer, moderngl.TRIANGLES, count=part.stop - part.start,
                                            first=offsets[material] + part.start)  # fmt: skip
                    else:
                        for first, count in runs[part].tolist():
                            vao.render(moderngl.TRIANGLES, vertices=count, first=first)
        self.ctx.disable(moderngl.CULL_FACE)
        self.ctx.depth_func = "<="
        sky_key = ("sky", light.cloudiness > 0.01, falloff, airlight)
        sky = self._program(sky_key)
        self._set_uniforms(sky, {**uniforms, **beams})
        _set(sky, "u_cam_rot", pose[:3, :3] @ UE_TO_CV[:3, :3].T)  # OpenCV axes → world
        _set(sky, "u_cam_pos", per_camera["u_cam_pos"])
        _set(sky, "u_intrinsic", (float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])))
        _set(sky, "u_viewport", (float(view.width), float(view.height)))
        self._vao(sky_key, "sky").render(moderngl.TRIANGLES)
        return targets

    @_current
    def render(
        self,
        views: Sequence[CameraView],
        lighting: Lighting,
        lights: SpotLights | None = None,
        centre: np.ndarray | None = None,
    ) -> list[CameraFrame]:
        """Draw each view and read back RGB (and depth / semantic / instance when ``labels``).

        ``lights`` are the vehicle lamps lighting the scene at night; ``centre`` is where the sun's shadows are drawn
        around (the ego; by default the first view's position). Depth is float32 metres, or with ``depth8`` the
        uint8 metres the depth PNG stores (``depth_to_png_pixels``).
        """
        if self._wants_shadows(lighting) and views:
            self._update_shadow_map(lighting, views[0].sensor_to_world[:3, 3] if centre is None else centre)
        uniforms = self._weather_uniforms(lighting)
        # Every view gets its own targets and all are drawn before any is read back: the rasteriser threads work
        # on one camera while this thread prepares the next, and read-backs do not stall between draws.
        drawn = [self._draw(view, lighting, uniforms, slot, lights) for slot, view in enumerate(views)]
        for targets in drawn:
            if targets.packed is not None:
                self._unpack(targets)
            if targets.planes:
                self._convert_planes(targets)
        reads = _Readback(self.ctx, self._pack_buffer, self.pixel_buffer, self._host, self._mapped, self._packer)
        for view, targets in zip(views, drawn):
            h, w = view.height, view.width
            if targets.planes:
                assert targets.luma_fbo is not None and targets.chroma_fbo is not None
                # Read through framebuffers as the other one-byte targets are (the driver's fast path).
                reads.add(targets.luma_fbo, 0, (h, w), "u1")
                reads.add(targets.chroma_fbo, 0, (h // 2, w // 2), "u1")
                reads.add(targets.chroma_fbo, 1, (h // 2, w // 2), "u1")
            else:
                # Reading RGBA is about twice as fast as letting GL convert to RGB; the JPEG encoders drop the alpha.
                reads.add(targets.read_fbo, 0, (h, w, 4), "f1")
            if view.labels and targets.png_rows:
                assert targets.rows_fbo is not None and targets.labels_fbo is not None
                reads.add(targets.rows_fbo, 0, (h, w + 1), "u1")
                reads.add(targets.labels_fbo, 0, (h, 4 * w + 1), "u1")
                reads.add(targets.rows_fbo, 1, (h, w + 1), "u1")
            elif view.labels:
                reads.add(targets.read_fbo, 1, (h, w), "u1" if self.depth8 else "f4")
                reads.add(targets.read_fbo, 2, (h, w, 4), "u1")
                # The semantic PNG filters a contiguous plane ~9× faster than a strided view of the labels.
                reads.add(targets.read_fbo, 3, (h, w), "u1")
        arrays = iter(reads.finish())
        self._pack_buffer = reads.buffer
        frames = []
        for view, targets in zip(views, drawn):
            rgb: np.ndarray | None = None
            planes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
            if targets.planes:
                planes = (next(arrays), next(arrays), next(arrays))
            else:
                rgb = next(arrays)[..., :3]  # a view of this frame's own RGBA pixels
            if not view.labels:
                frames.append(CameraFrame(rgb=rgb, jpeg_planes=planes))
                continue
            depth, labels, semantic = next(arrays), next(arrays), next(arrays)
            if targets.png_rows:  # the images without their filter bytes (views: the encoder finds the rows again)
                depth, semantic = depth[:, 1:], semantic[:, 1:]
                labels = labels[:, 1:].reshape(view.height, view.width, 4)
            _, instance = label_views(labels)
            frames.append(CameraFrame(rgb=rgb, depth=depth, semantic=semantic, instance=instance, labels=labels,
                                      jpeg_planes=planes))  # fmt: skip
        return frames

    def close(self) -> None:
        """Release the GL context and everything in it."""
        with self.ctx:
            for t in self._targets.values():
                t.release()
            self._targets.clear()
            for buffer in self._indirect.values():
                buffer.release()
            self._indirect.clear()
            if self._pack_buffer is not None:
                self._pack_buffer.release()
                self._pack_buffer = None
            if self._packer is not None:
                self._packer.release()
            mapped_free = self._mapped is None or self._mapped.release()
        if mapped_free:
            self.ctx.release()
        else:
            # Arrays of a frame still view mapped read-back memory, which the context's end would unmap under them:
            # the context is kept until they are gone (released by a later close).
            log.debug("GL context kept open: a frame's arrays still view its mapped read-back memory")
            _KEPT_OPEN.append((self.ctx, self._mapped))
        _release_kept_open()
