"""SIGTERM handled like Ctrl-C by the long-running commands (batch schedulers stop jobs with SIGTERM)."""

from __future__ import annotations

import signal
import threading


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def stop_on_sigterm() -> object | None:
    """Make SIGTERM raise KeyboardInterrupt in the main thread; returns the previous handler (None off the main
    thread, where handlers cannot be set)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _interrupt)


def restore_sigterm(previous: object | None) -> None:
    """Put back the handler :func:`stop_on_sigterm` replaced."""
    if previous is not None:
        signal.signal(signal.SIGTERM, previous)  # type: ignore[arg-type]
