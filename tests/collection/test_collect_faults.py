"""``b2d-collect`` under faults (issue 25): a worker lost after renaming its clip, a killed idle worker, lost
attempts in the summary, a full disk, multiprocessing's temporary folders of killed drivers.

Routes are the short Accident routes of ``test_collect.py`` at a tiny resolution; the worker-death cases that need an
exact moment (1 ms after a rename) are staged: the route really runs, then the driver is told its worker died.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from b2d_data.cli.collect import main
from b2d_data.collection import run_log as rl
from b2d_data.collection.backends import WORKER_LOST, InlineBackend, error_result
from b2d_data.collection.job import ADOPTED, CollectConfig, write_route_results
from b2d_data.format import leaderboard as lb

from ..conftest import alive, assert_all_exit, descendants
from .test_collect import _args, _clips, short_routes  # noqa: F401 - fixture


class _LostAfterRename:
    """Runs routes in this process, but the first attempt's worker "dies" right after renaming its clip: the clip
    and its success record are on disk, and the driver hears only that the worker was lost."""
    capacity = 1

    def __init__(self, out: Path, config: CollectConfig, on_frames=None) -> None:
        self.inner = InlineBackend(out, config, on_frames)
        self.lost = False

    def submit(self, task) -> None:
        self.inner.submit(task)

    def running(self) -> int:
        return self.inner.running()

    def wait(self, timeout=None):
        done = self.inner.wait(timeout)
        if not self.lost:
            self.lost = True
            assert [r.status for _, r in done] == ["clip"], "the staged route must succeed"
            return [(task, error_result(task, "worker process died (killed or crashed)")) for task, _ in done]
        return done

    def close(self, abandon: bool = False) -> None:
        self.inner.close(abandon)


def test_the_retry_of_a_route_whose_lost_worker_renamed_its_clip_adopts_it(short_routes, tmp_path, monkeypatch, capsys):  # noqa: F811, E501
    """Audit case 1g: before the fix the retry failed on the existing folder, wrote 'Simulation crashed' over the
    clip's record and a second route was collected: two clips for ``--n 1``."""
    import b2d_data.collection.runner as runner

    monkeypatch.setattr(runner, "make_backend", _LostAfterRename)
    out = tmp_path / "data"
    args = _args(short_routes, out)
    args[args.index("--n") + 1] = "1"
    assert main(args) == 0

    records = rl.read_run_log(out / rl.LOG_FILE)
    finals = rl.final_records(records)
    first = finals[0]["route_id"]
    # One route, run twice (the lost attempt and its retry); the third route of the file is never started.
    assert [r["route_id"] for r in records if r["event"] == rl.EVENT_START] == [first, first]
    assert [(r["route_id"], r["status"], r["note"]) for r in finals] == [
        (first, "error", WORKER_LOST),
        (first, "clip", ADOPTED),
    ]
    clip = finals[1]["clip"]
    assert [p.name for p in _clips(out)] == [clip]  # n = 1: exactly one clip folder
    assert finals[1]["clip_path"] == clip and finals[1]["frames"] == len(list((out / clip / "anno").iterdir()))
    record = lb.read_results(out / "results" / f"{clip}.json").records[0]
    assert record.status == "Completed" and record.extra["b2d_collect"]["success"] is True
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenarios"][0]["clips"] == 1 and summary["complete"] is True
    # The lost attempt is no verdict on the route: 1 attempt (the adopted clip), 1 lost, 100 %.
    assert [summary["scenarios"][0][k] for k in ("attempts", "lost", "success_rate")] == [1, 1, 1.0]
    assert (summary["attempts_this_run"], summary["lost_this_run"]) == (1, 1)
    assert "1 clips from 1 attempts (+1 lost) in" in capsys.readouterr().out


