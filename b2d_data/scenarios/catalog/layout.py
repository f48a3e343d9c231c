"""Scenario layouts: what a scenario type needs from a town, the lane tests layouts share, and their registry.

Each catalog family registers its types' :class:`Layout` records with :func:`register_layouts` beside its
scenarios, with the checks that find its places; :mod:`~b2d_data.scenarios.placement` searches towns for them and
builds routes. This module builds only on :mod:`.road_geometry`, so a family module imports it without pulling in
placement (which imports the whole catalog).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from b2d_data.maps import LaneType, Map, Waypoint
from b2d_data.scenarios.catalog.road_geometry import (
    JunctionLane,
    is_driving,
    is_outermost_driving,
    lane_walk,
    move_along,
    opposite_driving_neighbour,
    same_direction_driving_neighbour,
)

#: Spacing of route keypoints, as in Bench2Drive's route files (m).
KEYPOINT_SPACING = 2.0
#: Step of the lane walks that check a stretch (m).
CHECK_STEP = 5.0
#: Obstacle/highway routes are about this long (m).
ROUTE_LENGTH = 150.0
#: Largest heading change (deg) over the stretch of an obstacle scenario ("straight-ish").
STRAIGHTISH = 30.0


@dataclass(frozen=True)
class Layout:
    """What a scenario type needs from the town.

    Straight layouts: ``lane_ok`` must hold at the trigger and every 5 m over ``clear_after`` m (junction-free, turning
    by at most ``max_turn`` degrees), the lane must be junction-free ``clear_before`` m back, and ``extra`` (if any)
    must accept the trigger.
    Junction layouts: connections with a turn in ``turns``, signalised or not (``signalized``), with a stop sign
    on the approach (``stop_sign``), accepted by ``junction_extra`` (which may return fixed parameters).
    """

    name: str
    description: str
    lane_ok: Callable[[Waypoint], bool] | None = None
    clear_before: float = 20.0
    clear_after: float = 100.0
    pre: tuple[float, float] = (10.0, 14.0)
    length: float = ROUTE_LENGTH
    extra: Callable[[Map, Waypoint], bool] | None = None
    #: Largest heading change (deg) allowed over the ``clear_after`` stretch (None: any).
    max_turn: float | None = None
    turns: tuple[str, ...] = ()
    signalized: bool | None = None
    stop_sign: bool = False
    approach: tuple[float, float] = (30.0, 38.0)
    departure: tuple[float, float] = (22.0, 30.0)
    trigger_offset: tuple[float, float] = (2.0, 8.0)
    junction_extra: Callable[[JunctionLane, list[JunctionLane]], list[dict[str, dict[str, str]]]] | None = None
    #: Straight layouts: builds the planned lane path from the trigger instead of following its lane (None: no path).
    path_builder: Callable[[Waypoint, np.random.Generator, float], list[Waypoint] | None] | None = None
    #: Junction layouts: a further check of the connection in its town (e.g. an interurban road's speed limit).
    junction_ok: Callable[[Map, JunctionLane, list[JunctionLane]], bool] | None = None
    #: Junction layouts: after the junction the route keeps its exit lane this far (m), then changes into the lane
    #: on its left (an on-ramp's acceleration lane into the highway); None: it stays on the exit lane.
    merge_left_after: tuple[float, float] | None = None
    #: Junction layouts: builds the planned lane path and trigger itself (e.g. with lane changes; None: the lane).
    route_path: Callable[[JunctionLane, np.random.Generator], tuple[list[Waypoint], Waypoint] | None] | None = None
    #: Parameters that depend on the planned path (e.g. a flow starting behind the route's start).
    path_parameters: Callable[[JunctionLane | None, list[Waypoint]], dict[str, dict[str, str]] | None] | None = None
    #: Straight layouts with a ``direction``: the lane test each drawn side needs instead of ``lane_ok`` (the
    #: candidate search takes any side the parameter set draws, each route checks its own side).
    directions: Mapping[str, Callable[[Waypoint], bool]] | None = None
    #: Straight layouts with ``directions``: the sides that ``extra`` and ``reach_ok`` check (None: every side). The
    #: other sides' lane tests carry their own side's check (e.g. a parking lane on the left at every point).
    extra_sides: tuple[str, ...] | None = None
    #: Straight layouts: the parameter (m) placing the scenario's actors along the route. ``clear_before``,
    #: ``clear_after``, ``length`` and ``extra`` are sized for bench2drive220's values; a larger value lengthens
    #: the junction-free stretch ahead by ``reach_ahead`` m and behind by ``reach_behind`` m per metre beyond.
    reach_param: str | None = None
    reach_ahead: float = 1.0
    reach_behind: float = 0.0
    #: Straight layouts: ``extra`` for a ``reach_param`` value outside bench2drive220's range (None: no check).
    reach_ok: Callable[[Map, Waypoint, float], bool] | None = None
    #: Straight layouts: beyond ``clear_before``/``clear_after`` the lengthened stretch may cross junctions
    #: straight on (no turn beyond ``max_turn``, ``lane_ok`` outside them), and the walk back must lead forward to
    #: the trigger again (a vehicle spawned there on its lane reaches the ego's lane).
    reach_through_junctions: bool = False

    @property
    def is_junction(self) -> bool:
        """Junction layouts have turns."""
        return bool(self.turns)


#: The layout of each implemented scenario type, filled by the catalog's :func:`register_layouts` calls.
LAYOUTS: dict[str, Layout] = {}


def register_layouts(layouts: Mapping[str, Layout]) -> None:
    """Add scenario types' layouts to :data:`LAYOUTS` (a type registered twice is an error)."""
    for scenario_type, layout in layouts.items():
        if scenario_type in LAYOUTS:
            raise ValueError(f"a layout for {scenario_type!r} is registered already")
        LAYOUTS[scenario_type] = layout


