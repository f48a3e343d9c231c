"""Live progress of ``b2d-collect``: reports at least every 2 s during a route, the frame-based ETA, throttling.

A scripted backend on a fake clock stands in for the workers: each route records 10 frames per (fake) second and
reports them whenever the driver waits, as the pool and Ray backends do.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from types import SimpleNamespace

import pytest

from b2d_data.collection import run_log as rl
from b2d_data.collection.job import CollectConfig, JobResult
from b2d_data.collection.plan import CollectionPlan, RouteTask, ScenarioPlan
from b2d_data.collection.progress import FrameReport, FrameReporter, set_frame_sink
from b2d_data.collection.runner import Progress, _Session

ROUTE_FRAMES = 100
FPS = 10  # frames per fake second


@dataclass
class FakeClock:
    t: float = 0.0

    def __call__(self) -> float:
        return self.t


class ScriptedBackend:
    """One route at a time; every ``wait`` moves the clock by its timeout and the route by ``FPS`` frames/s."""

    capacity = 1

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock
        self.on_frames = None
        self.task: RouteTask | None = None
        self.frames = 0.0

    def submit(self, task: RouteTask) -> None:
        self.task, self.frames = task, 0.0

    def running(self) -> int:
        return int(self.task is not None)

    def wait(self, timeout: float | None = None) -> list[tuple[RouteTask, JobResult]]:
        assert timeout is not None and timeout <= 2.0, "the driver must not block longer than a refresh"
        self.clock.t += timeout
        self.frames = min(self.frames + FPS * timeout, ROUTE_FRAMES)
        task = self.task
        assert task is not None
        if self.frames < ROUTE_FRAMES:
            frames = int(self.frames)
            self.on_frames(FrameReport(str(task.route.id), f"Accident_Town100_Route{task.route.id}_Weather1", frames,
                                       100.0 * frames / ROUTE_FRAMES))  # fmt: skip
            return []
        self.task = None
        result = JobResult(str(task.route.id), task.scenario, "Town100", 1, task.seed, "clip", success=True,
                           frames=ROUTE_FRAMES, ticks=2 * ROUTE_FRAMES - 1)  # fmt: skip
        return [(task, result)]

    def close(self, abandon: bool = False) -> None:
        self.task = None


def _session(tmp_path, clock: FakeClock, calls: list[tuple[float, Progress]]) -> _Session:
    tasks = [RouteTask(SimpleNamespace(id=str(i)), SimpleNamespace(name="Town100"), "Accident", i) for i in (7, 8)]
    plan = CollectionPlan([ScenarioPlan("Accident", 2, tasks)], towns=[], settings={})
    config = CollectConfig(out=tmp_path, scenarios=("Accident",), n=2)
    run_log = rl.RunLog(tmp_path / rl.LOG_FILE)
    return _Session(plan, tmp_path, config, run_log, [], lambda p: calls.append((clock(), p)), clock=clock)


def test_progress_is_reported_at_least_every_2_s_while_a_route_runs(tmp_path):
    clock = FakeClock()
    calls: list[tuple[float, Progress]] = []
    session = _session(tmp_path, clock, calls)
    backend = ScriptedBackend(clock)
    backend.on_frames = session.frames_reported
    assert session.run(backend) == (2, 2)

    times = [t for t, _ in calls]
    assert times[0] == 0.0 and times[-1] == pytest.approx(20.0)  # two routes of 100 frames at 10 frames/s
    assert max(b - a for a, b in itertools.pairwise(times)) <= 2.0
    during_first = [p for t, p in calls if 0.0 < t < 10.0]
    assert len(during_first) >= 9, "the display must move while the first route runs, not only when it ends"
    assert [p.elapsed for p in during_first] == sorted(p.elapsed for p in during_first)
    frames = [p.routes[0].frames for p in during_first]
    assert frames == sorted(frames) and frames[-1] == 90
    assert all(p.clips == 0 and p.routes[0].route_id == "7" for p in during_first)

    by_time = {t: p for t, p in calls}
    # t = 3 s: 30 of route 7's frames at 30 % completion -> ~100 frames a route; 10 frames/s since the first
    # report (t = 1 s, 10 frames); left: 70 frames of route 7 + 1 more clip x 100 frames = 170 frames -> 17 s.
    assert by_time[3.0].eta == pytest.approx(17.0)
    assert "Route7 Accident 30/~100 fr" in by_time[3.0].describe() and "ETA 00:17" in by_time[3.0].describe()
    # t = 11 s: route 7 made its clip with 100 frames; route 8 has 10 -> 90 frames left at 10 frames/s.
    assert by_time[11.0].clips == 1 and by_time[11.0].eta == pytest.approx(9.0)
    assert calls[-1][1].clips == 2 and calls[-1][1].result is not None


def test_a_job_reports_its_frames_at_most_every_half_second():
    clock = FakeClock()
    got: list[FrameReport] = []
    previous = set_frame_sink(got.append)
    try:
        reporter = FrameReporter("7", "clip", clock=clock)
        for frame in range(1, 21):  # 20 frames, one every 0.125 s
            clock.t = (frame - 1) * 0.125
            reporter(frame, 5.0 * frame)
    finally:
        set_frame_sink(previous)
    assert [(r.frames, r.completion) for r in got] == [(1, 5.0), (5, 25.0), (9, 45.0), (13, 65.0), (17, 85.0)]


def test_the_progress_line_counts_the_eta_down_between_reports():
    from b2d_data.cli.collect import ProgressLine

    clock = FakeClock()
    line = ProgressLine(enabled=False, clock=clock)
    line(Progress(clips=1, requested=4, attempts=2, elapsed=30.0, eta=17.0))
    assert line.text().endswith("ETA 00:17")
    clock.t = 5.0
    assert line.text() == "2 attempts, 0 failed | ETA 00:12"