def _finished(out: Path, route_id: int, success: bool | None, clip_on_disk: bool) -> str:
    """A route's record (``success`` None: the crash record of a failed job) and optionally its complete clip."""
    name = f"Accident_Town100_Route{route_id}_Weather3"
    status = "Failed - Simulation crashed" if success is None else "Completed" if success else "Failed"
    record = lb.RouteRecord(route_id=lb.record_route_id(route_id), status=status, town_name="Town100", index=0)
    if success is not None:
        record.extra["b2d_collect"] = {"seed": 11, "clip": name, "success": success}
    write_route_results(out, name, record)
    if clip_on_disk:
        (out / name / "anno").mkdir(parents=True)
        (out / name / "b2d_format.json").write_text("{}")
    return name


def _attempt(route_id: int, status: str, note: str = "") -> dict:
    return {"event": "attempt", "route_id": str(route_id), "status": status, "note": note,
            "clip": f"Accident_Town100_Route{route_id}_Weather3"}  # fmt: skip


@pytest.mark.parametrize("case", ["older version's duplicate", "driver killed before the retry"])
def test_resume_counts_every_clip_it_keeps(tmp_path, case):
    """A clip that only error attempts speak of is adopted when its success record is there, else set aside."""
    from b2d_data.collection.corpus import reconcile

    out = tmp_path / "data"
    log = rl.RunLog(out / rl.LOG_FILE)
    if case == "older version's duplicate":
        # What 1g left: route 1's clip under a crash record, logged as two errors; route 2 collected instead.
        lost = _finished(out, 1, None, clip_on_disk=True)
        kept = _finished(out, 2, True, clip_on_disk=True)
        records = [_attempt(1, "error", WORKER_LOST), _attempt(1, "error"), _attempt(2, "clip")]
    else:
        # The worker died after its rename and the driver was killed before the retry finished.
        kept = _finished(out, 1, True, clip_on_disk=True)
        records = [_attempt(1, "error", WORKER_LOST), {"event": "start", "route_id": "1"}]
    for r in records:
        log.append(r)
    report = reconcile(out, records, CollectConfig(out=out), log)

    finals = rl.final_records(rl.read_run_log(log.path))
    clip_routes = [r["route_id"] for r in finals if r["status"] == "clip"]
    if case == "older version's duplicate":
        assert report.set_aside == [f"failed/{lost}"] and not (out / lost).exists()
        assert clip_routes == ["2"] and report.adopted == []
    else:
        assert report.set_aside == [] and report.adopted == ["1"]
        assert clip_routes == ["1"]
    assert [p.name for p in _clips(out)] == [kept]  # every clip left in place is counted once


_NAPS = '''
import os, time
from pathlib import Path
from b2d_data.collection.job import JobResult


def nap(route, town, out, config, seed):
    """Stand-in route job: route 1 returns once route 2 runs (so two workers hold one task each), route 2 sleeps."""
    (Path(out) / f"started-{route.id}").write_text(str(os.getpid()))
    deadline = time.monotonic() + 30
    while route.id == "1" and not (Path(out) / "started-2").exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(route.seconds)
    return JobResult(str(route.id), "Accident", town.name, 1, seed, "failed", pid=os.getpid())
'''

_KILL_IDLE_WORKER = '''
import os, signal, sys, time
from pathlib import Path
from types import SimpleNamespace

from b2d_data.collection.backends import ProcessPoolBackend
from b2d_data.collection.job import CollectConfig
from b2d_data.collection.plan import RouteTask
import naps


def main():
    out = Path(sys.argv[1])
    backend = ProcessPoolBackend(out, CollectConfig(out=out, workers=2, sensors=False), 2, job=naps.nap)
    for i, seconds in ((1, 0.0), (2, 6.0)):
        backend.submit(RouteTask(SimpleNamespace(id=str(i), seconds=seconds), SimpleNamespace(name="Town100"),
                                 "Accident", i))
    first = []
    while not first:
        first = backend.wait(timeout=1.0)
    time.sleep(0.3)  # the idle worker is back in the pool's queue, holding its read lock
    os.kill(first[0][1].pid, signal.SIGKILL)
    lost = []
    while backend.running():
        lost += [(task.route.id, result.note) for task, result in backend.wait(timeout=1.0)]
    backend.close()
    print("lost", lost, flush=True)


if __name__ == "__main__":
    main()
'''


