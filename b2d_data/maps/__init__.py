"""OpenDRIVE towns as CARLA-like maps: lane graph, waypoint queries, junctions, signals, routes, HD-map export.

``load_opendrive(path)`` gives a :class:`Map` whose API follows ``carla.Map`` / ``carla.Waypoint`` in CARLA's
frame (OpenDRIVE y flipped once at import). See docs/interfaces.md (section ``b2d_data.maps``).
"""

from b2d_data.maps.geolocation import GeoLocation, GeoReference
from b2d_data.maps.junction import Junction
from b2d_data.maps.lane_types import LaneChange, LaneMarking, LaneMarkingColor, LaneMarkingType, LaneType
from b2d_data.maps.map import LaneGeometry, Map, load_opendrive
from b2d_data.maps.objects import Crosswalk, RoadMarkLine
from b2d_data.maps.opendrive_parser import OpenDriveError, parse_opendrive
from b2d_data.maps.route_planner import RouteNotFoundError
from b2d_data.maps.signals import Controller, Signal, SignalLane
from b2d_data.maps.waypoint import Waypoint

__all__ = [
    "Controller", "Crosswalk", "GeoLocation", "GeoReference", "Junction", "LaneChange", "LaneGeometry", "LaneMarking",
    "LaneMarkingColor", "LaneMarkingType", "LaneType", "Map", "OpenDriveError", "RoadMarkLine", "RouteNotFoundError",
    "Signal", "SignalLane", "Waypoint", "load_opendrive", "parse_opendrive",
]  # fmt: skip
