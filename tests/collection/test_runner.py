"""The collection loop's choice of the next route: round robin over the targets, with a free worker's town first.

A backend of ``capacity`` simulated workers finishes routes in launch order; the worker that finished a route takes
the next one launched (as a process pool's idle worker does), and the test counts how often a worker changes town.
"""

from __future__ import annotations

from collections import deque
from types import SimpleNamespace

import pytest

from b2d_data.collection import run_log as rl
from b2d_data.collection import runner
from b2d_data.collection.job import CollectConfig, JobResult
from b2d_data.collection.plan import CollectionPlan, RouteTask, ScenarioPlan
from b2d_data.collection.runner import _Session


class WorkerBackend:
    """``capacity`` workers; ``wait`` finishes the oldest running route, whose worker then takes the next launch."""

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.on_frames = None
        self.running_tasks: deque[tuple[int, RouteTask]] = deque()
        self.free = deque(range(capacity))
        self.town_of: dict[int, str] = {}
        self.launched: list[str] = []
        self.switches = 0

    def submit(self, task: RouteTask) -> None:
        worker = self.free.popleft()
        if self.town_of.get(worker, task.town.name) != task.town.name:
            self.switches += 1
        self.town_of[worker] = task.town.name
        self.running_tasks.append((worker, task))
        self.launched.append(str(task.route.id))

    def running(self) -> int:
        return len(self.running_tasks)

    def wait(self, timeout: float | None = None) -> list[tuple[RouteTask, JobResult]]:
        worker, task = self.running_tasks.popleft()
        self.free.append(worker)
        return [(task, JobResult(str(task.route.id), task.scenario, task.town.name, 1, task.seed, "clip",
                                 success=True, frames=10, ticks=19))]  # fmt: skip

    def close(self, abandon: bool = False) -> None:
        self.running_tasks.clear()


def _run(tmp_path, towns: str, capacity: int) -> WorkerBackend:
    """One clip wanted of each of ``len(towns)`` targets (a preset's layout), target i's route on town ``towns[i]``."""
    plans = [ScenarioPlan("Accident", 1, [RouteTask(SimpleNamespace(id=str(i)), SimpleNamespace(name=f"Town{t}"),
                                                    "Accident", i, group=f"#{i}")], group=f"#{i}")
             for i, t in enumerate(towns)]  # fmt: skip
    plan = CollectionPlan(plans, towns=[], settings={})
    config = CollectConfig(out=tmp_path, scenarios=("Accident",), n=1)
    session = _Session(plan, tmp_path, config, rl.RunLog(tmp_path / rl.LOG_FILE), [], None)
    backend = WorkerBackend(capacity)
    assert session.run(backend) == (len(towns), len(towns))
    return backend


def test_a_free_worker_takes_a_route_on_the_town_it_has_loaded(tmp_path) -> None:
    # Towns A B B B A A on two workers. In turn, worker 0 (A) would take 2 (B), worker 1 (B) 3, then 4 and 5 (A) go
    # to workers last on B: three changes. Looking ahead, worker 0 takes 4 and then 5, worker 1 takes 2 and 3.
    backend = _run(tmp_path, "ABBBAA", capacity=2)
    assert backend.launched == ["0", "1", "4", "2", "5", "3"]
    assert backend.switches == 0


def test_one_town_keeps_the_round_robin(tmp_path) -> None:
    backend = _run(tmp_path, "AAAAA", capacity=2)
    assert backend.launched == ["0", "1", "2", "3", "4"]


def test_the_target_in_turn_is_passed_over_a_bounded_number_of_times(tmp_path, monkeypatch) -> None:
    # One worker, towns A B A A A: the worker stays on A for 2, 3 and 4 while target 1 (B) waits ...
    assert _run(tmp_path / "free", "ABAAA", capacity=1).launched == ["0", "2", "3", "4", "1"]
    # ... unless it has been passed over TOWN_PASSES times: with 2, target 1 goes third.
    monkeypatch.setattr(runner, "TOWN_PASSES", 2)
    assert _run(tmp_path / "bounded", "ABAAA", capacity=1).launched == ["0", "2", "3", "1", "4"]


@pytest.mark.parametrize("capacity", [1, 3])
def test_every_target_gets_its_clip_whatever_the_towns(tmp_path, capacity: int) -> None:
    backend = _run(tmp_path, "ABCABCCBA", capacity=capacity)
    assert sorted(backend.launched, key=int) == [str(i) for i in range(9)]
