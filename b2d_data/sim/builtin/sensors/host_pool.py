"""Host memory for a frame's read-backs, reused once nothing views it any more.

A rig's read-back is ~70 MB a frame at 1600×900. Fresh memory of that size comes from the kernel page by page and
zeroed: ~9 ms of CPU a frame on the 2-core machine before a byte is copied (``scripts/bench_collect.py`` profile).
Every array a frame hands out is a view of its block, so a block whose only owner is the pool can be written again.
"""

from __future__ import annotations

import sys

import numpy as np

#: References to a block that only the pool holds, as ``sys.getrefcount`` counts them in :meth:`HostPool.take`: the
#: pool's list, the ``block`` name there, and the call's own argument.
_UNVIEWED = 3


class HostPool:
    """A few byte blocks handed out for reuse; a block still viewed by some frame's arrays is never handed out."""

    def __init__(self, keep: int = 3) -> None:
        self.keep = keep
        self._blocks: list[np.ndarray] = []

    def take(self, nbytes: int) -> np.ndarray:
        """A uint8 array of ``nbytes`` that no earlier frame's array views (its contents are stale)."""
        free = []
        for index in range(len(self._blocks)):
            block = self._blocks[index]
            if sys.getrefcount(block) <= _UNVIEWED:
                if block.nbytes >= nbytes:
                    return block[:nbytes]
                free.append(index)
        block = np.empty(max(nbytes, 1), np.uint8)
        if len(self._blocks) < self.keep:
            self._blocks.append(block)
        elif free:
            # A free block that is too small (the rig grew) gives its place to the new one; where every block is
            # still viewed (frames queued for writing) the new one is not kept.
            self._blocks[free[0]] = block
        return block[:nbytes]
