"""The agent thread: one thread for every agent call, errors handed back, a time limit per call."""

from __future__ import annotations

import threading
import time

import pytest

from b2d_data.closed_loop.agent_thread import AgentThread, AgentTimeout


def test_every_call_runs_on_the_same_thread_and_returns_its_value():
    worker = AgentThread()
    try:
        names = {worker.call(lambda: threading.current_thread().name, timeout=5) for _ in range(3)}
        assert names == {"b2d-agent"}
        assert worker.call(lambda: 6 * 7, timeout=5) == 42
    finally:
        worker.close()


def test_an_error_in_the_call_is_raised_in_the_caller():
    worker = AgentThread()
    try:
        with pytest.raises(ZeroDivisionError):
            worker.call(lambda: 1 / 0, timeout=5)
        assert worker.call(lambda: "still serving", timeout=5) == "still serving"
    finally:
        worker.close()


def test_a_call_over_its_limit_times_out_and_marks_the_thread_stuck():
    worker = AgentThread()
    release = threading.Event()
    try:
        start = time.monotonic()
        with pytest.raises(AgentTimeout):
            worker.call(lambda: release.wait(30), timeout=0.2)
        assert time.monotonic() - start < 5  # the caller is not held up by the stuck call
        assert worker.stuck and worker.busy
        with pytest.raises(AgentTimeout, match="still busy"):
            worker.call(lambda: None, timeout=1)
    finally:
        release.set()
        worker.close()
