"""Traffic lights that a route's signalised scenarios need where the town's OpenDRIVE file has none.

CARLA's older towns place some lights in their Unreal level rather than in the ``.xodr`` (Town04's junction 1452, on
bench2drive220 route 26944), so a signalised scenario that CARLA runs there finds no light in our town. Such a
junction gets CARLA-style lights (``b2d_data.maps.generated_lights``) before the world is built, so the simulator,
the expert, background traffic and the red-light criterion all see them as any other light.

Only the junctions the route's signalised scenarios use get them, not every light-less junction of the town: most
of those have no lights in CARLA either (stop-controlled, priority and highway junctions), and the file does not
tell which ones CARLA's level signalises. Adding lights where a signalised scenario runs is the least we must assume.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from b2d_data.maps.generated_lights import has_traffic_lights
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.triggers import trigger_route_index

if TYPE_CHECKING:
    from b2d_data.maps import Map
    from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)


def is_signalized(scenario_type: str) -> bool:
    """Whether the scenario type needs traffic lights at its junction (unknown types do not)."""
    from b2d_data.scenarios.framework import SCENARIO_CLASSES  # importing the framework registers the catalog

    cls = SCENARIO_CLASSES.get(scenario_type)
    return bool(getattr(cls, "signalized", False)) if cls is not None else False


def junctions_needing_lights(town: Map, route: Route, dense: DenseRoute | None = None) -> list[int]:
    """Junctions of the route's signalised scenarios (found as the scenarios find them) that have no lights."""
    from b2d_data.scenarios.catalog.junctions import junction_entry

    configs = [cfg for cfg in route.scenarios if is_signalized(cfg.type)]
    if not configs:
        return []
    dense = dense if dense is not None else DenseRoute.from_route(town, route)
    needed: list[int] = []
    for cfg in configs:
        index = trigger_route_index(dense, cfg.trigger_point)
        # A trigger off the route or no junction ahead: the scenario reports that itself when it is built.
        entry = junction_entry(dense, index) if index is not None else None
        if entry is None:
            continue
        junction_id = int(dense.waypoints[entry].junction_id)
        if junction_id not in needed and not has_traffic_lights(town, junction_id):
            log.info("route %s: %s needs lights at junction %d of %s, whose OpenDRIVE file has none; adding "
                     "CARLA-style ones", route.id, cfg.name, junction_id, town.name)  # fmt: skip
            needed.append(junction_id)
    return needed


def with_scenario_lights(town: Map, route: Route) -> Map:
    """The town the route runs on: ``town`` itself, or a copy with lights at its signalised scenarios' junctions."""
    needed = junctions_needing_lights(town, route)
    return town.with_junction_lights(needed) if needed else town
