"""One thread that runs every call into the agent, so that a call can be given a time limit.

A Leaderboard agent's code (its model, its PIDs) runs on this thread only: set-up, every step and ``destroy``.
Keeping it on one thread matters beyond the time limit: thread-local state an agent sets in ``setup`` (PyTorch's
``torch.set_grad_enabled(False)``, CUDA streams) holds for its steps too. A call that outlives its limit cannot be
stopped from Python; the thread is left behind (it is a daemon) and :attr:`AgentThread.stuck` tells the route
process to end without waiting for it.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")


class AgentTimeout(TimeoutError):
    """An agent call took longer than its limit."""


class AgentThread:
    """Runs callables one at a time on a dedicated daemon thread; :meth:`call` waits at most ``timeout`` s."""

    def __init__(self, name: str = "b2d-agent") -> None:
        self._requests: queue.SimpleQueue[tuple[Callable[[], Any], queue.SimpleQueue[tuple[bool, Any]]] | None] = (
            queue.SimpleQueue()
        )
        self.stuck = False
        #: A call is still running on the thread (its caller timed out or was interrupted while waiting).
        self.busy = False
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while True:
            request = self._requests.get()
            if request is None:
                return
            fn, reply = request
            try:
                reply.put((True, fn()))
            except BaseException as exc:  # noqa: BLE001 - every agent error is handed to the caller
                reply.put((False, exc))

    def call(self, fn: Callable[[], T], timeout: float | None) -> T:
        """``fn()`` on the agent thread; its exception is re-raised here, :class:`AgentTimeout` after ``timeout`` s."""
        if self.busy:
            raise AgentTimeout("the agent thread is still busy with an earlier call")
        reply: queue.SimpleQueue[tuple[bool, Any]] = queue.SimpleQueue()
        self.busy = True
        self._requests.put((fn, reply))
        try:
            ok, value = reply.get(timeout=timeout)
        except queue.Empty:
            self.stuck = True
            raise AgentTimeout(f"no answer within {timeout:g} s") from None
        self.busy = False
        if not ok:
            raise value
        return value

    def close(self) -> None:
        """Let the thread end after the calls queued so far (returns at once)."""
        self._requests.put(None)
