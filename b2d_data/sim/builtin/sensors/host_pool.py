"""Host memory for a frame's read-backs, reused once nothing views it any more: plain blocks, or pixel-pack buffers
mapped into the process (:class:`MappedPool`, where the GL driver has buffer storage).

A rig's read-back is ~70 MB a frame at 1600×900. Fresh memory of that size comes from the kernel page by page and
zeroed: ~9 ms of CPU a frame on the 2-core machine before a byte is copied (``scripts/bench_collect.py`` profile).
Every array a frame hands out is a view of its block, so a block whose only owner is the pool can be written again.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import moderngl
import numpy as np

log = logging.getLogger(__name__)

#: References to a block that only the pool holds, as ``sys.getrefcount`` counts them in :func:`_unviewed`: the
#: pool's list and the call's own argument.
_UNVIEWED = 2


def _unviewed(blocks: list[np.ndarray], nbytes: int) -> tuple[int | None, list[int]]:
    """The index of the first block of ``blocks`` that nothing but the list holds and that has room for ``nbytes``
    (or ``None``), and the indices of the unheld ones too small, looked at before it."""
    small = []
    for index in range(len(blocks)):
        if sys.getrefcount(blocks[index]) <= _UNVIEWED:
            if blocks[index].nbytes >= nbytes:
                return index, small
            small.append(index)
    return None, small


class HostPool:
    """A few byte blocks handed out for reuse; a block still viewed by some frame's arrays is never handed out."""

    def __init__(self, keep: int = 3) -> None:
        self.keep = keep
        self._blocks: list[np.ndarray] = []

    def take(self, nbytes: int) -> np.ndarray:
        """A uint8 array of ``nbytes`` that no earlier frame's array views (its contents are stale)."""
        fits, small = _unviewed(self._blocks, nbytes)
        if fits is not None:
            return self._blocks[fits][:nbytes]
        block = np.empty(max(nbytes, 1), np.uint8)
        if len(self._blocks) < self.keep:
            self._blocks.append(block)
        elif small:
            # A free block that is too small (the rig grew) gives its place to the new one; where every block is
            # still viewed (frames queued for writing) the new one is not kept.
            self._blocks[small[0]] = block
        return block[:nbytes]


# ------------------------------------------------------------------------------------ persistently mapped buffers

_PIXEL_PACK_BUFFER = 0x88EB
_MAP_READ, _MAP_PERSISTENT, _MAP_COHERENT, _CLIENT_STORAGE = 0x0001, 0x0040, 0x0080, 0x0200


@dataclass(frozen=True)
class _BufferCalls:
    """The buffer-storage entry points moderngl does not wrap (OpenGL 4.4), resolved through eglGetProcAddress."""

    gen_buffers: Callable[..., None]
    bind_buffer: Callable[..., None]
    buffer_storage: Callable[..., None]
    map_buffer_range: Callable[..., int | None]
    unmap_buffer: Callable[..., int]
    delete_buffers: Callable[..., None]


@functools.cache
def _buffer_calls() -> _BufferCalls | None:
    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return None
    lookup = egl.eglGetProcAddress
    lookup.restype, lookup.argtypes = ctypes.c_void_p, [ctypes.c_char_p]

    def entry(name: str, result: Any, *args: Any) -> Callable[..., Any]:
        address = lookup(name.encode("ascii"))
        if not address:
            raise OSError(f"{name} not found")
        return ctypes.CFUNCTYPE(result, *args)(address)

    size, uint = ctypes.c_ssize_t, ctypes.c_uint
    try:
        return _BufferCalls(
            entry("glGenBuffers", None, ctypes.c_int, ctypes.POINTER(uint)),
            entry("glBindBuffer", None, uint, uint),
            entry("glBufferStorage", None, uint, size, ctypes.c_void_p, uint),
            entry("glMapBufferRange", ctypes.c_void_p, uint, size, size, uint),
            entry("glUnmapBuffer", ctypes.c_ubyte, uint),
            entry("glDeleteBuffers", None, ctypes.c_int, ctypes.POINTER(uint)),
        )  # fmt: skip
    except OSError as exc:
        log.debug("no persistently mapped read-back buffers: %s", exc)
        return None


