"""Hand frame arrays to encoding processes through reusable shared-memory slots (one memcpy, no pickling).

Pickling a full 6-camera frame (~90 MB) through the pool's pipe costs ~0.25 s of the writer's CPU; copying it
into a reused shared-memory slot costs ~15 ms. Slots are reused because first-touching fresh shared pages
costs as much as the copy itself.
"""

from __future__ import annotations

import logging
import shutil
from collections import OrderedDict
from dataclasses import dataclass
from multiprocessing import shared_memory
from pathlib import Path

import numpy as np

logger = logging.getLogger(__name__)

_SHM_DIR = Path("/dev/shm")
_ALIGN = 64
_MIB = 1 << 20


@dataclass(frozen=True)
class SharedArray:
    """A reference to an array stored in a shared-memory slot; cheap to pickle."""

    segment: str
    offset: int
    shape: tuple[int, ...]
    dtype: str

    def view(self) -> np.ndarray:
        """The array, as a view into the segment (attached once per process)."""
        shm = _attach(self.segment)
        return np.ndarray(self.shape, dtype=np.dtype(self.dtype), buffer=shm.buf, offset=self.offset)


def resolve(value: np.ndarray | SharedArray | None) -> np.ndarray | None:
    """The array behind ``value``, whether it was passed directly or through shared memory."""
    return value.view() if isinstance(value, SharedArray) else value


# Worker side: segments stay attached between jobs; the least recently used ones are dropped.
_ATTACHED: OrderedDict[str, shared_memory.SharedMemory] = OrderedDict()
_MAX_ATTACHED = 8


def _attach(name: str) -> shared_memory.SharedMemory:
    shm = _ATTACHED.get(name)
    if shm is not None:
        _ATTACHED.move_to_end(name)
        return shm
    shm = shared_memory.SharedMemory(name=name)
    _ATTACHED[name] = shm
    while len(_ATTACHED) > _MAX_ATTACHED:
        _, old = _ATTACHED.popitem(last=False)
        try:
            old.close()
        except BufferError:  # a view is still alive somewhere: leave the mapping to the process exit
            pass
    return shm


def _aligned(n: int) -> int:
    return (n + _ALIGN - 1) // _ALIGN * _ALIGN


def packed_size(arrays: list[np.ndarray]) -> int:
    """Bytes a slot needs to hold ``arrays`` back to back (each 64-byte aligned)."""
    return sum(_aligned(a.nbytes) for a in arrays)


class SharedSlot:
    """One shared-memory segment that holds the arrays of one in-flight frame."""

    def __init__(self, size: int) -> None:
        self.shm = shared_memory.SharedMemory(create=True, size=max(size, 1))
        self.size = self.shm.size

    def pack(self, arrays: list[np.ndarray]) -> list[SharedArray]:
        """Copy ``arrays`` into the slot and return their references."""
        refs, offset = [], 0
        for src in arrays:
            dst = np.ndarray(src.shape, dtype=src.dtype, buffer=self.shm.buf, offset=offset)
            dst[...] = src  # one copy, also of a strided view (the renderer's RGB is a view of its RGBA)
            refs.append(SharedArray(self.shm.name, offset, tuple(src.shape), src.dtype.str))
            offset += _aligned(src.nbytes)
        return refs

    def destroy(self) -> None:
        """Unmap and remove the segment."""
        try:
            self.shm.close()
        finally:
            try:
                self.shm.unlink()
            except FileNotFoundError:
                pass


class SlotPool:
    """Shared-memory slots for in-flight frames, reused from frame to frame."""

    def __init__(self) -> None:
        self._free: list[SharedSlot] = []
        self._disabled = False

    def acquire(self, size: int) -> SharedSlot | None:
        """A slot of at least ``size`` bytes, or ``None`` when shared memory is unavailable or too small."""
        if self._disabled:
            return None
        while self._free:
            slot = self._free.pop()
            if slot.size >= size:
                return slot
            slot.destroy()
        want = (size + _MIB - 1) // _MIB * _MIB
        # Writing past the free space of a tmpfs kills the process with SIGBUS, so check first (Docker's
        # default /dev/shm is 64 MiB, less than one full frame).
        if _SHM_DIR.is_dir() and shutil.disk_usage(_SHM_DIR).free < want + 64 * _MIB:
            logger.warning(
                "%s has too little free space for a %d MiB frame: frames go to the encoders by pickling "
                "(slower; enlarge it, e.g. docker --shm-size=1g)", _SHM_DIR, want // _MIB,
            )
            self._disabled = True
            return None
        try:
            return SharedSlot(want)
        except OSError as exc:
            logger.warning("shared memory unavailable (%s): frames go to the encoders by pickling", exc)
            self._disabled = True
            return None

    def release(self, slot: SharedSlot) -> None:
        """Return a slot whose frame has been written."""
        self._free.append(slot)

    def close(self) -> None:
        """Remove every free slot (in-use slots are released first by the writer)."""
        while self._free:
            self._free.pop().destroy()
