"""The default junction provider for the Traffic_Signs credit: OpenDRIVE maps read with ``b2d_data.maps``.

Bench2Drive densifies a route's XML keypoints with CARLA's GlobalRoutePlanner at 1 m on the town's
OpenDRIVE file and looks for the first waypoint flagged ``is_junction``. Here the same is done with
``b2d_data.maps`` (``load_opendrive`` and ``Map.interpolate_trajectory``). A town is found as
``<maps_dir>/<Town>.xodr``, or in CARLA's layouts ``<maps_dir>/OpenDrive/<Town>.xodr`` and
``<maps_dir>/<Town>/OpenDrive/<Town>.xodr``. When the map module or the town's file is missing the
provider raises ``JunctionUnavailable`` saying which, so that the route is reported as unchecked.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from b2d_data.eval.abilities import MAP_MISSING, JunctionLookup, JunctionUnavailable, first_junction_lookup
from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

#: Hop resolution of the densified route, as Bench2Drive's GlobalRoutePlanner(map, 1.0).
HOP_RESOLUTION = 1.0


def find_town_map(maps_dir: str | Path, town: str) -> Path | None:
    """The OpenDRIVE file of ``town`` under ``maps_dir``, or None."""
    maps_dir = Path(maps_dir)
    for candidate in (
        maps_dir / f"{town}.xodr",
        maps_dir / "OpenDrive" / f"{town}.xodr",
        maps_dir / town / "OpenDrive" / f"{town}.xodr",
    ):
        if candidate.is_file():
            return candidate
    return None


class MapJunctionProvider:
    """Junction lookups from ``<maps_dir>/<Town>.xodr`` through ``b2d_data.maps`` (one town kept loaded)."""

    def __init__(self, maps_dir: str | Path) -> None:
        self.maps_dir = Path(maps_dir)
        self._town: str | None = None
        self._map: Any = None
        self._lookups: dict[str, JunctionLookup] = {}

    def _load(self, town: str) -> Any:
        if self._town == town:
            return self._map
        path = find_town_map(self.maps_dir, town)
        if path is None:
            raise JunctionUnavailable(f"map of {town} missing: no {town}.xodr in {self.maps_dir}", MAP_MISSING)
        try:
            from b2d_data.maps import load_opendrive
        except ImportError as exc:
            raise JunctionUnavailable(f"b2d_data.maps cannot be imported ({exc})") from None
        log.info("loading %s for the Traffic_Signs junction check", path)
        try:
            town_map = load_opendrive(path)
        except Exception as exc:  # noqa: BLE001 - any failure of a third-party map becomes a reported reason
            raise JunctionUnavailable(f"map of {town} could not be loaded from {path}: {exc}") from None
        # Only one town stays in memory: Town12/13 maps are large, and routes are visited grouped by town.
        self._town, self._map = town, town_map
        return town_map

    def __call__(self, route: Route) -> JunctionLookup:
        """First junction index and length of the route densified at 1 m."""
        if route.id in self._lookups:
            return self._lookups[route.id]
        town_map = self._load(route.town)
        try:
            dense = town_map.interpolate_trajectory(list(route.waypoints), hop_resolution=HOP_RESOLUTION)
        except Exception as exc:  # noqa: BLE001 - a route the planner cannot trace is reported, not fatal
            raise JunctionUnavailable(f"route {route.id} could not be traced on {route.town}: {exc}") from None
        lookup = first_junction_lookup([bool(waypoint.is_junction) for waypoint, _ in dense])
        self._lookups[route.id] = lookup
        return lookup
