"""Every layout a preset promises, found through the project's OpenDRIVE loader (``b2d_data.maps.load_opendrive``).

Each detector below looks for one road layout of expert-and-scenarios.md §2 with the CARLA-like map API only
(waypoints, neighbours, junctions, signals, crosswalks, routes), the way scenario placement would.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import pytest

from b2d_data.format.road_option import RoadOption
from b2d_data.maps import LaneType, Map, Waypoint, load_opendrive
from b2d_data.maps.towngen import TOWN_PRESETS, write_town
from b2d_data.maps.towngen import presets as P

STEP = 5.0


@pytest.fixture(scope="module")
def maps(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Map]:
    folder = tmp_path_factory.mktemp("towns")
    return {name: load_opendrive(write_town(name, 0, folder)) for name in TOWN_PRESETS}


# -- helpers ---------------------------------------------------------------------------------------------------------


def _yaw_change(a: Waypoint, b: Waypoint) -> float:
    return (b.transform.rotation.yaw - a.transform.rotation.yaw + 180.0) % 360.0 - 180.0


def _same_direction_driving(w: Waypoint, other: Waypoint | None) -> bool:
    return other is not None and bool(other.lane_type & LaneType.DRIVING) and abs(_yaw_change(w, other)) < 90.0


def _opposite_driving(w: Waypoint, other: Waypoint | None) -> bool:
    return other is not None and bool(other.lane_type & LaneType.DRIVING) and abs(_yaw_change(w, other)) > 90.0


def _walk(w: Waypoint, distance: float) -> list[Waypoint] | None:
    """Waypoints every STEP metres along the lane; None when it branches or enters a junction first."""
    out = [w]
    while len(out) * STEP <= distance:
        nxt = out[-1].next(STEP)
        if len(nxt) != 1 or nxt[0].is_junction:
            return None
        out.append(nxt[0])
    return out


def _right_types(w: Waypoint) -> list[LaneType]:
    types, cur = [], w.get_right_lane()
    while cur is not None and len(types) < 6:
        types.append(cur.lane_type)
        cur = cur.get_right_lane()
    return types


def _street_points(m: Map) -> list[Waypoint]:
    return [w for w in m.generate_waypoints(STEP * 4) if not w.is_junction]


def _arms(m: Map, junction_id: int) -> tuple[set[int], set[int], list[tuple[Waypoint, Waypoint, Waypoint, Waypoint]]]:
    """(incoming road ids, outgoing road ids, [(before, entry, exit, after)]) of a junction's driving lanes."""
    incoming: set[int] = set()
    outgoing: set[int] = set()
    moves = []
    for entry, exit_ in m.junctions[junction_id].get_waypoints(LaneType.DRIVING):
        before, after = entry.previous(1.0), exit_.next(1.0)
        if not before or not after:
            continue
        incoming.add(before[0].road_id)
        outgoing.add(after[0].road_id)
        moves.append((before[0], entry, exit_, after[0]))
    return incoming, outgoing, moves


def _junction_ahead(w: Waypoint, distance: float = 20.0) -> int | None:
    cur, walked = w, 0.0
    while walked <= distance:
        if cur.is_junction:
            return cur.junction_id
        nxt = cur.next(1.0)
        if not nxt:
            return None
        cur, walked = nxt[0], walked + 1.0
    return None


def _controls(m: Map) -> tuple[dict[int, set[int]], dict[int, set[int]]]:
    """Junction id -> incoming road ids governed by traffic lights / by stop signs."""
    lights: dict[int, set[int]] = {}
    stops: dict[int, set[int]] = {}
    for sig in m.signals():
        if not (sig.is_traffic_light or sig.is_stop):
            continue
        for lane in sig.lanes:
            jid = _junction_ahead(lane.stop_waypoint)
            if jid is not None:
                (lights if sig.is_traffic_light else stops).setdefault(jid, set()).add(lane.road_id)
    return lights, stops


# -- detectors (each returns a short description of what it found, or None) --------------------------------------


