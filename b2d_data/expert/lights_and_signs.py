"""Traffic lights and stop signs (expert-and-scenarios.md §1.2 step 4 and §1.7).

The route precomputes which light and stop sign govern each route point; this module holds the stop-sign
membership test (the same one RunningStopTest uses), the target speeds for a light that is not green and an
uncleared stop sign, and the stop sign's cleared/uncleared bookkeeping.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.idm import idm_target_speed
from b2d_data.format.transform import Location
from b2d_data.sim.api import TrafficLightInfo, TrafficLightState, TrafficSignInfo

if TYPE_CHECKING:
    from b2d_data.maps import Map


def stop_sign_centre(sign: TrafficSignInfo) -> np.ndarray:
    """World position of the sign's trigger-volume centre."""
    c = sign.transform.transform_point(sign.trigger_volume.location)
    return np.array([c.x, c.y, c.z])


def point_in_trigger(point: np.ndarray, sign: TrafficSignInfo, config: ExpertConfig) -> bool:
    """Is ``point`` inside the sign's trigger box, extents at least 1 m and enlarged ×1.2, in the horizontal plane?

    The box is tested in its own (rotated) frame.
    """
    local = sign.transform.inverse_transform_points(np.asarray(point, dtype=np.float64)[None, :])[0]
    tv = sign.trigger_volume
    half_x = config.stop_sign_box_multiplier * max(tv.extent.x, config.stop_sign_min_extent)
    half_y = config.stop_sign_box_multiplier * max(tv.extent.y, config.stop_sign_min_extent)
    return abs(local[0] - tv.location.x) < half_x and abs(local[1] - tv.location.y) < half_y


def stop_sign_affects(town: Map, location: np.ndarray, sign: TrafficSignInfo, config: ExpertConfig) -> bool:
    """RunningStopTest's test: within 4 m of the trigger centre and one of 9 lane waypoints (0.5 m apart) inside it."""
    location = np.asarray(location, dtype=np.float64)
    if np.linalg.norm(stop_sign_centre(sign) - location) > config.stop_sign_max_distance:
        return False
    wp = town.get_waypoint(Location(*location))
    if wp is None:
        return False
    steps = round(config.stop_sign_lookahead / config.stop_sign_step)
    for _ in range(steps + 1):
        loc = wp.transform.location
        if point_in_trigger(np.array([loc.x, loc.y, loc.z]), sign, config):
            return True
        nxt = wp.next(config.stop_sign_step)
        if not nxt:
            break
        wp = nxt[0]
    return False


def red_light_target_speed(config: ExpertConfig, desired_speed: float, ego_speed: float, distance: float,
                           light: TrafficLightInfo | None) -> float:
    """Target speed for the route's next light: IDM toward its stop line when it is red or yellow (§1.7)."""
    if light is None or light.state not in (TrafficLightState.RED, TrafficLightState.YELLOW):
        return desired_speed
    return idm_target_speed(config, desired_speed, ego_speed, 0.0, 0.0, distance, config.idm_red_light_s0,
                            config.idm_red_light_T)


@dataclass
class StopSignTracker:
    """Cleared flag of the next stop sign: cleared when nearly stopped close to it, reset once farther than 10 m."""

    config: ExpertConfig
    cleared: bool = False

    def target_speed(self, desired_speed: float, ego_speed: float, ego_location: np.ndarray,
                     sign: TrafficSignInfo | None) -> tuple[float, float]:
        """(target speed, Euclidean distance to the trigger centre) for the route's next stop sign."""
        if sign is None:
            return desired_speed, float("inf")
        cfg = self.config
        distance = float(np.linalg.norm(stop_sign_centre(sign) - np.asarray(ego_location, dtype=np.float64)))
        if distance > cfg.stop_sign_unclearing_distance:
            self.cleared = False
        elif ego_speed < cfg.stop_sign_clearing_speed and distance < cfg.stop_sign_clearing_distance:
            self.cleared = True
        if self.cleared:
            return desired_speed, distance
        target = idm_target_speed(cfg, desired_speed, ego_speed, 0.0, 0.0, distance, cfg.idm_stop_sign_s0,
                                  cfg.idm_stop_sign_T)
        return target, distance
