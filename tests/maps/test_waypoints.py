"""Waypoint queries on the tiny junction town (see conftest.py for its layout)."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from b2d_data.format.transform import Location
from b2d_data.maps import LaneChange, LaneMarkingColor, LaneMarkingType, LaneType


def _xy(wp) -> list[float]:
    return [wp.transform.location.x, wp.transform.location.y]


def test_get_waypoint_snaps_to_lane_centre(tiny_map):
    # Road 1 lane -1 centre is OpenDRIVE t = −1.75 → CARLA y = +1.75, heading east (yaw 0).
    wp = tiny_map.get_waypoint(Location(10.3, 2.4, 0.0))
    assert (wp.road_id, wp.section_id, wp.lane_id) == (1, 0, -1)
    np.testing.assert_allclose(_xy(wp), [10.3, 1.75], atol=1e-9)
    assert abs(wp.s - 10.3) < 1e-9 and wp.transform.rotation.yaw == pytest.approx(0.0, abs=1e-9)
    assert wp.lane_type == LaneType.DRIVING and not wp.is_junction and wp.junction_id == -1
    assert wp.lane_width == pytest.approx(3.5)
    # Lane 1 drives west: OpenDRIVE t = +1.75 → CARLA y = −1.75, yaw 180.
    west = tiny_map.get_waypoint((20.0, -1.0, 0.0))
    assert west.lane_id == 1 and abs(abs(west.transform.rotation.yaw) - 180.0) < 1e-9


def test_get_waypoint_lane_type_and_projection(tiny_map):
    # The sidewalk (lane -3) spans t ∈ [−9, −7]: CARLA (10, 8) is on it.
    on_sidewalk = Location(10.0, 8.0, 0.0)
    assert tiny_map.get_waypoint(on_sidewalk, project_to_road=False) is None  # 2.75 m from lane -2's centre
    projected = tiny_map.get_waypoint(on_sidewalk)
    assert projected.lane_id == -2 and projected.transform.location.y == pytest.approx(5.25)
    walk = tiny_map.get_waypoint(on_sidewalk, lane_type=LaneType.SIDEWALK)
    assert walk.lane_id == -3 and walk.lane_type == LaneType.SIDEWALK
    assert walk.transform.location.y == pytest.approx(8.0)
    either = tiny_map.get_waypoint(on_sidewalk, lane_type=LaneType.DRIVING | LaneType.SIDEWALK)
    assert either.lane_id == -3


def test_waypoints_are_hashable_and_equal_by_position(tiny_map):
    a = tiny_map.get_waypoint_xodr(1, -1, 12.0)
    b = tiny_map.get_waypoint(Location(12.0, 1.75, 0.0))
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    with pytest.raises(AttributeError):
        a.s = 3.0  # frozen
    assert tiny_map.get_waypoint_xodr(1, -1, 13.0) != a
    assert tiny_map.get_waypoint_xodr(1, -7, 1.0) is None and tiny_map.get_waypoint_xodr(1, -1, 50.0) is None
    again = pickle.loads(pickle.dumps(a))
    assert (again.road_id, again.lane_id, again.s) == (1, -1, 12.0)


def test_next_branches_at_the_junction(tiny_map):
    start = tiny_map.get_waypoint_xodr(1, -1, 10.0)
    ahead = start.next(45.0)  # 40 m to the junction, then 5 m into each connecting lane
    assert [(w.road_id, w.lane_id) for w in ahead] == [(10, -1), (11, -1)]
    straight, left = ahead
    assert straight.is_junction and straight.junction_id == 100
    np.testing.assert_allclose(_xy(straight), [55.0, 1.75], atol=1e-6)
    # Left arc: centre (50, 10), lane radius 10 + 1.75 = 11.75, turned 5/10 rad: OpenDRIVE
    # (50 + 11.75·sin 0.5, 10 − 11.75·cos 0.5) = (55.63325, −0.31160) → CARLA (55.63325, 0.31160).
    np.testing.assert_allclose(_xy(left), [55.63325, 0.31160], atol=2e-3)
    assert left.transform.rotation.yaw == pytest.approx(-math.degrees(0.5), abs=1e-3)
    assert [(w.road_id, w.lane_id) for w in start.next(10.0)] == [(1, -1)]


def test_previous_crosses_back_through_the_junction(tiny_map):
    # 5 m into road 2, 10 m back: 5 m before the end of the straight connector (s = 15) → CARLA (65, 1.75).
    back = tiny_map.get_waypoint_xodr(2, -1, 5.0).previous(10.0)
    assert [(w.road_id, w.lane_id) for w in back] == [(10, -1)]
    np.testing.assert_allclose(_xy(back[0]), [65.0, 1.75], atol=1e-6)
    # From road 3 (north exit), 10 m back lands 8 m before the left arc's end: turned (15.708 − 8)/10 rad.
    theta = (10 * math.pi / 2 - 8.0) / 10.0
    back_left = tiny_map.get_waypoint_xodr(3, -1, 2.0).previous(10.0)
    assert [(w.road_id, w.lane_id) for w in back_left] == [(11, -1)]
    expected = [50 + 11.75 * math.sin(theta), -(10 - 11.75 * math.cos(theta))]
    np.testing.assert_allclose(_xy(back_left[0]), expected, atol=2e-3)
    # Road 1 lane -2 feeds the straight connector and the right turn: both are its successors.
    assert {(w.road_id, w.lane_id) for w in tiny_map.get_waypoint_xodr(1, -2, 49.0).next(2.0)} == {(10, -2), (12, -1)}


def test_next_until_lane_end_stops_at_the_road_end(tiny_map):
    points = tiny_map.get_waypoint_xodr(1, -1, 30.0).next_until_lane_end(5.0)
    assert [round(w.s, 6) for w in points] == [35.0, 40.0, 45.0, 50.0]
    assert all(w.road_id == 1 for w in points)
    back = tiny_map.get_waypoint_xodr(1, -1, 12.0).previous_until_lane_start(5.0)
    assert [round(w.s, 6) for w in back][:2] == [7.0, 2.0] and back[-1].road_id == 1


def test_neighbours_and_lane_change_permissions(tiny_map):
    lane_m1 = tiny_map.get_waypoint_xodr(1, -1, 20.0)
    lane_m2 = tiny_map.get_waypoint_xodr(1, -2, 20.0)
    # Lane -1: left mark = centre (solid yellow, laneChange none), right mark = its own (broken, both).
    assert lane_m1.left_lane_marking.type == LaneMarkingType.SOLID
    assert lane_m1.left_lane_marking.color == LaneMarkingColor.YELLOW
    assert lane_m1.right_lane_marking.type == LaneMarkingType.BROKEN
    assert lane_m1.lane_change == LaneChange.RIGHT
    # Lane -2: left mark = lane -1's broken line (both), right mark = its own solid line (none).
    assert lane_m2.lane_change == LaneChange.LEFT
    right = lane_m1.get_right_lane()
    assert (right.lane_id, right.s) == (-2, 20.0) and right.lane_type == LaneType.DRIVING
    # Left of lane -1 is the westbound lane 1 across the centre line (CARLA returns it too).
    left = lane_m1.get_left_lane()
    assert left.lane_id == 1 and abs(abs(left.transform.rotation.yaw) - 180.0) < 1e-9
    assert left.get_left_lane().lane_id == -1
    sidewalk = lane_m2.get_right_lane()
    assert sidewalk.lane_id == -3 and sidewalk.lane_type == LaneType.SIDEWALK
    assert sidewalk.get_right_lane() is None
    assert left.lane_change == LaneChange.NONE


def test_topology_junctions_and_generated_waypoints(tiny_map):
    pairs = {((a.road_id, a.lane_id), (b.road_id, b.lane_id)) for a, b in tiny_map.get_topology()}
    assert pairs == {
        ((1, -1), (10, -1)), ((1, -1), (11, -1)), ((1, -2), (10, -2)), ((1, -2), (12, -1)),
        ((10, -1), (2, -1)), ((10, -2), (2, -2)), ((11, -1), (3, -1)), ((12, -1), (4, -1)),
    }  # fmt: skip
    junction = tiny_map.junctions[100]
    # Lane centres of the connectors span x ∈ [50, 70] and y ∈ [−10, 13.5] (left exit at CARLA y = −10, right
    # exit at y = 13.5): centre (60, 1.75), half extents (10, 11.75).
    box = junction.bounding_box
    measured = [box.location.x, box.location.y, box.extent.x, box.extent.y]
    np.testing.assert_allclose(measured, [60, 1.75, 10, 11.75], atol=1e-6)
    entries = junction.get_waypoints(LaneType.DRIVING)
    assert sorted((a.road_id, a.lane_id) for a, _ in entries) == [(10, -2), (10, -1), (11, -1), (12, -1)]
    for entry, exit_ in entries:
        assert entry.road_id == exit_.road_id and entry.s < exit_.s
    assert tiny_map.get_waypoint_xodr(10, -1, 3.0).get_junction() is junction
    # Every 10 m on each road's driving lanes: road 1 (50 m, 3 lanes) gives s = 0⁺, 10, …, 40 × 3 lanes.
    generated = [w for w in tiny_map.generate_waypoints(10.0) if w.road_id == 1]
    assert len(generated) == 15 and {w.lane_id for w in generated} == {1, -1, -2}


def test_spawn_points_lie_on_driving_lanes_outside_junctions(tiny_map):
    points = tiny_map.get_spawn_points()
    assert points
    for transform in points:
        wp = tiny_map.get_waypoint(transform.location)
        assert not wp.is_junction and wp.transform.location.distance_2d(transform.location) < 1e-6
        assert transform.location.z == pytest.approx(wp.transform.location.z + 0.5)


def test_lane_geometry_borders_are_relative_to_traffic(tiny_map):
    geoms = {(g.road_id, g.lane_id): g for g in tiny_map.lane_geometry(resolution=1.0)}
    east = geoms[(1, -1)]
    # Eastbound lane -1: left border is the centre line (y = 0), right border y = 3.5, 51 samples over 50 m.
    assert east.centre.shape == (51, 3) and east.left.shape == (51, 3)
    np.testing.assert_allclose(east.left[:, 1], 0.0, atol=1e-9)
    np.testing.assert_allclose(east.right[:, 1], 3.5, atol=1e-9)
    assert east.right_marks[0][2].type == LaneMarkingType.BROKEN
    assert east.left_marks[0][2].color == LaneMarkingColor.YELLOW
    west = geoms[(1, 1)]
    # Samples follow road s (x from 0 to 50) whatever the traffic direction; the westbound lane's right border
    # (seen driving west, its outer border) is at CARLA y = −3.5.
    assert west.centre[0, 0] == pytest.approx(0.0) and west.centre[-1, 0] == pytest.approx(50.0)
    np.testing.assert_allclose(west.right[:, 1], -3.5, atol=1e-9)
    assert west.length == pytest.approx(50.0)
    assert geoms[(11, -1)].is_junction and geoms[(1, -3)].lane_type == LaneType.SIDEWALK


def test_crosswalk_and_road_marks(tiny_map):
    (crosswalk,) = tiny_map.crosswalks()
    # Object at road 2 s = 10, t = −3.5 → OpenDRIVE (80, −3.5); corners ±1.5 along x, ±3.5 across → CARLA y ∈ [0, 7].
    np.testing.assert_allclose(np.sort(crosswalk.polygon[:, 0]), [78.5, 78.5, 81.5, 81.5], atol=1e-9)
    np.testing.assert_allclose(np.sort(crosswalk.polygon[:, 1]), [0, 0, 7, 7], atol=1e-9)
    lines = tiny_map.road_marks()
    centre = [m for m in lines if m.road_id == 1 and m.lane_id == 0]
    assert len(centre) == 1 and centre[0].marking.color == LaneMarkingColor.YELLOW
    np.testing.assert_allclose(centre[0].points[:, 1], 0.0, atol=1e-9)
    assert all(m.marking.type != LaneMarkingType.NONE for m in lines)


def test_get_waypoint_is_fast(tiny_map):
    rng = np.random.default_rng(0)
    points = rng.uniform([0, -5, 0], [100, 15, 0], size=(300, 3))
    import time

    start = time.perf_counter()
    for p in points:
        tiny_map.get_waypoint(p)
    per_call = (time.perf_counter() - start) / len(points)
    assert per_call < 1e-3


def test_lane_keys_are_get_waypoints_lanes(tiny_map):
    locations = [Location(10.3, 2.4, 0.0), Location(20.0, -1.0, 0.0), Location(10.0, 8.0, 0.0), Location(-30, 50, 2)]
    expected = [(w.road_id, w.lane_id, w.section_id) for w in map(tiny_map.get_waypoint, locations)]
    assert tiny_map.lane_keys(locations) == expected
    assert tiny_map.lane_keys([(10.3, 2.4, 0.0)]) == expected[:1] and tiny_map.lane_keys([]) == []
    walk = tiny_map.get_waypoint(locations[2], lane_type=LaneType.SIDEWALK)
    assert tiny_map.lane_keys(locations[2:3], LaneType.SIDEWALK) == [(walk.road_id, walk.lane_id, walk.section_id)]


@pytest.mark.parametrize("town", ["Town01", "Town10HD"])
def test_nearest_many_is_nearest_to_the_last_bit(carla_towns, town):
    """The batched lane query gives each point nearest's segment, s and distance, bit for bit."""
    lane_index = carla_towns[town]._lane_index
    rng = np.random.default_rng(3)
    centres = np.concatenate([t.points for t in lane_index._trees.values()])
    lo, hi = centres.min(0) - 30, centres.max(0) + 30
    sample = centres[rng.integers(len(centres), size=1500)]
    queries = np.concatenate([rng.uniform(lo, hi, (1500, 3)), sample + rng.normal(0, 2.0, sample.shape), sample[:300]])
    for lane_type in (LaneType.DRIVING, LaneType.SIDEWALK, LaneType.DRIVING | LaneType.SIDEWALK | LaneType.SHOULDER):
        many = lane_index.nearest_many(queries, int(lane_type))
        for point, got in zip(queries, many):
            want = lane_index.nearest(point, int(lane_type))
            assert got == want and (want is None or (got[1].hex(), got[2].hex()) == (want[1].hex(), want[2].hex()))
    assert lane_index.nearest_many(np.zeros((0, 3))) == []


