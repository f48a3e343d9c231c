"""Shared fixtures: the real Bench2Drive / CARLA files the package ships (b2d_data/data); a light-less street grid;
process-tree helpers for the tests that interrupt or kill a command and check that none of its processes outlives
it."""

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


@pytest.fixture(scope="session")
def light_less_grid(tmp_path_factory):
    """Town199: a 3 × 3 street grid 120 m apart without lights or signs, one 3.49 m lane each way (seed 0's widths).

    The grid points are junctions in CARLA's frame at (120, 0), (0, -120), (120, -120), (240, -120), (120, -240); the
    corners are bends. The centre (120, -120) is a 4-way junction that four roads enter with one lane each.
    """
    import numpy as np

    from b2d_data.maps import load_opendrive
    from b2d_data.maps.towngen.cross_sections import TownWidths, street
    from b2d_data.maps.towngen.layouts import GridSpec, add_grid
    from b2d_data.maps.towngen.network import NetworkBuilder, TownPlan
    from b2d_data.maps.towngen.xodr_writer import to_xml

    section = street(TownWidths.draw(np.random.default_rng(0)))
    corners = ((0, 0), (2, 0), (0, 2), (2, 2))
    plan = TownPlan("Town199", "test", 0)
    add_grid(plan, GridSpec(
        (0.0, 120.0, 240.0), (0.0, 120.0, 240.0), (section,) * 3, (section,) * 3,
        {p: section for p in corners}, {p: 15.0 for p in corners}, {},
    ))  # fmt: skip
    path = tmp_path_factory.mktemp("grid") / "Town199.xodr"
    path.write_text(to_xml(NetworkBuilder(plan).build()))
    return load_opendrive(path)


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