def test_killing_an_idle_worker_does_not_hang_the_driver(tmp_path):
    """Audit case 1h: a real pool of 2 workers; worker A (idle, inside the pool's queue lock) is killed while B
    runs a 6 s task. The pool stops B with SIGTERM; before the fix B took the SystemExit for its task's error,
    went back to the queue, waited for ever on the lock A held, and the driver's exit waited for B."""
    import b2d_data

    (tmp_path / "naps.py").write_text(_NAPS)
    (tmp_path / "scenario.py").write_text(_KILL_IDLE_WORKER)
    out = tmp_path / "out"
    out.mkdir()
    repo = Path(b2d_data.__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(repo)]))
    try:
        # ~1.5 s of start-up + 0.3 s; B stops on its SIGTERM. The close() safety net (kill after 15 s) and the
        # hang both exceed 12 s.
        done = subprocess.run([sys.executable, str(tmp_path / "scenario.py"), str(out)], env=env,
                              capture_output=True, text=True, timeout=12)  # fmt: skip
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"the driver did not finish within 12 s: {exc.stdout!r} {exc.stderr!r}")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"lost [('2', '{WORKER_LOST}')]", done.stdout  # B's task came back as lost
    assert "did not stop" not in done.stderr and "leaked" not in done.stderr, done.stderr
    busy = int((out / "started-2").read_text())
    assert not alive(busy)


def test_attempts_lost_with_their_worker_are_not_route_failures(tmp_path):
    """Audit case 1d: one worker killed broke the pool; both in-flight routes were reported as errors and run
    again, and the table said 'success 50%' with 'error: worker process died' although every route succeeded."""
    from types import SimpleNamespace

    from b2d_data.collection.plan import CollectionPlan, RouteTask, ScenarioPlan
    from b2d_data.collection.runner import CollectSummary, summarise, summary_table

    tasks = [RouteTask(SimpleNamespace(id=str(i)), SimpleNamespace(name="Town100"), "Accident", i) for i in (1, 2)]
    plan = CollectionPlan([ScenarioPlan("Accident", 2, tasks)], towns=[], settings={})
    records = [
        {**_attempt(1, "error", WORKER_LOST), "reason": "worker process died (killed or crashed)"},
        {**_attempt(2, "error", WORKER_LOST), "reason": "worker pool broke while the route was queued or running"},
        _attempt(1, "clip"),
        _attempt(2, "clip"),
        {**_attempt(3, "error"), "route_id": "9"},  # another scenario's route: not counted here
    ]
    (s,) = summarise(plan, records, tmp_path, sensors=False)
    # 2 routes, each lost once then a clip: 2 attempts, 2 clips, 2 lost, no error, 100 %.
    assert (s.attempts, s.clips, s.lost, s.errors, s.failed, s.reasons) == (2, 2, 2, 0, 0, {})
    assert s.success_rate == 1.0 and s.to_dict()["lost"] == 2
    table = summary_table(CollectSummary(str(tmp_path), [s])).splitlines()
    assert table[0].split() == ["scenario", "clips", "attempts", "lost", "success", "main", "failure", "reasons"]
    assert table[2].split() == ["Accident", "2/2", "2", "2", "100%", "—"]
    assert table[3].startswith("lost: attempts whose worker process died")


