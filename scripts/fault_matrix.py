"""Fault matrix of ``b2d-collect`` and the loaders (issue 25, audit ``spec/audits/reliability.md``), run for real.

Usage: ``PYTHONPATH=. python scripts/fault_matrix.py [--keep DIR]``. Prints one line per case (case, outcome,
clips on disk vs asked, whether the error was clear) and exits 1 if any case missed its expectation.

Every collection case is a real ``b2d-collect`` process (signals, kill -9 of the driver or of a worker, a tmpfs
that fills up) on three generated Accident routes cut to 22 m (the cut of ``tests/collection/test_collect.py``),
160x90 cameras, so a route takes seconds. Everything lives in one temporary folder, removed at the end. About 3
minutes on the 2-core machine (plus 90 s per hung driver). Moments that polling misses (a clip's rename) are caught
with inotify from a real-time watcher, which needs root (as the tmpfs of the full-disk case does).
"""

from __future__ import annotations

import argparse
import builtins
import contextlib
import gzip
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.conftest import alive, descendants, sigint_default  # noqa: E402 - the kill tests' /proc helpers

SEED = "7"
ROUTE_LENGTH = 22.0  # m kept of each route, as tests/collection/test_collect.py
TINY = ["--width", "160", "--height", "90", "--lidar-azimuth-steps", "100", "--no-progress"]
INTERRUPTED = "b2d-collect: interrupted; run the same command with --resume to finish"


@dataclass
class CaseResult:
    """One row of the matrix."""

    case: str
    ok: bool
    outcome: str
    clips: int | None = None  # complete clip folders on disk at the end (None: not a collection case)
    asked: int | None = None
    clear_error: bool | None = None  # None: no error expected


def format_table(results: list[CaseResult]) -> str:
    """The matrix as a fixed-width text table, one line per case, and a last line counting the failures."""
    rows = [("case", "result", "clips/asked", "clear error", "outcome")]
    for r in results:
        clips = "—" if r.asked is None else f"{r.clips}/{r.asked}"
        clear = "—" if r.clear_error is None else ("yes" if r.clear_error else "no")
        rows.append((r.case, "ok" if r.ok else "FAIL", clips, clear, r.outcome))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row[:4], widths)) + "  " + row[4] for row in rows]
    failed = sum(not r.ok for r in results)
    lines.append(f"{len(results) - failed} of {len(results)} cases held" + (f"; {failed} FAILED" if failed else ""))
    return "\n".join(line.rstrip() for line in lines)