def find_multi_lane(m: Map) -> str | None:
    for w in _street_points(m):
        if _same_direction_driving(w, w.get_left_lane()):
            path = _walk(w, 200.0)
            if path and all(_same_direction_driving(p, p.get_left_lane()) for p in path):
                return f"road {w.road_id} lane {w.lane_id}: 200 m beside a same-direction lane, no junction"
    return None


def find_two_way_street(m: Map) -> str | None:
    for w in _street_points(m):
        if _opposite_driving(w, w.get_left_lane()) and not _same_direction_driving(w, w.get_right_lane()):
            path = _walk(w, 250.0)
            if path and all(
                _opposite_driving(p, p.get_left_lane()) and LaneType.SIDEWALK in _right_types(p) for p in path
            ):
                return f"road {w.road_id}: 250 m of one lane each way with a sidewalk"
    return None


def find_parking(m: Map) -> str | None:
    for w in _street_points(m):
        right = w.get_right_lane()
        if right is not None and right.lane_type == LaneType.PARKING:
            path = _walk(w, 150.0)
            if path and all((r := p.get_right_lane()) is not None and r.lane_type == LaneType.PARKING for p in path):
                return f"road {w.road_id}: parking lane right of lane {w.lane_id} for 150 m"
    return None


def find_shoulder_curve(m: Map) -> str | None:
    for w in _street_points(m):
        right = w.get_right_lane()
        if right is None or right.lane_type != LaneType.SHOULDER or right.lane_width < 0.9:
            continue
        if not _opposite_driving(w, w.get_left_lane()):
            continue
        path = _walk(w, 150.0)
        if not path:
            continue
        straight = all(abs(_yaw_change(w, p)) < 3.0 for p in path[: int(50 / STEP)])
        if straight and abs(_yaw_change(w, path[-1])) > 30.0:
            return f"road {w.road_id}: 50 m straight then a curve, shoulder on the right"
    return None


