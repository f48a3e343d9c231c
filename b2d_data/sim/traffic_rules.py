"""Backend-neutral traffic-rule geometry shared by the expert and the criteria (one definition, one behaviour).

A stop sign *affects* a vehicle as scenario_runner's RunningStopTest decides: take the vehicle's lane waypoint and
the 8 following ones 0.5 m apart (4 m); the sign's trigger centre must lie within 4 m of the first, and one of them
must fall inside the trigger box enlarged 1.2×. The box test is axis-aligned in the world (the trigger volume's
rotation is ignored, as CARLA's does), so the expert stops exactly where the criterion watches.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from b2d_data.format.transform import Location
from b2d_data.sim.api import TrafficSignInfo

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint

STOP_PROXIMITY = 4.0  # m between the trigger centre and the vehicle's lane waypoint
STOP_WAYPOINT_STEP = 0.5  # m between the lane waypoints checked
STOP_BOX_MULTIPLIER = 1.2


def stop_zone_waypoints(town: Map, location: Location) -> list[Waypoint]:
    """The lane waypoint at ``location`` and those following it every 0.5 m over 4 m (9 at most)."""
    wp = town.get_waypoint(location)
    if wp is None:
        return []
    out = [wp]
    for _ in range(int(STOP_PROXIMITY / STOP_WAYPOINT_STEP)):
        nxt = wp.next(STOP_WAYPOINT_STEP)
        if not nxt:
            break
        wp = nxt[0]
        out.append(wp)
    return out


def stop_trigger_centre(sign: TrafficSignInfo) -> Location:
    """World position of a sign's trigger-volume centre."""
    return sign.transform.transform_point(sign.trigger_volume.location)


def inside_stop_box(point: Location, centre: Location, extent: Location, multiplier: float = STOP_BOX_MULTIPLIER) -> bool:
    """scenario_runner's horizontal, axis-aligned box test."""
    return abs(point.x - centre.x) < multiplier * extent.x and abs(point.y - centre.y) < multiplier * extent.y


def stop_affects(waypoints: Sequence[Waypoint], sign: TrafficSignInfo) -> bool:
    """Whether a vehicle whose stop-zone waypoints are ``waypoints`` is affected by ``sign``."""
    if not waypoints:
        return False
    centre = stop_trigger_centre(sign)
    if centre.distance(waypoints[0].transform.location) > STOP_PROXIMITY:
        return False
    extent = sign.trigger_volume.extent
    return any(inside_stop_box(wp.transform.location, centre, extent) for wp in waypoints)
