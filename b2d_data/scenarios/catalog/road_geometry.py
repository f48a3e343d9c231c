"""Lane and junction queries shared by the scenarios and the placement search (scenario_runner's scenario_helper).

Conventions: CARLA frame, yaw in degrees clockwise seen from above, so a right turn increases the yaw and the
right vector of a heading ``yaw`` is ``(-sin yaw, cos yaw)``. "Same direction" lanes have lane ids of the same sign
on the same road section, as CARLA's ``lane_id * other.lane_id > 0`` test.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import Junction, LaneType, Map, Waypoint
from b2d_data.sim.api import TrafficLightInfo

#: Below this heading change a junction connection counts as going straight (CARLA's planner uses 35°).
STRAIGHT_ANGLE = 35.0
#: Beyond this heading change a connection is a U-turn.
UTURN_ANGLE = 150.0


def yaw_diff(a: float, b: float) -> float:
    """``b − a`` wrapped to (−180, 180] degrees (positive: ``b`` is turned to the right of ``a``)."""
    d = (b - a + 180.0) % 360.0 - 180.0
    return 180.0 if d == -180.0 else d


def offset_transform(
    base: Transform | Waypoint, lateral: float = 0.0, forward: float = 0.0, z: float = 0.0, yaw: float = 0.0
) -> Transform:
    """A pose ``lateral`` m to the right (negative: left), ``forward`` m ahead and ``z`` m above ``base``, turned."""
    t = base.transform if isinstance(base, Waypoint) else base
    r = math.radians(t.rotation.yaw)
    loc = t.location
    x = loc.x + math.cos(r) * forward - math.sin(r) * lateral
    y = loc.y + math.sin(r) * forward + math.cos(r) * lateral
    return Transform(Location(x, y, loc.z + z), Rotation(pitch=0.0, yaw=t.rotation.yaw + yaw, roll=0.0))


def lateral_offset(a: Waypoint, b: Waypoint) -> float:
    """Signed lateral offset (m, + right of ``a``'s heading) of ``b``'s centre from ``a``'s centre."""
    r = math.radians(a.transform.rotation.yaw)
    dx = b.transform.location.x - a.transform.location.x
    dy = b.transform.location.y - a.transform.location.y
    return -math.sin(r) * dx + math.cos(r) * dy


def same_direction(a: Waypoint, b: Waypoint) -> bool:
    """Whether two lanes of one road section carry traffic the same way."""
    return a.lane_id * b.lane_id > 0


def is_driving(wp: Waypoint | None) -> bool:
    """A driving lane."""
    return wp is not None and bool(wp.lane_type & LaneType.DRIVING)


def neighbour(wp: Waypoint, side: str) -> Waypoint | None:
    """The lane to the ``side`` ('left'/'right') of the driving direction."""
    return wp.get_left_lane() if side == "left" else wp.get_right_lane()


def same_direction_driving_neighbour(wp: Waypoint, side: str) -> Waypoint | None:
    """The driving lane on ``side`` that carries traffic the same way, or None."""
    other = neighbour(wp, side)
    return other if is_driving(other) and same_direction(wp, other) else None


def opposite_driving_neighbour(wp: Waypoint) -> Waypoint | None:
    """The driving lane to the left that carries opposite traffic (two-way roads), or None."""
    other = wp.get_left_lane()
    return other if is_driving(other) and not same_direction(wp, other) else None


def is_outermost_driving(wp: Waypoint, side: str = "right") -> bool:
    """No same-direction driving lane lies further to ``side``."""
    return same_direction_driving_neighbour(wp, side) is None


def outermost_lane(wp: Waypoint, side: str = "right") -> Waypoint:
    """The last lane (any type) reached walking to ``side`` over lanes of the same direction."""
    current = wp
    while True:
        other = neighbour(current, side)
        if other is None or not same_direction(current, other) or other.lane_type == LaneType.NONE:
            return current
        current = other


def find_side_lane(wp: Waypoint, side: str, lane_type: LaneType) -> Waypoint | None:
    """The first lane of ``lane_type`` walking to ``side`` over lanes of the same direction, or None."""
    current = wp
    while True:
        other = neighbour(current, side)
        if other is None or not same_direction(current, other):
            return None
        if other.lane_type & lane_type:
            return other
        current = other


def walk_to_sidewalk(wp: Waypoint, side: str) -> list[Waypoint] | None:
    """The lanes from ``wp`` to ``side`` up to the first sidewalk or the road's edge, over lanes of any type and
    direction (LB2.0 DynamicObjectCrossing's walk, object_crash_vehicle.py); None where the walk would go round in a
    circle: lanes ±1 are each other's left lane, so walking left across the centre line never reaches a sidewalk
    (the reference's loop does not end there)."""
    walk = [wp]
    while not walk[-1].lane_type & LaneType.SIDEWALK:
        other = neighbour(walk[-1], side)
        if other is None:
            break
        if any(other.lane_id == w.lane_id for w in walk):
            return None
        walk.append(other)
    return walk


def same_direction_lanes(wp: Waypoint) -> list[Waypoint]:
    """Every driving lane of the road section that carries traffic like ``wp`` (scenario_helper.get_same_dir_lanes)."""
    lanes = [wp]
    for side in ("left", "right"):
        current = wp
        while True:
            other = same_direction_driving_neighbour(current, side)
            if other is None:
                break
            lanes.append(other)
            current = other
    return lanes


def straightest(options: Sequence[Waypoint], yaw: float) -> Waypoint | None:
    """The option whose heading differs least from ``yaw``."""
    if not options:
        return None
    return min(options, key=lambda o: abs(yaw_diff(yaw, o.transform.rotation.yaw)))


def move_along(wp: Waypoint, distance: float, forward: bool = True, step: float = 1.0) -> Waypoint | None:
    """The waypoint ``distance`` m ahead (or behind) along the lane, straightest branch at forks; None at a dead end."""
    current = wp
    remaining = distance
    while remaining > 1e-6:
        d = min(step, remaining)
        options = current.next(d) if forward else current.previous(d)
        nxt = straightest(options, current.transform.rotation.yaw)
        if nxt is None:
            return None
        current = nxt
        remaining -= d
    return current


def walk_through_junctions(wp: Waypoint, distance: float) -> Waypoint:
    """scenario_runner's ``get_location_in_distance_from_wp(wp, distance, stop_at_junction=False)``: 1 m steps
    through junctions until the steps' straight-line lengths add up to ``distance``; where the lane ends, its end.

    The reference takes ``next(1.0)[-1]`` at a fork; here the straightest branch stands for it (CARLA's order of
    the branches is its own), as :func:`move_along` does for ``next(d)[0]``. A sum short of ``distance`` by less
    than 1 mm counts as reached: the steps' lengths carry rounding errors (ours a little under 1 m each), and
    whether a whole ``distance`` takes one step more would otherwise depend on them.
    """
    current, travelled = wp, 0.0
    while travelled < distance - 1e-3:
        nxt = straightest(current.next(1.0), current.transform.rotation.yaw)
        if nxt is None:
            break
        travelled += nxt.transform.location.distance(current.transform.location)
        current = nxt
    return current


def lane_walk(wp: Waypoint, distance: float, forward: bool = True, step: float = 1.0) -> list[Waypoint]:
    """Waypoints every ``step`` m along the lane (straightest branch), starting with ``wp``; stops at a dead end."""
    out = [wp]
    current = wp
    walked = 0.0
    while walked < distance - 1e-6:
        options = current.next(step) if forward else current.previous(step)
        nxt = straightest(options, current.transform.rotation.yaw)
        if nxt is None:
            break
        out.append(nxt)
        current = nxt
        walked += step
    return out


def move_before_junction(wp: Waypoint, distance: float, forward: bool = True) -> Waypoint:
    """Up to ``distance`` m along the lane in 1 m steps, stopping at the last point before a junction or dead end.

    scenario_runner's ``_move_waypoint_forward`` / ``_move_waypoint_backwards`` (OppositeActorFlow and the obstacle
    scenarios): a step that would land inside a junction is not taken, so the result is never in one unless ``wp``
    is.
    """
    current = wp
    walked = 0.0
    while walked < distance - 1e-6:
        options = current.next(1.0) if forward else current.previous(1.0)
        nxt = straightest(options, current.transform.rotation.yaw)
        if nxt is None or nxt.is_junction:
            break
        current = nxt
        walked += 1.0
    return current


def heading_change(waypoints: Sequence[Waypoint]) -> float:
    """Largest heading difference (deg) between any waypoint and the first one."""
    if not waypoints:
        return 0.0
    yaw0 = waypoints[0].transform.rotation.yaw
    return max(abs(yaw_diff(yaw0, wp.transform.rotation.yaw)) for wp in waypoints)


# ------------------------------------------------------------------------------------------------ junctions


@dataclass(frozen=True, eq=False)
class JunctionLane:
    """One lane through a junction: the lane waypoints just before and after it and the turn it makes."""

    junction_id: int
    start: Waypoint  # first waypoint inside the junction
    end: Waypoint  # last waypoint inside the junction
    entry: Waypoint  # on the incoming lane, just outside the junction
    exit: Waypoint  # on the outgoing lane, just outside the junction
    angle: float  # heading change from entry to exit (deg, + right)

    @property
    def turn(self) -> str:
        """'straight', 'left', 'right' or 'uturn'."""
        if abs(self.angle) < STRAIGHT_ANGLE:
            return "straight"
        if abs(self.angle) > UTURN_ANGLE:
            return "uturn"
        return "right" if self.angle > 0 else "left"


def _leave_junction(wp: Waypoint, forward: bool, step: float = 0.5, limit: int = 200) -> Waypoint | None:
    current = wp
    for _ in range(limit):
        if not current.is_junction:
            return current
        options = current.next(step) if forward else current.previous(step)
        nxt = straightest(options, current.transform.rotation.yaw)
        if nxt is None:
            return None
        current = nxt
    return None


def junction_lanes(junction: Junction) -> list[JunctionLane]:
    """Every driving connection of a junction with its entry/exit lane waypoints and turn."""
    out = []
    for start, end in junction.get_waypoints(LaneType.DRIVING):
        entry = _leave_junction(start, forward=False)
        exit_ = _leave_junction(end, forward=True)
        if entry is None or exit_ is None:
            continue
        angle = yaw_diff(entry.transform.rotation.yaw, exit_.transform.rotation.yaw)
        out.append(JunctionLane(junction.id, start, end, entry, exit_, angle))
    return out


def same_lane(a: Waypoint, b: Waypoint) -> bool:
    """Same road and lane id."""
    return (a.road_id, a.lane_id) == (b.road_id, b.lane_id)


def entry_direction(ego_entry: Waypoint, other_entry: Waypoint) -> str:
    """Where another entry comes from, seen from the ego's entry: 'left', 'right', 'opposite' or 'same'.

    A vehicle coming from the ego's left drives toward its right, i.e. its heading is the ego's turned right.
    """
    d = yaw_diff(ego_entry.transform.rotation.yaw, other_entry.transform.rotation.yaw)
    if abs(d) < 45.0:
        return "same"
    if abs(d) > 135.0:
        return "opposite"
    return "left" if d > 0 else "right"


def entries_from(lanes: Iterable[JunctionLane], ego_entry: Waypoint, direction: str) -> list[Waypoint]:
    """Distinct entry lanes of a junction coming from ``direction`` relative to the ego's entry."""
    seen: set[tuple[int, int]] = set()
    out = []
    for lane in lanes:
        key = (lane.entry.road_id, lane.entry.lane_id)
        if key in seen or same_lane(lane.entry, ego_entry):
            continue
        if entry_direction(ego_entry, lane.entry) == direction:
            seen.add(key)
            out.append(lane.entry)
    return out


def connection(lanes: Iterable[JunctionLane], entry: Waypoint, turn: str | None) -> JunctionLane | None:
    """The straightest connection leaving ``entry``'s lane with the given turn (None: any turn)."""
    matches = [lane for lane in lanes if same_lane(lane.entry, entry) and turn in (None, lane.turn)]
    if not matches:
        return None
    return min(matches, key=lambda lane: abs(lane.angle))


def straightest_connection(lanes: Iterable[JunctionLane], entry: Waypoint) -> JunctionLane | None:
    """The connection leaving ``entry``'s lane with the smallest heading change, whatever its angle, or None.

    LB2.0's ``generate_target_waypoint(source, 0)`` (scenario_helper.py ``choose_at_junction``) takes the branch
    closest to straight ahead without a limit, so a lane that only turns gives its flattest turn. Placement's layout
    checks keep :func:`connection` with ``"straight"`` (under :data:`STRAIGHT_ANGLE`).
    """
    return connection(lanes, entry, None)


def flow_into_exit(
    lanes: Iterable[JunctionLane], entry: Waypoint, exit_: Waypoint | None, turn: str = "right"
) -> JunctionLane | None:
    """The connection with ``turn`` from ``entry``'s lane onto ``exit_``'s road and direction (its lane if
    possible), or None."""
    if exit_ is None:
        return None
    matches = [
        lane for lane in lanes
        if same_lane(lane.entry, entry) and lane.turn == turn and lane.exit.road_id == exit_.road_id
        and lane.exit.lane_id * exit_.lane_id > 0
    ]  # fmt: skip
    if not matches:
        return None
    return min(matches, key=lambda lane: (lane.exit.lane_id != exit_.lane_id, abs(lane.angle)))


def first_junction_ahead(wp: Waypoint, max_distance: float, step: float = 1.0) -> tuple[Waypoint, float] | None:
    """The first junction waypoint along the lane (straightest branches) and its distance, within ``max_distance``."""
    current = wp
    travelled = 0.0
    while travelled <= max_distance:
        if current.is_junction:
            return current, travelled
        nxt = straightest(current.next(step), current.transform.rotation.yaw)
        if nxt is None:
            return None
        current = nxt
        travelled += step
    return None


def junction_lights(lights: Mapping[int, TrafficLightInfo], town: Map, junction: Junction) -> list[TrafficLightInfo]:
    """The traffic lights of a junction: those whose OpenDRIVE signal belongs to it, else those stopping traffic
    within 15 m of its box."""
    out = []
    for info in lights.values():
        signal = town.signal(info.opendrive_id) if info.opendrive_id else None
        if signal is not None and signal.junction_id == junction.id:
            out.append(info)
    if out:
        return sorted(out, key=lambda i: i.id)
    box = junction.bounding_box
    c, e = box.location, box.extent
    for info in lights.values():
        for wp in info.stop_waypoints:
            loc = wp.transform.location
            if abs(loc.x - c.x) <= e.x + 15.0 and abs(loc.y - c.y) <= e.y + 15.0:
                out.append(info)
                break
    return sorted(out, key=lambda i: i.id)


def light_of_lane(lights: Sequence[TrafficLightInfo], wp: Waypoint) -> TrafficLightInfo | None:
    """The light governing ``wp``'s lane (a stop waypoint on the same road and lane), else the nearest one."""
    best, best_d = None, math.inf
    for info in lights:
        for stop in info.stop_waypoints:
            d = stop.transform.location.distance_2d(wp.transform.location)
            if same_lane(stop, wp):
                d -= 1000.0  # a light on the very lane always wins
            if d < best_d:
                best, best_d = info, d
    return best


def line_intersection(a: Transform | Waypoint, b: Transform | Waypoint) -> Location | None:
    """Where the lines through two poses along their headings cross (None when parallel)."""
    ta = a.transform if isinstance(a, Waypoint) else a
    tb = b.transform if isinstance(b, Waypoint) else b
    ra, rb = math.radians(ta.rotation.yaw), math.radians(tb.rotation.yaw)
    d1 = (math.cos(ra), math.sin(ra))
    d2 = (math.cos(rb), math.sin(rb))
    den = d1[0] * d2[1] - d1[1] * d2[0]
    if abs(den) < 1e-3:
        return None
    px, py = tb.location.x - ta.location.x, tb.location.y - ta.location.y
    t = (px * d2[1] - py * d2[0]) / den
    return Location(ta.location.x + t * d1[0], ta.location.y + t * d1[1], ta.location.z)
