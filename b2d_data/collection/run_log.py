"""The run log of a collection: ``<out>/run_log.jsonl``, one JSON object per line, append-only and fsync'd.

Two kinds of lines describe attempts: ``{"event": "start", ...}`` when an attempt is launched and
``{"event": "attempt", ...}`` when it ends (a :class:`~b2d_data.collection.job.JobResult`). A route with a start line
but no attempt line was interrupted; resume runs it again. Two more kinds say what happened to interrupted work:
``{"event": "interrupted", "route_id": ...}`` records it (written on Ctrl-C / SIGTERM, or by the resume that
finds the start of a ``kill -9``-ed run), and ``{"event": "discarded", "path": ...}`` names a half-written
temporary that a resume removed. Only the collection's driver process writes the log, so
lines never interleave. A line cut short by a crash is skipped with a warning when reading, and the next append
starts on a fresh line.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

LOG_FILE = "run_log.jsonl"
EVENT_START = "start"
EVENT_ATTEMPT = "attempt"
EVENT_INTERRUPTED = "interrupted"
EVENT_DISCARDED = "discarded"


class RunLog:
    """Appends records to a run log file; every append reaches the disk before it returns."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)

    def append(self, record: Mapping[str, Any]) -> None:
        """Write one record as one line and fsync it."""
        line = json.dumps(dict(record), sort_keys=False, separators=(",", ":"), default=str)
        new_file = not self.path.exists()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path, "a+b") as f:
            f.seek(0, os.SEEK_END)
            prefix = b""
            if f.tell() > 0:
                # A crash may have cut the last line: never glue a record onto it.
                f.seek(-1, os.SEEK_END)
                if f.read(1) != b"\n":
                    prefix = b"\n"
            f.write(prefix + line.encode("utf-8") + b"\n")
            f.flush()
            os.fsync(f.fileno())
        if new_file:
            _fsync_dir(self.path.parent)


def read_run_log(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Every readable record of a run log, in file order (a missing file is an empty log)."""
    path = Path(path)
    if not path.is_file():
        return []
    records: list[dict[str, Any]] = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            text = line.strip()
            if not text:
                continue
            try:
                record = json.loads(text)
            except json.JSONDecodeError:
                log.warning("%s: line %d is not JSON (cut short by a crash?); ignored", path, number)
                continue
            if isinstance(record, dict):
                records.append(record)
            else:
                log.warning("%s: line %d is not a JSON object; ignored", path, number)
    return records


def final_records(records: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The records of finished attempts, in order."""
    return [dict(r) for r in records if r.get("event") == EVENT_ATTEMPT]


def interrupted_routes(records: Iterable[Mapping[str, Any]]) -> list[str]:
    """Route ids that were started but have no finished attempt (in start order)."""
    records = list(records)
    finished = {str(r.get("route_id")) for r in final_records(records)}
    out: list[str] = []
    for r in records:
        rid = str(r.get("route_id"))
        if r.get("event") == EVENT_START and rid not in finished and rid not in out:
            out.append(rid)
    return out


def unrecorded_interruptions(records: Iterable[Mapping[str, Any]]) -> list[str]:
    """Interrupted routes whose interruption has no ``interrupted`` record yet (the driver was killed outright)."""
    records = list(records)
    finished = {str(r.get("route_id")) for r in final_records(records)}
    open_starts: dict[str, None] = {}
    for r in records:
        rid = str(r.get("route_id"))
        if r.get("event") == EVENT_START and rid not in finished:
            open_starts[rid] = None
        elif r.get("event") == EVENT_INTERRUPTED:
            open_starts.pop(rid, None)
    return list(open_starts)


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
