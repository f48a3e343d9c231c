"""``leaderboard.utils.route_manipulation``: the route's GPS conversion, downsampling and interpolation.

Semantics are the Leaderboard 2.0's: the GPS of a route point is CARLA's Mercator projection around the geo
reference parsed from the OpenDRIVE header (42.0, 2.0 when absent), and the downsampling keeps the route's decision
points plus one point per ``sample_factor`` metres.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from typing import Any

import carla
from agents.navigation.local_planner import RoadOption
from carla._convert import from_carla_location, to_carla_transform
from lxml import etree

from b2d_data.maps.geolocation import EARTH_RADIUS_EQUA, GeoReference

__all__ = ["EARTH_RADIUS_EQUA", "_get_latlon_ref", "_location_to_gps", "downsample_route", "interpolate_trajectory",
           "location_route_to_gps"]  # fmt: skip

log = logging.getLogger(__name__)

#: The Leaderboard's geo reference when the OpenDRIVE header has none.
DEFAULT_LAT_REF = 42.0
DEFAULT_LON_REF = 2.0

_LANE_CHANGES = (RoadOption.CHANGELANELEFT, RoadOption.CHANGELANERIGHT)


def _location_to_gps(lat_ref: float, lon_ref: float, location: Any) -> dict[str, float]:
    """A world location as ``{'lat', 'lon', 'z'}``: Mercator scaled by cos(lat_ref), east +x, north −y."""
    geo = GeoReference(float(lat_ref), float(lon_ref)).transform(from_carla_location(location))
    return {"lat": geo.latitude, "lon": geo.longitude, "z": float(location.z)}


def location_route_to_gps(route: Sequence[tuple[Any, Any]], lat_ref: float, lon_ref: float) -> list[tuple[dict, Any]]:
    """``[(transform, option)]`` → ``[({'lat', 'lon', 'z'}, option)]``."""
    return [(_location_to_gps(lat_ref, lon_ref, transform.location), option) for transform, option in route]


def _parse_latlon_ref(xodr: str) -> tuple[float, float]:
    """``+lat_0`` / ``+lon_0`` of the header's geoReference (each defaulting to 42.0 / 2.0)."""
    lat_ref, lon_ref = DEFAULT_LAT_REF, DEFAULT_LON_REF
    root = etree.fromstring(xodr.encode("utf-8"), parser=etree.XMLParser(huge_tree=True, recover=True))
    if root is None:
        return lat_ref, lon_ref
    for header in root.iter("header"):
        for georef in header.iter("geoReference"):
            for item in (georef.text or "").split():
                match = re.fullmatch(r"\+(lat_0|lon_0)=(.+)", item)
                if match is None:
                    continue
                try:
                    value = float(match.group(2))
                except ValueError:
                    log.warning("unreadable %s in the geoReference %r", match.group(1), georef.text)
                    continue
                if match.group(1) == "lat_0":
                    lat_ref = value
                else:
                    lon_ref = value
    return lat_ref, lon_ref


def _get_latlon_ref(world: Any) -> tuple[float, float]:
    """The geo reference (lat_0, lon_0) of the world's OpenDRIVE header (default 42.0, 2.0)."""
    return _parse_latlon_ref(world.get_map().to_opendrive())


def downsample_route(route: Sequence[tuple[Any, Any]], sample_factor: float) -> list[int]:
    """Indices of the route points an agent's plan keeps (the Leaderboard's rule).

    Kept: the first point; every lane-change point; every point whose option differs from the previous one, unless the
    previous one was a lane change; then, once the distance accumulated over the points not kept exceeds
    ``sample_factor`` metres, the next point; and the last point. Route items are ``(transform, option)``.
    """
    ids: list[int] = []
    prev_option = None
    dist = 0.0
    last = len(route) - 1
    for i, (transform, option) in enumerate(route):
        decision = option != prev_option and prev_option not in _LANE_CHANGES  # covers the first point (None)
        keep = option in _LANE_CHANGES or decision or dist > sample_factor or i == last
        if keep:
            ids.append(i)
            dist = 0.0
        else:
            dist += transform.location.distance(route[i - 1][0].location)
        prev_option = option
    return ids


def interpolate_trajectory(
    waypoints_trajectory: Sequence[Any], hop_resolution: float = 1.0
) -> tuple[list[tuple[dict, Any]], list[tuple[carla.Transform, RoadOption]]]:
    """Densify route keypoints (carla.Locations) through the route planner: ``(gps_route, route)``.

    ``route`` is ``[(carla.Transform, RoadOption)]`` (the waypoints' transforms), ``gps_route`` the same points as
    ``{'lat', 'lon', 'z'}`` with the town's geo reference. Consecutive keypoints with the same x, y are skipped.
    """
    from srunner.scenariomanager.carla_data_provider import CarlaDataProvider

    world = CarlaDataProvider.get_world()
    b2d_map = world.get_map().b2d_map
    keypoints = [from_carla_location(p) for p in waypoints_trajectory]
    dense = b2d_map.interpolate_trajectory(keypoints, hop_resolution)
    route = [(to_carla_transform(w.transform), RoadOption(option)) for w, option in dense]
    lat_ref, lon_ref = _get_latlon_ref(world)
    return location_route_to_gps(route, lat_ref, lon_ref), route
