"""Shared fixtures: the real Bench2Drive / CARLA files the package ships (b2d_data/data); process-tree helpers for
the tests that interrupt or kill a command and check that none of its processes outlives it."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import pytest

from b2d_data import data


@pytest.fixture(scope="session")
def b2d_data_dir() -> Path:
    """The shipped Bench2Drive files: route XML, weather.xml, split lists, VAD's merged result."""
    return data.bench2drive_dir()


@pytest.fixture(scope="session")
def carla_maps_dir() -> Path:
    """The shipped CARLA towns (Town01/04/06/07/10HD .xodr)."""
    return data.carla_maps_dir()


def descendants(pid: int) -> set[int]:
    """Every live process below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found: set[int] = set()
    todo = [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie counts as dead)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def sigint_default() -> None:
    """In the child: Ctrl-C as from a terminal. A shell starts background jobs with SIGINT ignored (a CI script run
    with ``&``), and Python started so never turns SIGINT into KeyboardInterrupt: the interrupt would be lost."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def assert_all_exit(pids: set[int], timeout: float = 10.0) -> None:
    """Every process of ``pids`` (a command's helpers) ends within ``timeout`` seconds."""
    assert pids, "the command started no helper process"
    deadline = time.monotonic() + timeout
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [p for p in pids if alive(p)], "helper processes outlived the stopped command"