def test_a_full_disk_stops_the_run_and_says_how_much_space_to_free(short_routes, tmp_path, monkeypatch, capsys):  # noqa: F811, E501
    """Audit case 3: on a full disk every later route was started into it (and spent an attempt), and the last
    line said 'raise --attempts-per-clip'. ENOSPC is injected into the writer from frame 5 of the route after the
    first clip."""
    from b2d_data.writers import frame_jobs

    out = tmp_path / "data"
    real_run = frame_jobs.MiscJob.run

    def full_once_a_clip_exists(self):
        if self.index >= 5 and any(p.name.startswith("Accident_") for p in out.iterdir()):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.clip_dir)
        return real_run(self)

    monkeypatch.setattr(frame_jobs.MiscJob, "run", full_once_a_clip_exists)
    args = _args(short_routes, out, "--workers", "1")  # in this process, where the writer is patched
    assert main(args) == 1  # --n 2 of 3 routes

    records = rl.read_run_log(out / rl.LOG_FILE)
    finals = rl.final_records(records)
    # Route 1 made its clip, route 2 hit the full disk, route 3 was never started.
    assert [r["route_id"] for r in records if r["event"] == rl.EVENT_START] == ["1", "2"]
    assert [(r["route_id"], r["status"], r["note"]) for r in finals] == [("1", "clip", ""), ("2", "error", "disk full")]
    assert finals[1]["frames"] == 5 and finals[1]["bytes_written"] > 0  # what it wrote before frame 5 failed
    clip = out / finals[0]["clip"]
    # The estimate by hand: the one clip's size (every file under it) times the 1 missing clip.
    size = sum(p.stat().st_size for p in clip.rglob("*") if p.is_file())
    assert size == finals[0]["bytes_written"] + len((clip / "b2d_format.json").read_bytes())
    err = capsys.readouterr().err
    mb = f"{size / 1e6:.1f} MB"
    assert f"the 1 missing clip(s) need about {mb} ({mb} per clip, measured on 1 clip(s))" in err, err
    assert "then run the same command with --resume" in err and "attempts-per-clip" not in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["disk_full"]["needed_bytes"] == size and summary["disk_full"]["missing_clips"] == 1
    # Route 2 is no verdict on the route: 1 attempt, 1 lost.
    assert [summary["scenarios"][0][k] for k in ("clips", "attempts", "lost")] == [1, 1, 1]

    monkeypatch.undo()  # space freed: the resume runs route 2 again and finishes
    assert main([*args, "--resume"]) == 0
    finals = rl.final_records(rl.read_run_log(out / rl.LOG_FILE))
    assert [(r["route_id"], r["status"]) for r in finals[2:]] == [("2", "clip")] and len(_clips(out)) == 2


def test_a_full_disk_under_the_drivers_own_files_is_one_clear_line(short_routes, tmp_path, monkeypatch, capsys):  # noqa: F811, E501
    def full(self, record):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))

    monkeypatch.setattr(rl.RunLog, "append", full)
    out = tmp_path / "data"
    assert main(_args(short_routes, out)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f"b2d-collect: error: {out / rl.LOG_FILE}: no space left on device; free space, then run the "
                       "same command with --resume"), err  # fmt: skip


def test_disk_full_is_recognised_through_wrappers_and_hdf5_text():

    from b2d_data.collection.disk_space import is_disk_full
    from b2d_data.writers.clip_writer import ClipWriterError

    try:
        try:
            raise OSError(errno.ENOSPC, "No space left on device")
        except OSError as exc:
            raise ClipWriterError("clip: frame 3 failed") from exc
    except ClipWriterError as wrapped:
        assert is_disk_full(wrapped)
    # h5py's error (audit case 3) carries the errno only in its text.
    assert is_disk_full(RuntimeError("Disable slist on flush dest failure failed (file write failed: errno = 28, "
                                     "error message = 'No space left on device')"))  # fmt: skip
    assert not is_disk_full(OSError(errno.EACCES, "Permission denied"))


def test_without_a_clip_the_space_needed_comes_from_the_bytes_per_frame(tmp_path):
    from b2d_data.collection.disk_space import space_needed

    stopped = [{"frames": 5, "bytes_written": 50_000}, {"frames": 0, "bytes_written": 0}]
    need = space_needed(tmp_path, [], stopped, missing_clips=2, frames_per_clip=300.0)
    # 50 000 B / 5 frames = 10 kB per frame; x 300 frames x 2 clips = 6 000 000 B.
    assert need.per_clip_bytes is None and need.per_frame_bytes == 10_000 and need.needed_bytes == 6_000_000
    assert "the 2 missing clip(s) need about 6.0 MB (10 kB per frame written before the disk filled, ~300 frames " \
           "per route)" in need.describe()


