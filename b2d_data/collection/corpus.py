"""The state of a corpus folder between collections: the lock, the fixed settings, crashed writers' temporaries,
and the reconciliation of the run log with what reached the disk before a crash.

Crash safety: clips appear atomically (the writer renames a finished temporary folder); on ``resume`` stale
temporaries are removed, the run log and the files on disk are reconciled (a clip or a route record that reached
the disk just before a crash is adopted rather than run again) and every route with a finished attempt is skipped.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import logging
import os
import re
import shutil
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from b2d_data.collection import run_log as rl
from b2d_data.collection.job import (
    FAILED_DIR,
    RESULTS_DIR,
    STATUS_CLIP,
    STATUS_ERROR,
    CollectConfig,
    move_to_failed,
    process_alive,
    recovered_result,
)
from b2d_data.collection.plan import FIXED_SETTINGS, PLANNED_ROUTES_DIR, CollectError
from b2d_data.collection.towns import (
    TOWNS_DIR,
)
from b2d_data.format.names import ClipName, ClipNameError
from b2d_data.format.version import FORMAT_FILE

log = logging.getLogger(__name__)

SETTINGS_FILE = "collect.json"
LOCK_FILE = ".b2d_collect.lock"
#: Seconds a starting collection waits for the writers of a killed one to exit.
LIVE_WRITER_WAIT = 10.0
#: Writers' temporaries: ``.<name>.tmp-<pid>-<hex>`` (clip_writer.py names them so).
_TEMP_RE = re.compile(r"^\.(?P<name>.+)\.(?:tmp|old)-(?P<pid>\d+)-[0-9a-f]+$")


@contextlib.contextmanager
def corpus_lock(
    out: Path, lock_file: str = LOCK_FILE, owner: str = "b2d-collect", error: type[Exception] = CollectError
) -> Iterator[None]:
    """Hold ``<out>/<lock_file>`` so that two runs never write one folder (released on any exit); a busy folder
    raises ``error`` naming the ``owner`` command that holds it."""
    out.mkdir(parents=True, exist_ok=True)
    with open(out / lock_file, "a+") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise error(f"another {owner} is writing {out} (it holds {out / lock_file})") from None
        try:
            yield
        finally:
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def check_settings(out: Path, settings: dict[str, Any], resume: bool) -> None:
    path = out / SETTINGS_FILE
    if resume and path.is_file():
        try:
            previous = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise CollectError(f"{path} is unreadable ({exc}); cannot check that the resume matches") from None
        changed = [k for k in FIXED_SETTINGS if k in previous and previous[k] != settings.get(k)]
        if changed:
            detail = "; ".join(f"{k}: was {previous[k]!r}, now {settings.get(k)!r}" for k in changed)
            raise CollectError(f"--resume with other settings than the collection in {out}: {detail}")
        return
    temp = path.with_name(f".{path.name}.tmp-{os.getpid()}-000000")
    temp.write_text(json.dumps(settings, indent=2), encoding="utf-8")
    os.replace(temp, path)


def remove_temporaries(out: Path) -> list[Path]:
    """Remove what crashed writers left in the corpus (clip, map, town, record and route-list temporaries)."""
    from b2d_data.writers import remove_stale_temporaries

    removed: list[Path] = []
    for folder in (out, out / TOWNS_DIR, out / RESULTS_DIR, out / FAILED_DIR, out / PLANNED_ROUTES_DIR):
        removed += remove_stale_temporaries(folder)
        # The writers' rule keeps a zombie's temporaries (a killed worker nobody reaped); they are dead too.
        for sub in (folder, folder / "maps"):
            for entry in sorted(sub.iterdir()) if sub.is_dir() else []:
                match = _TEMP_RE.match(entry.name)
                if match is None or process_alive(int(match["pid"])):
                    continue
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry, ignore_errors=True)
                else:
                    entry.unlink(missing_ok=True)
                removed.append(entry)
    return removed


def _live_temporaries(out: Path) -> list[tuple[Path, int]]:
    """Clip temporaries in the corpus whose writing process is still alive."""
    found = []
    if out.is_dir():
        for entry in out.iterdir():
            match = _TEMP_RE.match(entry.name)
            if match is not None and process_alive(int(match["pid"])):
                found.append((entry, int(match["pid"])))
    return found


def _clips_on_disk(out: Path) -> dict[str, Path]:
    """Complete clips at the top of the corpus, keyed by route id."""
    found: dict[str, Path] = {}
    if not out.is_dir():
        return found
    for entry in sorted(out.iterdir()):
        if entry.name.startswith(".") or not entry.is_dir() or not (entry / FORMAT_FILE).is_file():
            continue
        try:
            name = ClipName.parse(entry.name)
        except ClipNameError:
            continue
        found[str(name.route_id)] = entry
    return found


@dataclass
class ResumeReport:
    """What a resume found: the work kept, the work adopted from the disk, and what it threw away."""

    #: Complete clips of earlier sessions that count towards the targets.
    clips_kept: int = 0
    #: Finished attempts of earlier sessions (their routes are not run again).
    attempts_kept: int = 0
    #: Routes whose finished attempt reached results/ but not the run log, adopted now.
    adopted: list[str] = field(default_factory=list)
    #: Routes started but never finished; they run again.
    interrupted: list[str] = field(default_factory=list)
    #: Half-written temporaries removed (paths relative to the corpus).
    discarded: list[str] = field(default_factory=list)
    #: Complete clips that no attempt of the run log counts, moved to failed/ (relative paths).
    set_aside: list[str] = field(default_factory=list)

    def describe(self) -> str:
        """One paragraph for the user: kept, recovered, discarded, run again."""

        def some(items: list[str], limit: int = 3) -> str:
            shown = ", ".join(items[:limit])
            return f"{shown}, +{len(items) - limit} more" if len(items) > limit else shown

        parts = [f"kept {self.clips_kept} complete clip(s) from {self.attempts_kept} finished attempt(s)"]
        if self.adopted:
            parts.append(f"recovered {len(self.adopted)} finished route(s) from results/ ({some(self.adopted)})")
        if self.discarded:
            parts.append(f"discarded {len(self.discarded)} half-written temporary item(s) ({some(self.discarded)})")
        if self.set_aside:
            parts.append(f"moved {len(self.set_aside)} clip(s) that no attempt counts to {FAILED_DIR}/")
        if self.interrupted:
            parts.append(f"{len(self.interrupted)} interrupted route(s) run again: {some(self.interrupted)}")
        return "resume: " + "; ".join(parts)


def reconcile(out: Path, records: list[dict[str, Any]], config: CollectConfig, run_log: rl.RunLog) -> ResumeReport:
    """Adopt what reached the disk before a crash but not the run log (clips and route records); set aside every
    clip that the run log does not count."""
    report = ResumeReport()
    finals = rl.final_records(records)
    # Routes with a verdict; those whose attempts all ended in an error (a lost worker, a crash) have none.
    decided = {str(r.get("route_id")) for r in finals if r.get("status") != STATUS_ERROR}
    counted = {str(r.get("route_id")) for r in finals if r.get("status") == STATUS_CLIP}
    clips = _clips_on_disk(out)
    results_dir = out / RESULTS_DIR
    for path in sorted(results_dir.glob("*.json")) if results_dir.is_dir() else []:
        recovered = recovered_result(path)
        if recovered is None or recovered.route_id in decided:
            continue
        clip_dir = clips.get(recovered.route_id)
        if recovered.success:
            if config.sensors and clip_dir is None:
                continue  # killed between the record and the clip: run the route again
            recovered.clip_path = clip_dir.name if clip_dir is not None else None
            counted.add(recovered.route_id)
        elif clip_dir is not None:
            # Killed between closing a failed clip and moving it (keep_failed): finish the move.
            recovered.clip_path = move_to_failed(out, clip_dir.name)
        log.info("adopting the finished attempt of route %s from %s", recovered.route_id, path)
        run_log.append(recovered.to_record())
        records.append(recovered.to_record())
        decided.add(recovered.route_id)
        report.adopted.append(recovered.route_id)
    for route_id, clip_dir in clips.items():
        if route_id not in counted and clip_dir.is_dir():
            # A complete clip that no attempt counts (no record, or a crash record written over it by an older
            # version's retry) cannot be vouched for: keep it aside, never count it.
            log.warning("clip %s is not counted by the run log; moving it to %s/", clip_dir.name, FAILED_DIR)
            report.set_aside.append(move_to_failed(out, clip_dir.name))
    return report


def record_discarded(run_log: rl.RunLog, records: list[dict[str, Any]], out: Path, removed: list[Path]) -> list[str]:
    """Append a ``discarded`` record for each removed temporary; returns their paths relative to the corpus."""
    paths = []
    for path in removed:
        relative = str(path.relative_to(out)) if path.is_relative_to(out) else str(path)
        match = _TEMP_RE.match(path.name)
        record = {"event": rl.EVENT_DISCARDED, "path": relative, "name": match["name"] if match else path.name,
                  "reason": "half-written by a process that is gone", "time": now_iso()}  # fmt: skip
        run_log.append(record)
        records.append(record)
        paths.append(relative)
    return paths


def record_interrupted(run_log: rl.RunLog, records: list[dict[str, Any]], route_ids: list[str], detected: str) -> None:
    """Append an ``interrupted`` record for each route (``detected``: when the interruption was noticed)."""
    for route_id in route_ids:
        record = {"event": rl.EVENT_INTERRUPTED, "route_id": str(route_id), "detected": detected, "time": now_iso()}
        run_log.append(record)
        records.append(record)


def collection_of(results_file: Path) -> tuple[Path, int] | None:
    """The corpus that wrote a route-record file (``<root>/results/<file>`` beside a run log) and its number of
    routes with a finished attempt (each has its record in ``results/``); None for any other file."""
    folder = Path(results_file).resolve().parent
    root = folder.parent
    if folder.name != RESULTS_DIR or not (root / rl.LOG_FILE).is_file():
        return None
    finals = rl.final_records(rl.read_run_log(root / rl.LOG_FILE))
    return root, len({str(r.get("route_id")) for r in finals})


def now_iso() -> str:
    """The UTC time in the run log's format."""
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def prepare_corpus(out: Path, config: CollectConfig) -> list[Path]:
    """Refuse to reuse a collection folder without ``resume``; remove what dead writers left behind (returned)."""
    log_path = out / rl.LOG_FILE
    if log_path.exists() and not config.resume:
        raise CollectError(
            f"{out} already holds a collection ({rl.LOG_FILE}); pass --resume to continue it, or choose another --out"
        )
    # Leftovers of dead processes only (the lock keeps other collections out; live writers' files are kept).
    removed = remove_temporaries(out)
    # Workers of a killed collection exit within a second (exit_with_parent); never run beside one.
    deadline = time.monotonic() + LIVE_WRITER_WAIT
    while (live := _live_temporaries(out)) and time.monotonic() < deadline:
        time.sleep(0.2)
        removed += remove_temporaries(out)
    if live:
        pids = ", ".join(sorted({str(pid) for _, pid in live}))
        raise CollectError(f"process(es) {pids} still write into {out} ({live[0][0].name}); stop them first")
    if removed:
        log.info("removed %d stale temporary file(s)/folder(s)", len(removed))
    return removed