def find_bike_lane(m: Map) -> str | None:
    lights, _ = _controls(m)
    for lane in m.lane_geometry(lane_type=LaneType.BIKING):
        if not lane.is_junction or lane.junction_id not in lights:
            continue
        mid = lane.centre[len(lane.centre) // 2]
        w = m.get_waypoint(tuple(mid), lane_type=LaneType.BIKING)
        ahead, behind = w.next(30.0), w.previous(30.0)
        if ahead and behind and not ahead[0].is_junction and not behind[0].is_junction:
            if ahead[0].lane_type == behind[0].lane_type == LaneType.BIKING:
                return f"biking lane through signalised junction {lane.junction_id}"
    return None


def find_sidewalk(m: Map) -> str | None:
    total = sum(abs(float(g.s[-1] - g.s[0])) for g in m.lane_geometry(lane_type=LaneType.SIDEWALK))
    beside = any(LaneType.SIDEWALK in _right_types(w) for w in _street_points(m))
    return f"{total:.0f} m of sidewalk" if total > 1000.0 and beside else None


def find_crosswalk(m: Map) -> str | None:
    walks = m.crosswalks()
    for cw in walks:
        cx, cy = cw.polygon[:, 0].mean(), cw.polygon[:, 1].mean()
        inside = any(
            abs(cx - j.bounding_box.location.x) <= j.bounding_box.extent.x + 1.0
            and abs(cy - j.bounding_box.location.y) <= j.bounding_box.extent.y + 1.0
            for j in m.junctions.values()
        )
        if not inside:
            return None
    return f"{len(walks)} crosswalks, all at junctions" if walks else None


def _signalised(m: Map, n_arms: int) -> str | None:
    lights, _ = _controls(m)
    groups = m.traffic_light_groups()
    for jid in m.junctions:
        incoming, outgoing, _ = _arms(m, jid)
        if len(incoming) == n_arms and incoming == outgoing and incoming <= lights.get(jid, set()):
            ids = {sig.id for sig in m.traffic_lights() if sig.junction_id == jid}
            if any(set(members) == ids for members in groups.values()):
                return f"junction {jid}: {n_arms} two-way approaches, each with a light, one controller"
    return None


def find_signalized_4way(m: Map) -> str | None:
    return _signalised(m, 4)


def find_signalized_t(m: Map) -> str | None:
    return _signalised(m, 3)


def _unsignalised(m: Map, n_arms: int, stops_wanted: Callable[[int, int], bool]) -> str | None:
    lights, stops = _controls(m)
    for jid in m.junctions:
        incoming, outgoing, _ = _arms(m, jid)
        if len(incoming | outgoing) != n_arms or jid in lights:
            continue
        stopped = stops.get(jid, set()) & incoming
        if stops_wanted(len(stopped), len(incoming)):
            return f"junction {jid}: {n_arms} arms, {len(stopped)} stop-controlled approaches, no lights"
    return None


def find_stop_4way(m: Map) -> str | None:
    return _unsignalised(m, 4, lambda stopped, _: stopped >= 1)


def find_stop_t(m: Map) -> str | None:
    return _unsignalised(m, 3, lambda stopped, _: stopped == 1)


def find_uncontrolled(m: Map) -> str | None:
    for n in (3, 4):
        found = _unsignalised(m, n, lambda stopped, _: stopped == 0)
        if found:
            return found
    return None


def _lanes_one_way(w: Waypoint) -> int:
    """Driving lanes running the same way as ``w`` on its road at that point (``w`` included)."""
    count = 1
    for step in (Waypoint.get_left_lane, Waypoint.get_right_lane):
        cur = step(w)
        # Lanes on the same side of the reference line (same id sign) run the same way.
        while cur is not None and cur.lane_id * w.lane_id > 0:
            if cur.lane_type & LaneType.DRIVING:
                count += 1
            cur = step(cur)
    return count


def find_highway_ramps(m: Map) -> str | None:
    merge = diverge = None
    for jid in m.junctions:
        _, _, moves = _arms(m, jid)
        # A fast multi-lane carriageway goes straight through the junction...
        through = any(
            _lanes_one_way(b) >= 2
            and _lanes_one_way(a) >= 2
            and abs(_yaw_change(b, a)) < 5.0
            and m.speed_limit(b) >= 80.0
            for b, _, _, a in moves
        )
        for before, _, _, after in moves:
            # ...and a single-lane ramp leaves or joins it at a shallow angle.
            if not through or abs(_yaw_change(before, after)) > 20.0:
                continue
            n_in, n_out = _lanes_one_way(before), _lanes_one_way(after)
            if n_in == 1 and n_out >= 3:
                merge = jid
            if n_in >= 3 and n_out == 1:
                diverge = jid
    if merge is not None and diverge is not None:
        return f"on-ramp merge at junction {merge}, off-ramp diverge at junction {diverge}"
    return None


def find_interurban(m: Map) -> str | None:
    for jid in m.junctions:
        _, _, moves = _arms(m, jid)
        for before, _, _, after in moves:
            fast, left_turn = m.speed_limit(before) >= 70.0, -135.0 < _yaw_change(before, after) < -45.0
            rural = LaneType.SIDEWALK not in _right_types(before) + _right_types(after)
            if not (fast and left_turn and rural and _opposite_driving(before, before.get_left_lane())):
                continue
            start, end = before.previous(40.0), after.next(40.0)
            if not start or not end:
                continue
            route = m.trace_route(start[0].transform.location, end[0].transform.location)
            if RoadOption.LEFT in {option for _, option in route}:
                speed = m.speed_limit(before)
                return f"junction {jid}: left turn off a {speed:.0f} km/h rural road across the opposite lane"
    return None


def _left_kerb(w: Waypoint) -> bool:
    """A driving lane with no driving lane across the centre line, a parking lane on its left on the same side of
    the reference line, and a sidewalk left of that (a one-way road's left kerb)."""
    left = w.get_left_lane()
    if left is None or left.lane_type != LaneType.PARKING or left.lane_id * w.lane_id <= 0:
        return False
    kerb = left.get_left_lane()
    if kerb is None or kerb.lane_type != LaneType.SIDEWALK or kerb.lane_id * w.lane_id <= 0:
        return False
    across = w.get_right_lane()
    while across is not None:
        if across.lane_id * w.lane_id < 0 and across.lane_type & LaneType.DRIVING:
            return False
        across = across.get_right_lane()
    return True


def find_one_way(m: Map) -> str | None:
    for w in _street_points(m):
        if _left_kerb(w):
            path = _walk(w, 150.0)
            if path and all(_left_kerb(p) for p in path):
                return f"road {w.road_id} lane {w.lane_id}: one-way, parking and sidewalk on its left for 150 m"
    return None


DETECTORS: dict[str, Callable[[Map], str | None]] = {
    P.TWO_WAY: find_two_way_street,
    P.PARKING: find_parking,
    P.SHOULDER_CURVE: find_shoulder_curve,
    P.MULTI_LANE: find_multi_lane,
    P.BIKE_LANE: find_bike_lane,
    P.SIDEWALK: find_sidewalk,
    P.CROSSWALK: find_crosswalk,
    P.SIGNALIZED_4WAY: find_signalized_4way,
    P.SIGNALIZED_T: find_signalized_t,
    P.STOP_4WAY: find_stop_4way,
    P.STOP_T: find_stop_t,
    P.UNCONTROLLED: find_uncontrolled,
    P.HIGHWAY_RAMPS: find_highway_ramps,
    P.INTERURBAN: find_interurban,
    P.ONE_WAY: find_one_way,
}


def test_every_layout_has_a_detector() -> None:
    assert set(DETECTORS) == set(P.ALL_LAYOUTS)


@pytest.mark.parametrize(
    ("preset", "layout"), [(name, layout) for name, preset in sorted(TOWN_PRESETS.items()) for layout in preset.layouts]
)
def test_preset_contains_layout(maps: dict[str, Map], preset: str, layout: str) -> None:
    found = DETECTORS[layout](maps[preset])
    assert found, f"{preset}: no {layout}"


def test_detectors_do_not_find_what_is_not_there(maps: dict[str, Map]) -> None:
    # The interurban ring has no sidewalks, crosswalks, lights, ramps or multi-lane roads.
    m = maps["interurban"]
    for layout in (
        P.SIDEWALK,
        P.CROSSWALK,
        P.SIGNALIZED_4WAY,
        P.SIGNALIZED_T,
        P.HIGHWAY_RAMPS,
        P.MULTI_LANE,
        P.PARKING,
    ):
        assert DETECTORS[layout](m) is None, layout


def test_trace_route_crosses_the_whole_default_town(maps: dict[str, Map]) -> None:
    m = maps["all"]
    points = [w for w in m.generate_waypoints(50.0) if not w.is_junction]
    origin = min(points, key=lambda w: w.transform.location.y)  # CARLA y points south: northernmost (highway)
    target = max(points, key=lambda w: w.transform.location.y)  # southernmost (interurban road)
    o, t = origin.transform.location, target.transform.location
    route = m.trace_route(o, t)
    locs = [w.transform.location for w, _ in route]
    assert locs[0].distance_2d(o) < 5.0 and locs[-1].distance_2d(t) < 5.0
    assert all(a.distance_2d(b) < 2.5 for a, b in zip(locs, locs[1:], strict=False))
    length = sum(a.distance_2d(b) for a, b in zip(locs, locs[1:], strict=False))
    assert length > math.hypot(o.x - t.x, o.y - t.y) > 500.0
    assert any(w.is_junction for w, _ in route)


def test_written_file_loads_under_its_town_name(maps: dict[str, Map]) -> None:
    for name, m in maps.items():
        assert m.name == TOWN_PRESETS[name].town
        assert isinstance(m.path, Path)


def test_only_the_downtown_town_has_a_one_way_left_kerb(maps: dict[str, Map]) -> None:
    # Town100-103 are all two-way roads and ramps: a lane's left is the opposite lane (or the ramp's shoulder).
    for name in ("all", "urban", "highway", "interurban"):
        assert find_one_way(maps[name]) is None, name
    assert find_one_way(maps["downtown"])
