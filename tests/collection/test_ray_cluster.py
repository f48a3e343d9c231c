"""``b2d-collect --ray`` against a real local Ray cluster (two worker CPUs), with one worker killed mid-route.

Runs where Ray is installed. The cluster is a private one (its own ports and temporary folder) started by
``ray start --head --block``, and stopped by killing exactly the processes it started.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from b2d_data.collection import run_log as rl

from ..conftest import descendants
from .test_collect import N, _args, _clips, _temporaries, short_routes  # noqa: F401 - fixture

pytest.importorskip("ray")

# Ray's process title while a worker runs a task is ray::<function>; the collection's task runs the route job.
WORKER_TITLE, JOB_FUNCTION = b"ray::", b"route_job"
# A private test cluster: no usage report, and no token from the user's ~/.ray (Ray >= 2.5x enables token auth
# whenever that file exists, and the head and the driver must agree).
RAY_ENV = {"RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "disabled"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def _job_workers(head: int) -> list[int]:
    """Worker processes of our cluster (below its head process) running a route right now."""
    return sorted(
        pid
        for pid in descendants(head)
        if _cmdline(pid).startswith(WORKER_TITLE) and JOB_FUNCTION in _cmdline(pid).split(b"\0")[0]
    )


@pytest.fixture
def ray_cluster(tmp_path):
    """A head node on 127.0.0.1 with 2 CPUs; yields (address, the head's process id)."""
    temp = Path("/tmp") / f"b2dray{os.getpid()}"  # Ray's socket paths must stay short: not under pytest's tmp_path
    port = _free_port()
    low = 20000 + (os.getpid() % 200) * 100
    cmd = [
        sys.executable, "-m", "ray.scripts.scripts", "start", "--head", "--block", "--node-ip-address=127.0.0.1",
        f"--port={port}", "--num-cpus=2", "--num-gpus=0", "--include-dashboard=false", "--disable-usage-stats",
        f"--temp-dir={temp}", f"--min-worker-port={low}", f"--max-worker-port={low + 60}",
        f"--node-manager-port={low + 70}", f"--object-manager-port={low + 71}",
        f"--dashboard-agent-listen-port={low + 73}",
        f"--dashboard-agent-grpc-port={low + 74}", f"--metrics-export-port={low + 75}",
        f"--runtime-env-agent-port={low + 76}",
    ]  # fmt: skip
    env = {**os.environ, **RAY_ENV}
    head = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if head.poll() is not None:
                pytest.fail(f"ray start failed:\n{head.stdout.read().decode(errors='replace')[-3000:]}")
            if any(b"raylet" in _cmdline(p) for p in descendants(head.pid)):
                break
            time.sleep(0.5)
        else:
            pytest.fail("the Ray head did not start within 60 s")
        yield f"127.0.0.1:{port}", head.pid
    finally:
        # Stop exactly what this cluster started: every process below the head, then the head's process group.
        for pid in descendants(head.pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        try:
            os.killpg(head.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        head.wait(timeout=30)
        subprocess.run(["rm", "-rf", str(temp)], check=False)


def test_a_killed_ray_worker_costs_a_retry_not_a_clip(short_routes, ray_cluster, tmp_path):  # noqa: F811
    address, head = ray_cluster
    out = tmp_path / "ray"
    env = {**os.environ, **RAY_ENV, "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[2]),
                                                        os.environ.get("PYTHONPATH", "")])}  # fmt: skip
    driver = subprocess.Popen(
        [sys.executable, "-m", "b2d_data.cli.collect", *_args(short_routes, out, "--ray", address)],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )  # fmt: skip
    killed: int | None = None
    deadline = time.monotonic() + 150
    try:
        while killed is None and driver.poll() is None and time.monotonic() < deadline:
            workers = _job_workers(head)
            log = out / rl.LOG_FILE
            if workers and log.exists() and rl.EVENT_START in log.read_text():
                time.sleep(1.0)  # mid-route: past the set-up, frames being written
                workers = _job_workers(head)
                if workers:
                    killed = workers[0]
                    os.kill(killed, signal.SIGKILL)
            time.sleep(0.2)
        output, _ = driver.communicate(timeout=max(10.0, deadline - time.monotonic()))
    finally:
        if driver.poll() is None:
            driver.kill()
    text = output.decode(errors="replace")
    assert killed is not None, f"no Ray worker was seen running a route:\n{text[-3000:]}"
    assert driver.returncode == 0, text[-3000:]

    records = rl.final_records(rl.read_run_log(out / rl.LOG_FILE))
    lost = [r for r in records if r["status"] == "error"]
    assert len(lost) == 1 and "Ray task failed" in lost[0]["reason"], records
    # The killed route ran again and became a clip; the corpus holds exactly the N clips asked for.
    retried = [r for r in records if r["route_id"] == lost[0]["route_id"] and r["status"] != "error"]
    assert len(retried) == 1, records
    clips = _clips(out)
    assert len(clips) == N
    assert sorted(c.name for c in clips) == sorted(r["clip"] for r in records if r["status"] == "clip")
    assert _temporaries(out) == []
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] and summary["scenarios"][0]["clips"] == N
    assert {r["pid"] for r in records if r["status"] == "clip"} != {os.getpid()}  # the routes ran in Ray workers
