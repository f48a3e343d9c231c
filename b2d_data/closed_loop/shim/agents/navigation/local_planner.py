"""``agents.navigation.local_planner``: the route commands (``RoadOption``) as b2d-data stores them."""

from __future__ import annotations

from b2d_data.format.road_option import RoadOption

__all__ = ["RoadOption"]
