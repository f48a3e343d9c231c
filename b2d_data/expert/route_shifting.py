"""Lateral shifts of the dense route into a neighbouring lane (expert-and-scenarios.md §1.9).

A shift over route points [start, end) moves each point toward the neighbouring lane's centre by a factor
f·k, where k ramps with a cosine, ``k = (1 − cos(π·x)) / 2``, over the transition length at both ends.
Points inside the ramps get CHANGELANE commands (which switches the forecast into "near lane change" mode).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from b2d_data.expert.route_processing import DenseRoute
from b2d_data.format.road_option import RoadOption

if TYPE_CHECKING:
    from b2d_data.maps import Waypoint


def smooth_transition(x: float) -> float:
    """Cosine ramp from 0 (x = 0) to 1 (x = 1)."""
    return 0.5 - math.cos(x * math.pi) / 2.0


def _neighbour_centre(wp: Waypoint, to_left: bool) -> np.ndarray:
    other = wp.get_left_lane() if to_left else wp.get_right_lane()
    loc = (other if other is not None else wp).transform.location
    return np.array([loc.x, loc.y, loc.z])


def shift_route_smoothly(route: DenseRoute, start: int, end: int, to_left: bool, transition: int,
                         factor: float = 1.0) -> None:
    """Shift route points [start, end) toward the left/right lane centre by ``factor`` with cosine ramps."""
    change = RoadOption.CHANGELANELEFT if to_left else RoadOption.CHANGELANERIGHT
    back = RoadOption.CHANGELANERIGHT if to_left else RoadOption.CHANGELANELEFT
    transition = max(1, transition)
    for idx in range(max(0, start), min(end, len(route))):
        k = 1.0
        if idx <= start + transition and idx - start < end - idx:
            k = smooth_transition((idx - start) / transition)
            route.commands[idx] = change
        elif idx >= end - transition:
            k = smooth_transition((end - idx) / transition)
            route.commands[idx] = back
        target = _neighbour_centre(route.waypoint(idx), to_left)
        route.points[idx] = factor * k * target + (1.0 - factor * k) * route.points[idx]


def shift_route_around_actors(route: DenseRoute, first_location: np.ndarray, first_half_length: float,
                              last_location: np.ndarray | None, last_half_length: float, obstacle_side: str,
                              transition: int, factor: float = 1.0, extra_before: int = 0,
                              extra_after: int = 0) -> tuple[int, int]:
    """Shift away from the obstacle side around the actors; returns the shift's (start, end) route indices.

    The shift starts ``half length + transition + extra_before`` points before the first actor's route index
    and ends the same way after the last actor (or after the first one when there is no last actor).
    """
    ppm = route.config.points_per_meter
    tail = route.original_points[route.index :, :2]
    first_idx = route.index + int(np.argmin(np.linalg.norm(tail - np.asarray(first_location)[None, :2], axis=1)))
    start = first_idx - int(first_half_length * ppm + transition + extra_before)
    if last_location is None:
        end = first_idx + int(first_half_length * ppm + transition + extra_after)
    else:
        last_idx = route.closest_index(first_idx, last_location)
        end = last_idx + int(last_half_length * ppm + transition + extra_after)
    shift_route_smoothly(route, start, end, obstacle_side == "right", transition, factor)
    return start, end


def still_before_shift(route: DenseRoute, position: np.ndarray, blocker: np.ndarray, tolerance: float,
                       lookahead: float) -> bool:
    """True when the ego has planned a lane shift but not started to drive it, and ``blocker`` is not in its lane.

    That is: the ego is within ``tolerance`` m of the unshifted route, the route is shifted within ``lookahead`` m
    ahead of its index, and the blocking vehicle's centre is more than half a lane from the unshifted route (within
    50 m of the ego along it), i.e. in the lane the shift goes to rather than the obstacle the shift goes around.
    """
    index = route.index
    if float(np.linalg.norm(np.asarray(position)[:2] - route.original_points[index, :2])) > tolerance:
        return False
    end = index + route.config.points(lookahead)
    if not np.any(route.points[index:end] != route.original_points[index:end]):
        return False
    window = route.config.points(50.0)
    lane = route.original_points[max(0, index - window) : index + window, :2]
    offset = float(np.min(np.linalg.norm(lane - np.asarray(blocker)[None, :2], axis=1)))
    return offset > 0.5 * float(route.waypoint(index).lane_width)


def extend_shift(route: DenseRoute, previous_end: int, target_end: int, to_left: bool, transition: int) -> int:
    """Keep the route fully shifted from ``previous_end`` on and ramp back over the last transition before the end.

    The end is ``max(target_end, previous_end + transition)``; the stretch is rewritten from the original points,
    so calling this every frame with a growing target extends the shift smoothly. Returns the index where the
    returning ramp starts (the ``previous_end`` of the next call).
    """
    back = RoadOption.CHANGELANERIGHT if to_left else RoadOption.CHANGELANELEFT
    transition = max(1, transition)
    end = max(target_end, previous_end + transition)
    for idx in range(max(0, previous_end), min(end, len(route))):
        k = 1.0
        if end - idx < transition:
            k = smooth_transition((end - idx) / transition)
            route.commands[idx] = back
        else:
            route.commands[idx] = route.original_commands[idx]
        target = _neighbour_centre(route.waypoint(idx), to_left)
        route.points[idx] = k * target + (1.0 - k) * route.original_points[idx]
    return end - transition


def shift_route_for_invading_turn(route: DenseRoute, first_location: np.ndarray, last_location: np.ndarray,
                                  offset: float) -> tuple[int, int]:
    """Offset the route to the right by |offset| from 15 m before the first cone to 10 m after the last (§1.9).

    With ``invading_turn_shift_from_trigger`` the shift starts at the ego's route point instead when that comes
    first (see the config), and ``invading_turn_extra_shift`` is added to the offset. Next to a shoulder the offset is reduced by 0.3 m and capped at the shoulder's width (a fence may stand
    there). Returns the shifted index range.
    """
    from b2d_data.maps import LaneType

    cfg = route.config
    first_idx = route.closest_index(route.index, first_location)
    last_idx = route.closest_index(first_idx + cfg.points(cfg.invading_turn_search_offset), last_location)
    start = max(0, first_idx - cfg.points(cfg.invading_turn_start))
    if cfg.invading_turn_shift_from_trigger:
        start = min(start, route.index)
    end = min(len(route) - 1, last_idx + cfg.points(cfg.invading_turn_end))
    for idx in range(start, end):
        d = route.points[idx + 1, :2] - route.points[idx, :2]
        norm = float(np.linalg.norm(d))
        if norm < 1e-9:
            continue
        right = np.array([-d[1], d[0]]) / norm  # CARLA's frame: +90° (clockwise seen from above) is right
        amount = abs(offset) + cfg.invading_turn_extra_shift
        right_lane = route.waypoint(idx).get_right_lane()
        if right_lane is not None and right_lane.lane_type == LaneType.SHOULDER:
            amount = min(amount - cfg.invading_turn_fence_margin, right_lane.lane_width)
        route.points[idx, :2] += right * abs(amount)
    return start, end