class Matrix:
    """The shared town, routes and scratch folders of one run of the matrix."""

    def __init__(self, work: Path) -> None:
        self.work = work
        self.tmp = work / "t"  # TMPDIR of every collection: short, for the fork server's socket path
        self.tmp.mkdir()
        self.xodr, self.routes = _short_routes(work / "town")
        self.maps: Path | None = None  # an HD-map folder to seed each --out with (its export takes seconds)
        self.env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", TMPDIR=str(self.tmp))

    def args(self, out: Path, n: int, *extra: str, routes: Path | None = None) -> list[str]:
        routes = routes or self.routes
        return [sys.executable, "-m", "b2d_data.cli.collect", "--routes", str(routes), "--xodr", str(self.xodr),
                "--scenario", "Accident", "--n", str(n), "--seed", SEED, "--workers", "2", *TINY, "--out", str(out),
                *extra]  # fmt: skip

    def fresh(self, name: str) -> Path:
        out = self.work / name
        out.mkdir()
        if self.maps is not None:
            shutil.copytree(self.maps, out / "maps")
        return out

    def start(self, args: list[str], log: Path, *, sigint: bool = False) -> subprocess.Popen:
        with open(log, "wb") as stream:
            return subprocess.Popen(args, env=self.env, stdout=stream, stderr=subprocess.STDOUT,
                                    start_new_session=True, preexec_fn=sigint_default if sigint else None)  # fmt: skip

    def run(self, args: list[str], timeout: float = 180) -> tuple[int, str]:
        try:
            done = subprocess.run(args, env=self.env, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return -1, f"timed out after {timeout:.0f} s"
        return done.returncode, done.stdout + done.stderr


def _short_routes(folder: Path) -> tuple[Path, Path]:
    """(Town100.xodr, a route file of 3 Accident routes cut to ROUTE_LENGTH m)."""
    from b2d_data.collection.towns import TownSource, load_map
    from b2d_data.scenarios import placement
    from b2d_data.scenarios.route_xml import write_routes

    folder.mkdir()
    town = TownSource(preset="all").materialise(folder)
    world_map = load_map(town)
    short = []
    for route in placement.make_routes(world_map, "Accident", 3, seed=0, params="bench2drive220"):
        s = route.waypoints[0]
        short.append(replace(route, waypoints=tuple(p for p in route.waypoints
                                                    if math.hypot(p.x - s.x, p.y - s.y) <= ROUTE_LENGTH)))  # fmt: skip
    path = folder / "short_accident.xml"
    write_routes(short, path)
    # Route 1 cut to 12 m (the shortest that keeps its trigger point), so that its worker is idle for seconds while
    # route 2 runs (the idle-worker case).
    s = short[0].waypoints[0]
    first = replace(short[0], waypoints=tuple(p for p in short[0].waypoints
                                              if math.hypot(p.x - s.x, p.y - s.y) <= 12.0))  # fmt: skip
    write_routes([first, *short[1:]], folder / "uneven_accident.xml")
    return Path(town.xodr), path


def clips(out: Path) -> list[Path]:
    """Complete clip folders directly under ``out``."""
    if not out.is_dir():
        return []
    return sorted(p for p in out.iterdir() if not p.name.startswith(".") and (p / "b2d_format.json").is_file())


def temporaries(out: Path) -> list[Path]:
    return [p for p in out.rglob(".*") if ".tmp-" in p.name or ".old-" in p.name] if out.is_dir() else []


def writing(out: Path, frames: int = 3) -> list[Path]:
    """Half-written clips (writer temporaries) holding at least ``frames`` annotations."""
    return [p for p in out.glob(".*.tmp-*") if p.is_dir() and len(list(p.glob("anno/*.json.gz"))) >= frames]


def writer_pid(temp: Path) -> int:
    """The worker writing a clip temporary ``.<clip>.tmp-<pid>-<hex>``."""
    return int(temp.name.rsplit(".tmp-", 1)[1].split("-")[0])


def wait_for(proc: subprocess.Popen, cond: Callable[[], object], timeout: float = 120, step: float = 0.02):
    """Poll ``cond`` until it is truthy (returned) or the process ends or time runs out (None)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        value = cond()
        if value:
            return value
        time.sleep(step)
    return None


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def all_exit(pids: set[int], timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    return not any(alive(p) for p in pids)


def finish_with_resume(m: Matrix, out: Path, n: int, case: str, before: str, clear: bool) -> CaseResult:
    """Run ``--resume`` and judge: exactly n clips, no temporary left, the resume says what it kept."""
    rc, text = m.run(m.args(out, n, "--resume"))
    got = len(clips(out))
    ok = rc == 0 and got == n and not temporaries(out) and clear and "resume: kept" in text
    return CaseResult(case, ok, f"{before}; --resume rc {rc}", got, n, clear and "resume: kept" in text)


def case_kill_driver(m: Matrix, name: str, n: int, clips_first: int) -> CaseResult:
    out = m.fresh(name)
    proc = m.start(m.args(out, n), m.work / f"{name}.log")
    helpers: set[int] = set()

    def moment():
        helpers.update(descendants(proc.pid))
        return len(clips(out)) >= clips_first and writing(out)

    try:
        hit = wait_for(proc, moment)
        helpers.update(descendants(proc.pid))
        if not hit:
            return CaseResult(name, False, f"ended (rc {proc.poll()}) before the kill", len(clips(out)), n)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        stop(proc)
    gone = all_exit(helpers)
    before = f"killed with {len(clips(out))} clip(s) + {len(writing(out, 0))} half; helpers gone: {gone}"
    result = finish_with_resume(m, out, n, name, before, clear=True)
    result.ok = result.ok and gone
    return result


class _Renames:
    """Linux inotify on one folder: wakes the moment an entry is renamed into it (the worker's clip rename), which
    polling misses (the result reaches the driver within a millisecond after)."""

    IN_MOVED_TO = 0x80

    def __init__(self, folder: Path) -> None:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        self.fd = libc.inotify_init1(os.O_NONBLOCK)
        if self.fd < 0 or libc.inotify_add_watch(self.fd, bytes(folder), self.IN_MOVED_TO) < 0:
            raise OSError(ctypes.get_errno(), "inotify")

    def wait(self, timeout: float) -> bool:
        """Whether a rename into the folder happened within ``timeout`` seconds."""
        import select

        ready, _, _ = select.select([self.fd], [], [], timeout)
        return bool(ready)

    def close(self) -> None:
        os.close(self.fd)


@contextlib.contextmanager
def _realtime():
    """This process under the real-time FIFO scheduler while inside (root only; else as it is)."""
    before = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
    except OSError:
        pass
    try:
        yield
    finally:
        try:
            os.sched_setscheduler(0, before[0], before[1])
        except OSError:
            pass


def _kill(pid: int) -> bool:
    """kill -9 of ``pid``; False when it has already gone (the moment passed)."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        return False
    return True


def case_kill_worker(m: Matrix, name: str, n: int, when: str) -> CaseResult:
    """kill -9 of a worker: mid-route, the moment its clip is renamed into place, once idle, or once idle at the
    moment the busy worker renames its clip."""
    out = m.fresh(name)
    uneven = m.routes.with_name("uneven_accident.xml") if when.startswith("idle") else None
    proc = m.start(m.args(out, n, routes=uneven), m.work / f"{name}.log")
    seen: dict[str, int] = {}  # clip name -> pid of the worker writing it

    def moment():
        for temp in writing(out, 0):
            seen[temp.name[1:].split(".tmp-")[0]] = writer_pid(temp)
        if when == "mid-route":
            busy = writing(out)
            return writer_pid(busy[0]) if busy else None
        done = [c.name for c in clips(out) if c.name in seen]
        if when == "after-rename" and done:
            return seen[done[0]]
        if when.startswith("idle") and done and writing(out):  # its route is over, the other worker's still runs
            time.sleep(0.3)  # back in the pool's queue
            return seen[done[0]]
        return None

    try:
        if when == "idle-as-other-finishes":  # the idle worker, killed as the busy one renames its clip
            idle = wait_for(proc, lambda: moment() and [c.name for c in clips(out)])
            renames = _Renames(out)
            with _realtime():
                pid = seen[idle[0]] if idle and renames.wait(120) else None
                pid = pid if pid and _kill(pid) else None
            renames.close()
        elif when == "after-rename":  # the one worker writing the one clip, killed as its rename lands
            temp = wait_for(proc, lambda: writing(out, 1))
            renames = _Renames(out)
            with _realtime():  # woken ahead of the busy workers: the result is on its way within a millisecond
                pid = writer_pid(temp[0]) if temp and renames.wait(120) else None
                pid = pid if pid and _kill(pid) else None
            renames.close()
        else:
            pid = wait_for(proc, moment, step=0.005)
            pid = pid if pid and _kill(pid) else None
        if not pid:
            stop(proc)
            return CaseResult(name, False, f"ended (rc {proc.poll()}) before the kill", len(clips(out)), n)
        try:
            rc = proc.wait(timeout=90)  # the lost route run again: ~20 s
        except subprocess.TimeoutExpired:
            rc = None
    finally:
        stop(proc)
    text = (m.work / f"{name}.log").read_text()
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").is_file() else {}
    lost = summary.get("lost_this_run", 0)
    got = len(clips(out))
    outcome = "driver hung (killed after 90 s)" if rc is None else f"rc {rc}, {lost} attempt(s) counted lost"
    if when == "after-rename":  # did the kill land between the rename and the result reaching the driver?
        log = (out / "run_log.jsonl").read_text() if (out / "run_log.jsonl").is_file() else ""
        outcome += ", clip adopted by the retry" if "adopted the complete clip" in log else ", result had arrived"
    clear = "worker" in text and "Traceback" not in text
    ok = rc == 0 and got == n and not temporaries(out) and summary.get("complete") is True
    return CaseResult(name, ok, outcome, got, n, clear if lost else None)


def case_two_collections(m: Matrix) -> CaseResult:
    name = "two-collections-one-out"
    out = m.fresh(name)
    link = m.work / f"{name}-link"
    link.symlink_to(out)
    proc = m.start(m.args(out, 2), m.work / f"{name}.log")
    try:
        if not wait_for(proc, lambda: (out / "run_log.jsonl").is_file()):
            return CaseResult(name, False, "first run ended early", len(clips(out)), 2)
        # A plain second run is refused on the used folder, a --resume one (also through a symlink) on the lock.
        second = [m.run(m.args(out, 2)), m.run(m.args(out, 2, "--resume")), m.run(m.args(link, 2, "--resume"))]
        rc = proc.wait(timeout=180)
    finally:
        stop(proc)
    refused = [r for r, text in second if r == 2 and ("another b2d-collect is writing" in text
                                                      or "already holds a collection" in text)]  # fmt: skip
    got = len(clips(out))
    ok = len(refused) == 3 and rc == 0 and got == 2
    outcome = f"{len(refused)}/3 second runs refused (rc 2); first rc {rc}"
    return CaseResult(name, ok, outcome, got, 2, len(refused) == 3)


def case_disk_full(m: Matrix) -> CaseResult:
    """A real tmpfs a little larger than the HD map: the first routes hit ENOSPC; remounted larger, --resume."""
    name = "disk-full-then-resume"
    mount = m.work / name
    mount.mkdir()
    maps_bytes = sum(p.stat().st_size for p in (m.maps or mount).rglob("*") if p.is_file())
    size = maps_bytes + (3 << 20)
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mount)],
                      capture_output=True).returncode != 0:  # fmt: skip
        return CaseResult(name, False, "cannot mount a tmpfs (needs root)", None, None)
    try:
        out = mount / "corpus"
        out.mkdir()
        if m.maps is not None:
            shutil.copytree(m.maps, out / "maps")
        rc, text = m.run(m.args(out, 2))
        half = temporaries(out)
        said = "need about" in text and "attempts-per-clip" not in text and "Traceback" not in text
        first = f"full: rc {rc}, {len(clips(out))} clip(s), {len(half)} temporaries"
        subprocess.run(["mount", "-o", "remount,size=256m", str(mount)], check=True)
        result = finish_with_resume(m, out, 2, name, first, clear=said)
        result.ok = result.ok and rc == 1 and not half
        return result
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def case_signal(m: Matrix, name: str, group_sigint: bool) -> CaseResult:
    out = m.fresh(name)
    log = m.work / f"{name}.log"
    proc = m.start(m.args(out, 2), log, sigint=group_sigint)
    helpers: set[int] = set()
    try:
        hit = wait_for(proc, lambda: helpers.update(descendants(proc.pid)) or writing(out))
        helpers.update(descendants(proc.pid))
        if not hit:
            return CaseResult(name, False, "ended before the signal", len(clips(out)), 2)
        t0 = time.monotonic()
        if group_sigint:
            os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C reaches the terminal's whole process group
        else:
            os.kill(proc.pid, signal.SIGTERM)
        try:
            rc = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            rc = None
        took = time.monotonic() - t0
    finally:
        stop(proc)
    gone = all_exit(helpers)
    text = log.read_text()
    clear = text.strip().splitlines()[-1:] == [INTERRUPTED] and "Traceback" not in text
    before = f"rc {rc} after {took:.1f} s, helpers gone: {gone}"
    result = finish_with_resume(m, out, 2, name, before, clear)
    result.ok = result.ok and rc == 130 and gone
    return result


