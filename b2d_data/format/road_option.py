"""RoadOption: route commands as stored in annotations (format.md §3.1)."""

from __future__ import annotations

from enum import IntEnum


class RoadOption(IntEnum):
    """CARLA's local-planner RoadOption values."""

    VOID = -1
    LEFT = 1
    RIGHT = 2
    STRAIGHT = 3
    LANEFOLLOW = 4
    CHANGELANELEFT = 5
    CHANGELANERIGHT = 6

    def to_six_way(self) -> int:
        """Index 0..5 of the 6-way one-hot used by TCP/Zoo (VOID counts as LANEFOLLOW)."""
        value = RoadOption.LANEFOLLOW if self is RoadOption.VOID else self
        return int(value) - 1
