"""``agents.navigation.global_route_planner.GlobalRoutePlanner`` on the running town.

One planner keeps its turn-decision state between ``trace_route`` calls, as CARLA's does (the Leaderboard densifies a
route's keypoints with one planner).
"""

from __future__ import annotations

from typing import Any

import carla
from carla._convert import from_carla_location

from b2d_data.format.road_option import RoadOption
from b2d_data.maps.route_planner import RoutePlanner

__all__ = ["GlobalRoutePlanner"]


class GlobalRoutePlanner:
    """CARLA's global route planner over a ``carla.Map`` of the stand-in, at ``sampling_resolution`` metres."""

    def __init__(self, wmap: carla.Map, sampling_resolution: float) -> None:
        b2d_map = getattr(wmap, "b2d_map", None)
        if b2d_map is None:
            raise TypeError(f"GlobalRoutePlanner needs the map of the running world (world.get_map()), got {wmap!r}")
        self._wmap = wmap
        self._sampling_resolution = float(sampling_resolution)
        self._planner = RoutePlanner(b2d_map.route_graph(self._sampling_resolution))

    def trace_route(self, origin: Any, destination: Any) -> list[tuple[carla.Waypoint, RoadOption]]:
        """``[(waypoint, RoadOption)]`` from ``origin`` to ``destination`` (carla.Locations)."""
        route = self._planner.trace_route(from_carla_location(origin), from_carla_location(destination))
        return [(carla.Waypoint(w), RoadOption(option)) for w, option in route]