#: Layouts that replace a type's :data:`LAYOUTS` entry under one parameter set, keyed (set name, type): where the
#: reference's routes of that set put the type on other roads than our default layout (EnterActorFlow's 36
#: routes_training routes all join Town12's highway by on-ramps; bench2drive220's include urban turns).
PARAM_LAYOUTS: dict[tuple[str, str], Layout] = {}


def register_param_layouts(params: str, layouts: Mapping[str, Layout]) -> None:
    """Add layouts used instead of the default ones under the parameter set named ``params``."""
    for scenario_type, layout in layouts.items():
        if (params, scenario_type) in PARAM_LAYOUTS:
            raise ValueError(f"a {params!r} layout for {scenario_type!r} is registered already")
        PARAM_LAYOUTS[(params, scenario_type)] = layout


def layout_of(scenario_type: str, params: str) -> Layout:
    """The layout ``scenario_type`` uses under the parameter set named ``params`` (KeyError: none registered)."""
    return PARAM_LAYOUTS.get((params, scenario_type)) or LAYOUTS[scenario_type]


def multi_lane_left(wp: Waypoint) -> bool:
    """A driving lane with a same-direction driving lane on its left."""
    return is_driving(wp) and same_direction_driving_neighbour(wp, "left") is not None


def multi_lane_right(wp: Waypoint) -> bool:
    """A driving lane with a same-direction driving lane on its right."""
    return is_driving(wp) and same_direction_driving_neighbour(wp, "right") is not None


def multi_lane_rightmost(wp: Waypoint) -> bool:
    """The rightmost driving lane of two or more same-direction lanes."""
    return multi_lane_left(wp) and is_outermost_driving(wp, "right")


def multi_lane_any(wp: Waypoint) -> bool:
    """A driving lane with a same-direction driving lane beside it."""
    return is_driving(wp) and (
        same_direction_driving_neighbour(wp, "left") is not None
        or same_direction_driving_neighbour(wp, "right") is not None
    )


