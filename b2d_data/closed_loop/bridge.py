"""The running route as the stand-in ``carla`` / ``srunner`` / ``leaderboard`` modules see it.

A route process installs one :class:`RouteBridge` before it creates the agent and updates it every tick, before the
agent's step; the modules under ``shim/`` read the world, the ego, the map and the game clock from it. Keeping this
state in one object (instead of in each stand-in module) lets those modules stay thin views of the builtin simulator.
"""

from __future__ import annotations

import datetime
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from b2d_data.sim.api import FIXED_DELTA_SECONDS, ScenarioHint, Simulator, Snapshot

if TYPE_CHECKING:
    from b2d_data.maps import Map
    from b2d_data.scenarios.route import DenseRoute


class NoRouteRunning(RuntimeError):
    """A stand-in module was used outside a route of ``b2d-eval run``."""


@dataclass
class RouteBridge:
    """What the stand-in modules read: the simulator, its map, the ego and the state after the last tick.

    ``ticks`` counts the route's scenario ticks (the agent's steps); the warm-up ticks after the sensors are
    mounted do not count, as the Leaderboard's ``GameTime`` does not see them. ``hints`` are the running scenarios'
    hints to a privileged agent (what PDM-Lite reads from the scenario runner).
    """

    sim: Simulator
    map: Map
    ego_id: int
    snapshot: Snapshot
    route: DenseRoute | None = None
    hints: Sequence[ScenarioHint] = ()
    ticks: int = 0
    wallclock_start: datetime.datetime = field(default_factory=datetime.datetime.now)
    platform_start: float = field(default_factory=time.time)

    @property
    def frame(self) -> int:
        """The simulator's frame number of the last tick (CARLA's ``timestamp.frame``)."""
        return self.snapshot.frame

    def game_time(self) -> float:
        """Game seconds since the route started (``GameTime.get_time``): one tick of 0.05 s per agent step."""
        return self.ticks * FIXED_DELTA_SECONDS

    def observe(self, snapshot: Snapshot) -> None:
        """A tick the agent does not see (the warm-up after mounting its sensors): only the world state changes."""
        self.snapshot = snapshot

    def advance(self, snapshot: Snapshot, hints: Sequence[ScenarioHint] = ()) -> None:
        """A scenario tick happened: the new world state, the scenarios' hints, one more game tick."""
        self.snapshot = snapshot
        self.hints = tuple(hints)
        self.ticks += 1


_current: RouteBridge | None = None


def install(bridge: RouteBridge | None) -> None:
    """Make ``bridge`` the running route (None: no route runs)."""
    global _current
    _current = bridge


def current() -> RouteBridge:
    """The running route; :class:`NoRouteRunning` outside one."""
    if _current is None:
        raise NoRouteRunning(
            "no route is running: the carla / leaderboard / srunner modules of b2d-data only work inside a route of "
            "`b2d-eval run` (they are views of its builtin simulator, not a CARLA client)"
        )
    return _current


def running() -> bool:
    """Whether a route is running in this process."""
    return _current is not None
