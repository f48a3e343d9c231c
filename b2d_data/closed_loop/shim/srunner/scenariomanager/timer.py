"""``srunner.scenariomanager.timer.GameTime``: the route's game clock, read from the running route.

The evaluator advances the clock (one 0.05 s tick per agent step); the scenario runner's own hooks (``restart``,
``on_carla_tick``) are accepted and do nothing.
"""

from __future__ import annotations

import datetime
import time
from typing import Any

from b2d_data.closed_loop import bridge as _bridge


class GameTime:
    """The game clock of the running route (all static, as scenario_runner's)."""

    @staticmethod
    def on_carla_tick(timestamp: Any = None) -> None:
        """Accepted and ignored: the evaluator advances the clock."""
        return

    @staticmethod
    def restart() -> None:
        """Accepted and ignored: the clock restarts with each route."""
        return

    @staticmethod
    def get_time() -> float:
        """Game seconds since the route started (0.05 per agent step)."""
        return _bridge.current().game_time()

    @staticmethod
    def get_carla_time() -> float:
        """The world's elapsed game seconds (CARLA's ``timestamp.elapsed_seconds``)."""
        return float(_bridge.current().snapshot.timestamp)

    @staticmethod
    def get_wallclocktime() -> datetime.datetime:
        """The system's current date and time."""
        return datetime.datetime.now()

    @staticmethod
    def get_frame() -> int:
        """The world's frame number of the last tick."""
        return _bridge.current().frame

    @staticmethod
    def get_platform_time() -> float:
        """The system clock (s since the epoch)."""
        return time.time()