def case_same_seed(m: Matrix) -> CaseResult:
    """The same command twice (one worker each, side by side): every sensor file and annotation identical."""
    name = "same-seed-twice"
    outs = [m.fresh(f"{name}-{i}") for i in (1, 2)]
    procs = [m.start([*m.args(o, 1), "--workers", "1"], m.work / f"{o.name}.log") for o in outs]
    rcs = [p.wait(timeout=300) for p in procs]
    differ = []
    a, b = (clips(o)[0] if clips(o) else o for o in outs)
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and p.name != "b2d_format.json")
    for rel in files:
        x, y = a / rel, b / rel
        if not y.is_file():
            differ.append(str(rel))
        elif rel.suffix == ".gz":  # gzip headers hold a time; the content must match
            if gzip.decompress(x.read_bytes()) != gzip.decompress(y.read_bytes()):
                differ.append(str(rel))
        elif x.read_bytes() != y.read_bytes():
            differ.append(str(rel))
    got = min(len(clips(o)) for o in outs)
    ok = rcs == [0, 0] and got == 1 and a.name == b.name and files and not differ
    return CaseResult(name, ok, f"{len(files) - len(differ)}/{len(files)} files identical (annotations gunzipped)",
                      got, 1)


def case_verify(m: Matrix, clip: Path) -> CaseResult:
    from b2d_data.writers.archive import pack_clip

    name = "b2d-verify-flipped-bit"
    root = m.work / "verify"
    root.mkdir()
    info = pack_clip(clip, root)
    archive = root / f"{clip.name}.tar.gz"
    listing = root / "list.json"
    listing.write_text(json.dumps({archive.name: {"sha256": info.sha256, "size": info.size}}))
    verify = [sys.executable, "-m", "b2d_data.cli.verify", str(root), "--list", str(listing), "--no-progress"]
    rc_good, _ = m.run(verify)
    data = bytearray(archive.read_bytes())
    data[len(data) // 2] ^= 0x10
    archive.write_bytes(bytes(data))
    rc_flip, text_flip = m.run(verify)
    archive.write_bytes(bytes(data[: len(data) // 3]))
    rc_cut, text_cut = m.run(verify)
    clear = "SHA256" in text_flip and archive.name in text_flip and "SIZE" in text_cut
    ok = (rc_good, rc_flip, rc_cut) == (0, 1, 1) and clear
    return CaseResult(name, ok, f"intact rc {rc_good}, flipped bit rc {rc_flip}, truncated rc {rc_cut}", None, None,
                      clear)  # fmt: skip


class _RunsCode:
    """Pickles as a call of ``func(*args)``: what a malicious HD map would hold."""

    def __init__(self, func, *args) -> None:
        self.func, self.args = func, args

    def __reduce__(self):
        return self.func, self.args


def case_loaders(m: Matrix, corpus: Path) -> list[CaseResult]:
    """Corrupt, stray, oversized and hostile files under a copy of one clip."""
    import numpy as np
    from torch.utils.data import DataLoader

    from b2d_data import ClipDataset
    from b2d_data.codecs import layout
    from b2d_data.format.errors import B2DFormatError

    source = clips(corpus)[0]
    root = m.work / "loaders"
    clip = root / source.name
    shutil.copytree(source, clip)
    frames = len(list((clip / "anno").glob("*.json.gz")))
    results = []

    # Stray files: an annotation far beyond the clip's end and foreign files (audit 4, issue item 5).
    layout.anno_path(clip, 99999).write_bytes(layout.anno_path(clip, 0).read_bytes())
    (clip / "notes.txt").write_text("x")
    (clip / "anno" / ".DS_Store").write_bytes(b"\0")
    n = len(ClipDataset(root, cameras=("front",)))
    results.append(CaseResult("loader-stray-files", n == frames, f"{n} frames indexed for {frames} on disk"))

    # Corrupt files: each error names its file; skip mode works with torch's default collate (items 8).
    bad = {2: "camera/rgb_front/00002.jpg", 3: "lidar/00003.laz", 4: "anno/00004.json.gz"}
    jpg = layout.image_path(clip, "rgb", "front", 2)
    jpg.write_bytes(jpg.read_bytes()[: jpg.stat().st_size // 2])
    layout.lidar_path(clip, 3).write_bytes(b"LASF" + bytes(range(200)))
    layout.anno_path(clip, 4).write_bytes(b"\x1f\x8b\x08\x00garbage, not deflate")
    ds = ClipDataset(root, cameras=("front",))
    named = 0
    for frame, rel in bad.items():
        try:
            ds[frame]
        except B2DFormatError as exc:
            named += rel in str(exc) and clip.name in str(exc)
    skip = ClipDataset(root, cameras=("front",), on_error="skip")
    try:
        batches = list(DataLoader(skip, batch_size=4, num_workers=2))
        loaded, skipped = sum(b["batch_size"] for b in batches), sum(b["skipped"] for b in batches)
    except Exception as exc:  # noqa: BLE001 - the outcome is the row
        loaded, skipped = -1, f"{type(exc).__name__}"
    ok = named == 3 and (loaded, skipped) == (frames - 3, 3)
    results.append(CaseResult("loader-corrupt-files", ok, f"{named}/3 errors name the file; skip+default collate: "
                              f"{loaded} loaded, {skipped} skipped", clear_error=named == 3))  # fmt: skip

    # A gzip bomb: 100 MB of spaces in a 100 kB annotation (item 9).
    from b2d_data.codecs import anno_json

    bomb = layout.anno_path(clip, 5)
    bomb.write_bytes(gzip.compress(b"{" + b" " * (100 << 20) + b"}"))
    old_cap, anno_json.MAX_ANNO_BYTES = anno_json.MAX_ANNO_BYTES, 16 << 20
    try:
        ds[5]
        text = "read without a limit"
    except B2DFormatError as exc:
        text = str(exc)
    finally:
        anno_json.MAX_ANNO_BYTES = old_cap
    capped = "00005.json.gz" in text and text != "read without a limit"
    results.append(CaseResult("loader-gzip-bomb", capped, f"{bomb.stat().st_size // 1000} kB -> 100 MB refused at a "
                              "16 MB cap" if capped else text[:80], clear_error=capped))  # fmt: skip

    # A hostile HD map in the corpus (item 1): refused, nothing executed.
    marker = m.work / "pwned"
    (root / "maps").mkdir()
    town = source.name.split("_")[1]
    arr = np.empty((1, 2), dtype=object)
    arr[0, 0], arr[0, 1] = 1, {-1: [_RunsCode(builtins.exec, f"open({str(marker)!r}, 'w').close()")]}
    np.savez_compressed(root / "maps" / f"{town}_HD_map.npz", arr=arr)
    try:
        ClipDataset(root, clips=[source.name], cameras=(), lidar=False, map_radius=20.0)[0]
        text = "loaded"
    except B2DFormatError as exc:
        text = str(exc)
    refused = "refused to unpickle" in text and not marker.exists()
    results.append(CaseResult("loader-hostile-hd-map", refused, f"code ran: {marker.exists()}; "
                              + ("refused to unpickle builtins.exec" if refused else text[:80]), clear_error=refused))
    return results


def case_bad_inputs(m: Matrix) -> list[CaseResult]:
    """Malformed route XML and xodr, hostile names: one line, rc 2, nothing written outside --out."""
    folder = m.work / "inputs"
    folder.mkdir()
    (folder / "bad.xml").write_text('<routes><route id="1" town="Town100"')
    (folder / "Town200.xodr").write_bytes(os.urandom(2000))
    route = ("<routes><route id='24211' town='{town}'><waypoints><position x='0' y='0' z='0'/></waypoints><scenarios>"
             "<scenario name='Accident_1' type='{type}'><trigger_point x='0' y='0' z='0' yaw='0'/></scenario>"
             "</scenarios></route></routes>")  # fmt: skip
    (folder / "evil_type.xml").write_text(route.format(town="Town01", type="../../evil"))
    (folder / "evil_town.xml").write_text(route.format(town="../Town200", type="Accident"))
    base = [sys.executable, "-m", "b2d_data.cli.collect", *TINY]
    cases = {
        "malformed-route-xml": ["--routes", str(folder / "bad.xml"), "--xodr", str(m.xodr)],
        "malformed-xodr": ["--xodr", str(folder / "Town200.xodr"), "--scenario", "Accident"],
        "hostile-scenario-type": ["--routes", str(folder / "evil_type.xml")],
        "hostile-route-town": ["--routes", str(folder / "evil_town.xml"), "--xodr", str(folder)],
        "hostile-scenario-arg": ["--scenario", "Acc;rm -rf x", "--scenario", "../../etc"],
    }
    results = []
    for case, extra in cases.items():
        out = folder / "deep" / "er" / case
        before = set(folder.rglob("*"))
        rc, text = m.run([*base, *extra, "--out", str(out)], timeout=60)
        lines = text.strip().splitlines()
        one_line = len(lines) == 1 and lines[0].startswith("b2d-collect: error:") and "Traceback" not in text
        escaped = [p.name for p in set(folder.rglob("*")) - before if p.is_file() and out not in p.parents]
        ok = rc == 2 and one_line and not escaped
        said = (lines[-1] if lines else "").removeprefix("b2d-collect: error: ").replace(f"{folder}/", "")
        results.append(CaseResult(case, ok, f"rc {rc}: {said[:100]}", clear_error=one_line))
    return results


#: A kill case whose collection ended before the kill's moment came is run again this many times in all.
KILL_TRIES = 3


def kill_worker_case(m: Matrix, name: str, n: int, when: str) -> CaseResult:
    """:func:`case_kill_worker`, run again (in a fresh folder) while the run ends before its kill's moment: the
    moment (a sibling's rename) can come after the last route has started and pass unseen."""
    for k in range(KILL_TRIES):
        result = case_kill_worker(m, name if k == 0 else f"{name}-{k + 1}", n, when)
        if not result.outcome.startswith("ended (rc"):
            break
    return replace(result, case=name, outcome=result.outcome + (f" (try {k + 1})" if k else ""))


def run_matrix(work: Path, only: str | None = None) -> list[CaseResult]:
    """Every case (or those whose name holds ``only``), in an order that lets later ones reuse earlier outputs."""
    m = Matrix(work)
    results: list[CaseResult] = []
    base = work / "two-collections-one-out"
    cases: list[tuple[str, Callable[[], CaseResult | list[CaseResult]]]] = [
        ("kill-9-driver-mid-route", lambda: case_kill_driver(m, "kill-9-driver-mid-route", 2, clips_first=0)),
        ("kill-9-driver-after-1st-clip", lambda: case_kill_driver(m, "kill-9-driver-after-1st-clip", 3, 1)),
        ("kill-9-worker-mid-route", lambda: kill_worker_case(m, "kill-9-worker-mid-route", 2, "mid-route")),
        ("kill-9-worker-after-rename", lambda: kill_worker_case(m, "kill-9-worker-after-rename", 1, "after-rename")),
        ("kill-9-idle-worker", lambda: kill_worker_case(m, "kill-9-idle-worker", 2, "idle")),
        ("kill-9-idle-worker-as-other-ends", lambda: kill_worker_case(m, "kill-9-idle-worker-as-other-ends", 2,
                                                                      "idle-as-other-finishes")),
        ("disk-full-then-resume", lambda: case_disk_full(m)),
        ("sigint-process-group", lambda: case_signal(m, "sigint-process-group", group_sigint=True)),
        ("sigterm-driver", lambda: case_signal(m, "sigterm-driver", group_sigint=False)),
        ("same-seed-twice", lambda: case_same_seed(m)),
        ("b2d-verify-flipped-bit", lambda: case_verify(m, clips(base)[0])),
        ("loader-*", lambda: case_loaders(m, base)),
        ("malformed-* hostile-*", lambda: case_bad_inputs(m)),
    ]

    def add(result: CaseResult | list[CaseResult]) -> None:
        for r in result if isinstance(result, list) else [result]:
            results.append(r)
            print(format_table([r]).splitlines()[1], flush=True)

    add(case_two_collections(m))  # also exports the HD map, then shared by the later --out folders
    m.maps = base / "maps"
    for name, run in cases:
        if only is None or only in name:
            add(run())
    leftovers = [p.name for p in m.tmp.iterdir()]
    add(CaseResult("no-temp-folder-left", not leftovers, f"TMPDIR entries left by all runs: {leftovers or 'none'}"))
    return results


def main(argv: list[str] | None = None) -> int:
    """Run the matrix; 1 if any case missed its expectation."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", type=Path, help="work in this (new) folder and keep it, for inspection")
    parser.add_argument("--only", help="run only the cases whose name holds this text (and the first, which the "
                        "others build on)")  # fmt: skip
    args = parser.parse_args(argv)
    work = args.keep or Path(tempfile.mkdtemp(prefix="b2dfm", dir="/tmp"))  # short: fork-server socket path
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    try:
        print("  ".join(["case", "result", "clips/asked", "clear error", "outcome"]), flush=True)
        results = run_matrix(work, args.only)
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    print()
    print(format_table(results))
    print(f"wall time {time.monotonic() - t0:.0f} s")
    return 1 if any(not r.ok for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