def test_a_killed_driver_leaves_no_multiprocessing_folder_after_the_next_run(short_routes, tmp_path):  # noqa: F811
    """Audit section 1: every killed driver left ``$TMPDIR/pymp-*/listener-*`` (multiprocessing's fork server
    socket), removed only at a normal exit. Now it lies in the run's own folder, which the next run removes."""
    # A short TMPDIR: the fork server's socket path must fit 103 bytes (pytest's tmp_path is too deep).
    temp = Path(tempfile.mkdtemp(prefix="b2dt", dir="/tmp"))
    try:
        _kill_then_run_again(short_routes, tmp_path, temp)
    finally:
        shutil.rmtree(temp, ignore_errors=True)


def _kill_then_run_again(short_routes, tmp_path: Path, temp: Path) -> None:  # noqa: F811
    env = dict(os.environ, TMPDIR=str(temp))
    args = _args(short_routes, tmp_path / "records", "--workers", "2", "--no-sensors")
    proc = subprocess.Popen([sys.executable, "-m", "b2d_data.cli.collect", *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    helpers: set[int] = set()
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            helpers |= descendants(proc.pid)
            if list(temp.rglob("listener-*")) and len(helpers) >= 3:  # fork server and workers are up
                break
            time.sleep(0.05)
        helpers |= descendants(proc.pid)
        assert proc.poll() is None, "the collection ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert_all_exit(helpers)
    left = [p.name for p in temp.iterdir()]
    assert len(left) == 1 and left[0].startswith(f"b2d-collect-{proc.pid}-"), left  # not a bare pymp-*
    assert list((temp / left[0]).glob("pymp-*/listener-*"))

    # What is not a dead run's folder stays: a live driver's (this process) and anything else.
    kept = sorted([f"b2d-collect-{os.getpid()}-live", "pymp-other"])
    for name in kept:
        (temp / name).mkdir()
    done = subprocess.run([sys.executable, "-m", "b2d_data.cli.collect", "--list-scenarios"], env=env,
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in temp.iterdir()) == kept  # the dead run's folder and the new run's own are gone


def test_a_temporary_folder_too_deep_for_the_fork_server_socket_is_left_alone(tmp_path, monkeypatch):
    """The fork server binds its socket at <run folder>/pymp-XXXXXXXX/listener-XXXXXXXX: at most 103 bytes."""
    from b2d_data.collection import temp_dir

    # 60 + 1 + the run folder's name (at least 12 + 1 + 1 + 8) + 32 > 103, whatever tmp_path is.
    deep = tmp_path / ("d" * 60)
    deep.mkdir()
    monkeypatch.setattr(temp_dir, "_folder", None)
    monkeypatch.setattr(tempfile, "tempdir", str(deep))
    monkeypatch.setenv("TMPDIR", str(deep))
    with temp_dir.private_temp_dir() as folder:
        assert folder == deep and os.environ["TMPDIR"] == str(deep) and not list(deep.iterdir())


def _wait_forever() -> None:
    time.sleep(3600)


def test_idle_workers_that_do_not_exit_at_close_are_stopped_after_the_grace():
    # A worker blocked on the pool's call-queue lock (its sibling was killed holding it) never reads its stop
    # sentinel: close() gives idle workers IDLE_GRACE, then SIGTERMs them. Here a stand-in that just waits, with a
    # 0.5 s grace: it must be gone after ≥ 0.5 s and well before ABANDON_GRACE (it dies on the first SIGTERM).
    import multiprocessing

    from b2d_data.collection.backends import _join_or_stop

    process = multiprocessing.get_context("spawn").Process(target=_wait_forever)
    process.start()
    t0 = time.monotonic()
    _join_or_stop([process], 0.5)
    took = time.monotonic() - t0
    assert not process.is_alive() and process.exitcode == -signal.SIGTERM
    assert 0.5 <= took < 5.0