def two_way_single(wp: Waypoint) -> bool:
    """A driving lane alone in its direction with an opposite driving lane beside it."""
    return (
        is_driving(wp)
        and opposite_driving_neighbour(wp) is not None
        and same_direction_driving_neighbour(wp, "left") is None
        and same_direction_driving_neighbour(wp, "right") is None
    )


def rightmost(wp: Waypoint) -> bool:
    """The rightmost driving lane of its direction."""
    return is_driving(wp) and is_outermost_driving(wp, "right")


def any_lane(wp: Waypoint) -> bool:
    """Any driving lane."""
    return is_driving(wp)


def leftmost_beside_parking(wp: Waypoint) -> bool:
    """The leftmost driving lane of its direction with a parking lane on its left (a one-way road's left kerb:
    ``direction`` left of the parking scenarios; a two-way road's left is the opposite lane)."""
    if not is_driving(wp) or not is_outermost_driving(wp, "left"):
        return False
    parking = wp.get_left_lane()
    return parking is not None and bool(parking.lane_type & LaneType.PARKING)


def parking_ahead(distances: Sequence[float]) -> Callable[[Map, Waypoint], bool]:
    """A parking lane on the right at each of ``distances`` m after the trigger."""

    def check(town: Map, wp: Waypoint) -> bool:
        for distance in distances:
            ahead = move_along(wp, distance, step=2.0)
            parking = ahead.get_right_lane() if ahead is not None else None
            if parking is None or not parking.lane_type & LaneType.PARKING:
                return False
        return True

    return check


def xml_location(wp: Waypoint) -> dict[str, str]:
    """A waypoint's location as route-XML attributes (0.1 m)."""
    loc = wp.transform.location
    return {"x": f"{loc.x:.1f}", "y": f"{loc.y:.1f}", "z": f"{loc.z:.1f}"}


def signal_lanes(signals: Iterable[Any]) -> set[tuple[int, int]]:
    """The (road, lane) keys that the signals reference."""
    return {(lane.road_id, lane.lane_id) for s in signals for lane in s.lanes}


def _departure(
    exit_wp: Waypoint, length: float, merge_left_after: tuple[float, float] | None, rng: np.random.Generator
) -> list[Waypoint] | None:
    """Lane points 2 m apart over ``length`` m from a junction exit, changing into the left lane on the way when
    ``merge_left_after`` asks for it (None when that lane is missing)."""
    step = KEYPOINT_SPACING
    if merge_left_after is None:
        return lane_walk(exit_wp, length, step=step)
    keep = float(rng.uniform(*merge_left_after))
    own = lane_walk(exit_wp, keep, step=step)
    left = same_direction_driving_neighbour(own[-1], "left")
    if left is None:
        return None
    # the next keypoint is one step ahead on the left lane: the planner makes the change between the two
    return own + lane_walk(left, length - keep, step=step)[1:]


def through_junction(
    conn: JunctionLane,
    departure: float,
    min_departure: float,
    merge_left_after: tuple[float, float] | None = None,
    rng: np.random.Generator | None = None,
) -> list[Waypoint] | None:
    """Lane waypoints 2 m apart through ``conn`` and ``departure`` m beyond it, changing left on the way as
    :func:`_departure` does when ``merge_left_after`` is given (None when the lane ends within ``min_departure``
    m or meets another junction)."""
    step = KEYPOINT_SPACING
    inside = [conn.start]
    while inside[-1].is_junction and len(inside) < 200:
        options = [o for o in inside[-1].next(step) if o.road_id == conn.start.road_id or not o.is_junction]
        if not options:
            break
        inside.append(options[0])
    after = _departure(conn.exit, departure, merge_left_after, rng)
    if after is None or any(wp.is_junction for wp in after) or len(after) * step < min_departure:
        return None
    return [wp for wp in inside if wp.is_junction] + after
