"""A killed ``b2d-collect`` leaves no temporary folder behind.

multiprocessing keeps its fork server's socket in a ``pymp-*`` folder of the temporary directory and removes it at a
normal exit only; every killed driver (or worker with encoders) left one. The CLI therefore sends its temporary
files, and its children's, into one folder per run, ``<tmp>/b2d-collect-<pid>-<random>``, removed at exit; a run
starting removes the folders whose driver is gone. Nothing else in the temporary directory is touched.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing.util
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from b2d_data.collection.job import process_alive

log = logging.getLogger(__name__)

PREFIX = "b2d-collect-"
#: Longest socket path every platform takes (macOS: 104 bytes with the final NUL; Linux: 108).
MAX_SOCKET_PATH = 103
#: What multiprocessing adds to the folder for its fork server's socket: ``/pymp-XXXXXXXX/listener-XXXXXXXX``.
_SOCKET_SUFFIX = len("/pymp-12345678/listener-12345678")
_NAME_RE = re.compile(rf"^{re.escape(PREFIX)}(?P<pid>\d+)-[A-Za-z0-9_]+$")
#: This process's folder (made once; the process's exit removes it).
_folder: Path | None = None


def remove_stale(parent: Path) -> list[Path]:
    """Remove the run folders in ``parent`` that belong to this user and whose driver process is gone."""
    removed = []
    for entry in sorted(parent.iterdir()) if parent.is_dir() else []:
        match = _NAME_RE.match(entry.name)
        if match is None:
            continue
        try:
            info = entry.lstat()
        except OSError:
            continue
        if not entry.is_dir() or entry.is_symlink() or info.st_uid != os.getuid() or process_alive(int(match["pid"])):
            continue
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry)
    if removed:
        log.info("removed %d temporary folder(s) of killed collections from %s", len(removed), parent)
    return removed


@contextlib.contextmanager
def private_temp_dir() -> Iterator[Path]:
    """Within the block, this process's temporary files and those of the processes it starts (multiprocessing's
    fork server and pool workers) go to a folder of this run, which the process's exit removes."""
    global _folder
    if _folder is None:
        parent = Path(tempfile.gettempdir())
        remove_stale(parent)
        prefix = f"{PREFIX}{os.getpid()}-"
        if len(os.fsencode(parent / prefix)) + 8 + _SOCKET_SUFFIX > MAX_SOCKET_PATH:
            # The fork server could not bind its socket there: keep multiprocessing's own folders (as before).
            log.debug("temporary folder %s too long for a private run folder", parent)
            yield parent
            return
        _folder = Path(tempfile.mkdtemp(prefix=prefix, dir=parent))
        # After multiprocessing removes its own pymp-* folder inside (its finalizer has priority -100).
        multiprocessing.util.Finalize(
            None, shutil.rmtree, args=(str(_folder),), kwargs={"ignore_errors": True}, exitpriority=-200
        )
    previous_env, previous_tempdir = os.environ.get("TMPDIR"), tempfile.tempdir
    # The environment reaches the fork server, which multiprocessing starts with a fresh interpreter.
    os.environ["TMPDIR"] = tempfile.tempdir = str(_folder)
    try:
        yield _folder
    finally:
        tempfile.tempdir = previous_tempdir
        if previous_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = previous_env
