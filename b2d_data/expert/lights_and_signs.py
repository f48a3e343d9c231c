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
from b2d_data.sim.traffic_rules import stop_affects, stop_trigger_centre, stop_zone_waypoints

if TYPE_CHECKING:
    from b2d_data.maps import Map


def stop_sign_centre(sign: TrafficSignInfo) -> np.ndarray:
    """World position of the sign's trigger-volume centre, as an array."""
    return stop_trigger_centre(sign).to_array()


def stop_sign_affects(town: Map, location: np.ndarray, sign: TrafficSignInfo) -> bool:
    """RunningStopTest's test at ``location`` (the shared definition in ``sim/traffic_rules.py``)."""
    return stop_affects(stop_zone_waypoints(town, Location(*np.asarray(location, dtype=np.float64))), sign)


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
