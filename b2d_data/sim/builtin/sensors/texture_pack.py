"""One-byte textures read back by a compute pass instead of glReadPixels: every SM packs their rows into a buffer on
the GPU (``shaders.BYTES_COMPUTE``), and one buffer copy moves the frame to host memory.

On an H100 shared by many route processes, glReadPixels of a collection frame (~67 MB of one-byte targets) held the
GPU 4.8 ms, whether it wrote host memory or a buffer on the GPU: the driver converts the pixels on the few graphics
units, and that, not the bus, bounded the frames per second. The pass and the copy take 1.3 ms
(``scripts/probe_readback.py``). The bytes are the same as glReadPixels' with a pack alignment of one.
"""

from __future__ import annotations

import moderngl

from b2d_data.sim.builtin.sensors import shaders


class TexturePacker:
    """Packs one-byte textures into a GPU buffer at given offsets, then copies that buffer to another in one go."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._program: moderngl.ComputeShader | None = None
        self._device: moderngl.Buffer | None = None

    @staticmethod
    def packable(texture: object, shape: tuple[int, ...], dtype: str) -> bool:
        """Whether reading ``texture`` as an array of ``shape`` (rows, columns) and moderngl type ``dtype`` is what
        :meth:`pack` does: a whole single-channel unsigned-byte texture."""
        return (isinstance(texture, moderngl.Texture) and texture.components == 1 and texture.dtype == "u1"
                and dtype == "u1" and len(shape) == 2 and texture.size == (shape[1], shape[0]))  # fmt: skip

    def begin(self, nbytes: int) -> None:
        """Make room for ``nbytes`` and make earlier image writes (the unpack and planes passes) visible to the pass."""
        if self._device is None or self._device.size < nbytes:
            if self._device is not None:
                self._device.release()
            self._device = self.ctx.buffer(reserve=max(nbytes, 4))
        if self._program is None:
            self._program = self.ctx.compute_shader(shaders.BYTES_COMPUTE)
        self.ctx.memory_barrier(moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)

    @property
    def device(self) -> moderngl.Buffer:
        """The GPU buffer of this frame (after :meth:`begin`): glReadPixels of other reads may go into it too."""
        assert self._device is not None, "begin() first"
        return self._device

    def pack(self, texture: moderngl.Texture, offset: int) -> None:
        """Queue the pass that writes ``texture``'s rows, one after the other, at byte ``offset`` (a multiple of 4)."""
        assert self._program is not None and self._device is not None, "begin() first"
        if offset % 4:
            raise ValueError(f"texture bytes go to a word boundary, not to byte {offset}")
        width, height = texture.size
        count = width * height
        texture.bind_to_image(0, read=True, write=False)
        self._device.bind_to_storage_buffer(0)
        self._program["u_width"] = width
        self._program["u_bytes"] = count
        self._program["u_first"] = offset // 4
        words = -(-count // 4)
        self._program.run(-(-words // shaders.BYTES_GROUP))

    def copy_to(self, target: moderngl.Buffer, nbytes: int) -> None:
        """Queue the copy of the first ``nbytes`` of the GPU buffer into ``target`` (after every queued pass)."""
        # The passes' storage writes must land before glCopyBufferSubData reads the buffer.
        self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
        self.ctx.copy_buffer(target, self.device, size=nbytes)

    def release(self) -> None:
        """Free the GPU buffer and the program."""
        for obj in (self._device, self._program):
            if obj is not None:
                obj.release()
        self._device = self._program = None
