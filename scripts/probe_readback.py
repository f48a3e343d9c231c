"""Ways of getting one collection frame's pixels from the GPU into host memory, timed alone and with many processes.

A frame of the collection rig, as the renderer reads it back on a GPU: six labelled cameras (JPEG planes Y / Cb / Cr,
depth, labels and tags as PNG scanlines) and the top-down camera's planes, ~69 MB at 1600×900, in one-byte
textures filled with noise. Each way is checked to deliver the same bytes as the first, then timed:

- ``pbo-mapped``: glReadPixels of every texture into a persistently mapped client-storage buffer (the renderer's
  way today, ``MappedPool``);
- ``pbo-device``: glReadPixels into a buffer the driver keeps on the GPU (no transfer: what the conversion costs);
- ``pbo-device-copy``: the same, then one glCopyBufferSubData into the mapped buffer;
- ``packer``: the renderer's ``TexturePacker``: a compute pass packs every texture's bytes into a GPU buffer, then
  one copy into the mapped buffer.

    python scripts/probe_readback.py --procs 1 --procs 16 --frames 30
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

from b2d_data.sim.builtin.sensors.texture_pack import TexturePacker
from probe_gpu_share import run_together  # scripts/ is the script's own folder

MODES = ("pbo-mapped", "pbo-device", "pbo-device-copy", "packer")
ALIGN = 64
def frame_shapes(width: int, height: int) -> list[tuple[int, int]]:
    """(columns, rows) of every one-byte texture a frame reads back."""
    planes = [(width, height), (width // 2, height // 2), (width // 2, height // 2)]
    labelled = planes + [(width + 1, height), (4 * width + 1, height), (width + 1, height)]
    return labelled * 6 + planes


class Frame:
    """The textures of one frame, their read framebuffers and their places in the read-back buffer."""

    def __init__(self, ctx: Any, width: int, height: int, seed: int) -> None:
        rng = np.random.default_rng(seed)
        self.ctx = ctx
        self.textures, self.fbos, self.offsets = [], [], []
        size = 0
        for w, h in frame_shapes(width, height):
            texture = ctx.texture((w, h), 1, rng.integers(0, 256, w * h, dtype=np.uint8).tobytes(), dtype="u1")
            self.textures.append(texture)
            self.fbos.append(ctx.framebuffer([texture]))
            self.offsets.append(size)
            size += -(-(w * h) // ALIGN) * ALIGN
        self.size = size
        self.packer = TexturePacker(ctx)

    def read_pixels(self, buffer: Any) -> None:
        """glReadPixels of every texture into ``buffer``."""
        for texture, fbo, offset in zip(self.textures, self.fbos, self.offsets):
            w, h = texture.size
            fbo.read_into(buffer, viewport=(0, 0, w, h), components=1, dtype="u1", write_offset=offset)

    def pack(self, buffer: Any) -> None:
        """The renderer's way: every texture packed on the GPU, then one copy into ``buffer``."""
        self.packer.begin(self.size)
        for texture, offset in zip(self.textures, self.offsets):
            self.packer.pack(texture, offset)
        self.packer.copy_to(buffer, self.size)


def _one(mode: str, frame: Frame, mapped: Any, device: Any) -> None:
    """Issue one frame's read-back in ``mode``, then wait for the GPU."""
    if mode == "pbo-mapped":
        frame.read_pixels(mapped)
    elif mode == "pbo-device":
        frame.read_pixels(device)
    elif mode == "pbo-device-copy":
        frame.read_pixels(device)
        frame.ctx.copy_buffer(mapped, device, size=frame.size)
    elif mode == "packer":
        frame.pack(mapped)
    frame.ctx.finish()


def _setup(width: int, height: int, seed: int) -> tuple[Frame, Any, np.ndarray, Any]:
    from b2d_data.sim.builtin.sensors.host_pool import MappedPool
    from b2d_data.sim.builtin.sensors.renderer import create_gl_context

    ctx = create_gl_context()
    frame = Frame(ctx, width, height, seed)
    pool = MappedPool(ctx, keep=1)
    mapped, block = pool.take(frame.size)
    device = ctx.buffer(reserve=frame.size)
    return frame, mapped, block, device


def check(width: int, height: int) -> None:
    """Every mode delivers the bytes glReadPixels delivers (raises otherwise)."""
    frame, mapped, block, device = _setup(width, height, 1)
    _one("pbo-mapped", frame, mapped, device)
    want = block.copy()
    for mode in MODES[1:]:
        block[:] = 0
        if mode == "pbo-device":
            _one(mode, frame, mapped, device)
            got = np.frombuffer(device.read(), dtype=np.uint8)
        else:
            _one(mode, frame, mapped, device)
            got = block
        for (w, h), offset in zip(frame_shapes(width, height), frame.offsets):
            if not np.array_equal(got[offset : offset + w * h], want[offset : offset + w * h]):
                raise SystemExit(f"{mode}: the bytes of a {w}x{h} texture differ from glReadPixels'")
    print(f"checked: every mode delivers glReadPixels' bytes ({frame.size / 1e6:.1f} MB a frame)")


def _worker(mode: str, width: int, height: int, frames: int, slot: int, barrier: Any, results: Any) -> None:
    os.environ.setdefault("B2D_GPU_SLOT", str(slot))
    frame, mapped, _, device = _setup(width, height, slot)
    for _ in range(3):
        _one(mode, frame, mapped, device)
    query = frame.ctx.query(time=True)
    with query:
        _one(mode, frame, mapped, device)
    gpu_ms = query.elapsed / 1e6
    barrier.wait()
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(frames):
        _one(mode, frame, mapped, device)
    results.put((time.perf_counter() - t0, time.process_time() - c0, gpu_ms))


def run(mode: str, procs: int, width: int, height: int, frames: int) -> tuple[float, float, float]:
    """(frames/s over all processes, CPU ms per frame, GPU ms of one frame alone) for ``procs`` processes."""
    got = run_together(_worker, (mode, width, height, frames), procs, mode)
    wall = max(g[0] for g in got)
    return procs * frames / wall, 1e3 * sum(g[1] for g in got) / (procs * frames), min(g[2] for g in got)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--procs", type=int, action="append", default=[])
    parser.add_argument("--mode", action="append", default=[], choices=MODES)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=900)
    args = parser.parse_args()
    check(args.width, args.height)
    mb = sum(-(-(w * h) // ALIGN) * ALIGN for w, h in frame_shapes(args.width, args.height)) / 1e6
    print("| processes | mode | frames/s (all) | GB/s (all) | ratio to first mode | CPU ms per frame | GPU ms alone |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    for procs in args.procs or [1, 16]:
        first = None
        for mode in args.mode or MODES:
            fps, cpu, gpu = run(mode, procs, args.width, args.height, args.frames)
            first = fps if first is None else first
            print(f"| {procs} | {mode} | {fps:.1f} | {fps * mb / 1e3:.1f} | {fps / first:.2f} | {cpu:.2f} | {gpu:.2f} |",
                  flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