class MappedPool:
    """Pixel-pack buffers mapped into this process for good: glReadPixels lands in host memory that the frame's
    arrays then view, without the copy out of a driver buffer (~10 CPU ms a frame on an H100 host for ~70 MB).

    A block is reused, as :class:`HostPool`'s, once no array views it; where every kept block is still viewed,
    :meth:`take` gives ``None`` (the caller reads another way). Unmapping memory that arrays still view would leave
    them dangling, so :meth:`release` refuses while any block is viewed.
    """

    def __init__(self, ctx: moderngl.Context, keep: int = 3) -> None:
        self.ctx = ctx
        self.keep = keep
        # Parallel lists: each buffer and its mapped memory.
        self._buffers: list[moderngl.Buffer] = []
        self._blocks: list[np.ndarray] = []

    @staticmethod
    def supported(ctx: moderngl.Context) -> bool:
        """Whether ``ctx`` has buffer storage (OpenGL 4.4, or the extension) and its entry points can be found."""
        # The NVIDIA driver hands out exactly the 4.3 context the renderer asks for, with the extension.
        storage = ctx.version_code >= 440 or "GL_ARB_buffer_storage" in ctx.extensions
        return storage and _buffer_calls() is not None

    def take(self, nbytes: int) -> tuple[moderngl.Buffer, np.ndarray] | None:
        """A mapped pixel-pack buffer of at least ``nbytes`` and its memory as a uint8 array, or ``None``."""
        fits, small = _unviewed(self._blocks, nbytes)
        if fits is not None:
            return self._buffers[fits], self._blocks[fits][:nbytes]
        if len(self._blocks) >= self.keep and not small:
            return None
        if small:  # a free block that is too small (the rig grew) gives its place to the new one
            self._unmap(self._buffers.pop(small[0]))
            self._blocks.pop(small[0])
        buffer, block = self._map(max(nbytes, 1))
        self._buffers.append(buffer)
        self._blocks.append(block)
        return buffer, block[:nbytes]

    def in_use(self) -> bool:
        """Whether some array still views one of the blocks."""
        return any(sys.getrefcount(self._blocks[index]) > _UNVIEWED for index in range(len(self._blocks)))

    def release(self) -> bool:
        """Unmap and delete every buffer, unless one is still viewed (then nothing is released: returns False)."""
        if self.in_use():
            return False
        while self._buffers:
            self._unmap(self._buffers.pop())
        self._blocks.clear()
        return True

    def _map(self, nbytes: int) -> tuple[moderngl.Buffer, np.ndarray]:
        calls = _buffer_calls()
        assert calls is not None
        name = (ctypes.c_uint * 1)()
        calls.gen_buffers(1, name)
        calls.bind_buffer(_PIXEL_PACK_BUFFER, name[0])
        # Client storage: the buffer lives in host memory, which the GPU writes by DMA and the CPU reads cached.
        calls.buffer_storage(_PIXEL_PACK_BUFFER, nbytes, None, _MAP_READ | _MAP_PERSISTENT | _MAP_COHERENT
                             | _CLIENT_STORAGE)  # fmt: skip
        address = calls.map_buffer_range(_PIXEL_PACK_BUFFER, 0, nbytes, _MAP_READ | _MAP_PERSISTENT | _MAP_COHERENT)
        calls.bind_buffer(_PIXEL_PACK_BUFFER, 0)
        if not address:
            calls.delete_buffers(1, name)
            raise RuntimeError(f"glMapBufferRange of a {nbytes}-byte pixel-pack buffer failed")
        block = np.ctypeslib.as_array((ctypes.c_ubyte * nbytes).from_address(address))
        return self.ctx.external_buffer(name[0], nbytes), block

    def _unmap(self, buffer: moderngl.Buffer) -> None:
        calls = _buffer_calls()
        assert calls is not None
        name = (ctypes.c_uint * 1)(buffer.glo)
        calls.bind_buffer(_PIXEL_PACK_BUFFER, name[0])
        calls.unmap_buffer(_PIXEL_PACK_BUFFER)
        calls.bind_buffer(_PIXEL_PACK_BUFFER, 0)
        calls.delete_buffers(1, name)