def test_get_waypoint_answers_the_same_place_once(tiny_map, monkeypatch):
    # the route criteria and the expert ask for the ego's lane each tick, at the same place while it waits;
    # a pickled map does not carry the answers of the one it came from
    assert tiny_map.get_waypoint(Location(1.0, 1.0, 0.0)) is not None
    assert "_waypoint_memo" in tiny_map.__dict__
    assert "_waypoint_memo" not in pickle.loads(pickle.dumps(tiny_map)).__dict__
    queries = []
    nearest = tiny_map._lane_index.nearest
    monkeypatch.setattr(tiny_map._lane_index, "nearest", lambda *a: queries.append(a) or nearest(*a))
    first = tiny_map.get_waypoint(Location(10.3, 2.4, 0.0))
    assert tiny_map.get_waypoint(Location(10.3, 2.4, 0.0)) is first and len(queries) == 1
    assert tiny_map.get_waypoint((10.3, 2.4, 0.0)) is first and len(queries) == 1
    assert tiny_map.get_waypoint(Location(10.3, 2.4, 0.0), lane_type=LaneType.SIDEWALK).lane_type == LaneType.SIDEWALK
    assert tiny_map.get_waypoint(Location(10.3, 2.4, 0.0), project_to_road=False) == first
    assert len(queries) == 3  # other arguments: asked anew, each remembered apart
    assert tiny_map.get_waypoint(Location(10.3, 2.4, 0.0)) is first and len(queries) == 3
    # any other place is looked up, to the last bit of its coordinates (−0.0 is not 0.0)
    moved = tiny_map.get_waypoint(Location(10.300000000000002, 2.4, 0.0))
    assert moved is not first and moved.s != first.s and len(queries) == 4
    tiny_map.get_waypoint(Location(10.3, 2.4, 0.0))
    tiny_map.get_waypoint(Location(10.3, 2.4, -0.0))
    assert len(queries) == 6
