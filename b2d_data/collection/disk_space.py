"""A full disk during a collection: recognising it in a job's error, and how much space the rest of the run needs.

A route job that fails on a full disk is noted :data:`DISK_FULL`; the driver then starts no new route (each would
fail the same way and use up an attempt) and, at the end, tells the user how much space the missing clips need.
"""

from __future__ import annotations

import errno
import os
import shutil
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

#: ``JobResult.note`` of an attempt stopped by a full disk: no verdict on the route, which runs again on resume.
DISK_FULL = "disk full"
#: Complete clips measured for the per-clip estimate (the most recent ones: measuring stats every file).
SAMPLE_CLIPS = 5
_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` or an exception it came from is 'No space left on device' (or a full quota); HDF5 reports it
    only in its message text."""
    texts = tuple(os.strerror(e) for e in _FULL_ERRNOS)
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, OSError) and current.errno in _FULL_ERRNOS:
            return True
        if any(text in str(current) for text in texts):
            return True
        current = current.__cause__ or current.__context__
    return False


def folder_bytes(folder: Path) -> int:
    """Bytes of the files under ``folder``."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file() and not p.is_symlink())


@dataclass(frozen=True)
class SpaceNeeded:
    """What a collection stopped by a full disk still needs, estimated from its clips or its stopped attempts."""

    out: str
    missing_clips: int
    free_bytes: int
    #: Mean size of the corpus's most recent complete clips (None before the first clip).
    per_clip_bytes: float | None = None
    clips_measured: int = 0
    #: Bytes per frame the stopped attempts wrote (None when they wrote none).
    per_frame_bytes: float | None = None
    #: Frames of a typical route of this collection (None before any estimate).
    frames_per_clip: float | None = None

    @property
    def needed_bytes(self) -> float | None:
        """Space the missing clips need: per clip when clips exist, else per frame times a route's frames."""
        if self.per_clip_bytes is not None:
            return self.per_clip_bytes * self.missing_clips
        if self.per_frame_bytes is not None and self.frames_per_clip is not None:
            return self.per_frame_bytes * self.frames_per_clip * self.missing_clips
        return None

    def describe(self) -> str:
        """One sentence for the user: how much space, how it was estimated, and what to do."""
        head = f"the disk of {self.out} is full (no space left on device), so no new route was started"
        need = self.needed_bytes
        if need is not None and self.per_clip_bytes is not None:
            basis = f"{format_bytes(self.per_clip_bytes)} per clip, measured on {self.clips_measured} clip(s)"
        elif need is not None:
            basis = (f"{format_bytes(self.per_frame_bytes or 0.0)} per frame written before the disk filled, "
                     f"~{self.frames_per_clip:.0f} frames per route")  # fmt: skip
        elif self.per_frame_bytes is not None:
            basis = f"each frame takes about {format_bytes(self.per_frame_bytes)}"
        else:
            basis = ""
        free = f"{format_bytes(self.free_bytes)} is free now"
        if need is not None:
            what = f"the {self.missing_clips} missing clip(s) need about {format_bytes(need)} ({basis}); {free}"
            return f"{head}: {what}. Free that much space, then run the same command with --resume"
        detail = f" ({basis}; {free})" if basis else f" ({free})"
        return f"{head}{detail}. Free space, then run the same command with --resume"

    def to_dict(self) -> dict[str, Any]:
        """JSON form (with the estimate)."""
        need = self.needed_bytes
        return {**asdict(self), "needed_bytes": None if need is None else round(need)}


def space_needed(
    out: Path,
    clip_dirs: Sequence[Path],
    stopped: Iterable[Mapping[str, Any]],
    missing_clips: int,
    frames_per_clip: float | None,
) -> SpaceNeeded:
    """Estimate what the ``missing_clips`` need: from the most recent complete ``clip_dirs``, else from the bytes
    per frame of the ``stopped`` attempts (run-log records) times ``frames_per_clip``."""
    sample = [d for d in clip_dirs if d.is_dir()][-SAMPLE_CLIPS:]
    per_clip = sum(folder_bytes(d) for d in sample) / len(sample) if sample else None
    pairs = [(int(r.get("frames") or 0), int(r.get("bytes_written") or 0)) for r in stopped]
    pairs = [(f, b) for f, b in pairs if f > 0 and b > 0]
    per_frame = sum(b for _, b in pairs) / sum(f for f, _ in pairs) if pairs else None
    try:
        free = shutil.disk_usage(out).free
    except OSError:
        free = 0
    return SpaceNeeded(str(out), missing_clips, free, per_clip, len(sample), per_frame, frames_per_clip)


def format_bytes(n: float) -> str:
    """``12 kB``, ``5.7 MB``, ``1.24 GB`` (decimal units, as ``df -H``)."""
    if n >= 1e9:
        return f"{n / 1e9:.2f} GB"
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.0f} kB"
