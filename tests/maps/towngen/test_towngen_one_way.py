"""One-way streets: the cross-section, the grid's direction per column, and how junctions join them (Town104)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from b2d_data.maps.towngen import build_town, plan_town
from b2d_data.maps.towngen.cross_sections import TownWidths, one_way, street
from b2d_data.maps.towngen.layouts import GridSpec, add_grid
from b2d_data.maps.towngen.model import Road, Town
from b2d_data.maps.towngen.network import TownPlan


@pytest.fixture(scope="module")
def town() -> Town:
    return build_town("downtown", 0)


def _widths() -> TownWidths:
    w = TownWidths.draw(np.random.default_rng(0))
    return replace(w, street_lane=3.5, parking=2.5, sidewalk=3.0)


def test_cross_section_by_hand() -> None:
    cs = one_way(_widths())
    assert [lane.type for lane in cs.right] == ["sidewalk", "parking", "driving", "driving", "parking", "sidewalk"]
    assert cs.left == () and cs.driving_count(True) == 2 and cs.driving_count(False) == 0
    # 2 × 3.0 + 2 × 2.5 + 2 × 3.5 = 18 m; the lane offset (9 m to the left) centres it on the reference line
    assert cs.lane_offset == pytest.approx(9.0)
    assert cs.half_width(True) == pytest.approx(9.0) and cs.half_width(False) == pytest.approx(9.0)
    # kerbs on both sides of the road, the left edge line of the leftmost lane, a broken line between the lanes
    assert [lane.mark.type for lane in cs.right] == ["curb", "solid", "broken", "solid", "curb", "none"]


def test_a_one_way_column_needs_a_direction() -> None:
    w = _widths()
    plain, oneway = street(w), one_way(w)
    corners = ((0, 0), (2, 0), (0, 2), (2, 2))
    grid = {
        "xs": (0.0, 200.0, 400.0), "ys": (0.0, -200.0, -400.0), "row_sections": (plain,) * 3,
        "col_sections": (plain, oneway, plain), "corner_sections": dict.fromkeys(corners, plain),
        "corner_radius": dict.fromkeys(corners, 20.0), "controls": {},
    }  # fmt: skip
    with pytest.raises(ValueError, match="column_flow"):
        add_grid(TownPlan("Town199", "test", 0), GridSpec(**grid))
    plan = TownPlan("Town199", "test", 0)
    add_grid(plan, GridSpec(**grid, column_flow={1: -1}))
    # northward (to row 0 at y = 0): each block of column 1 runs from its southern node to its northern one
    blocks = [(plan.node(e.a).y, plan.node(e.b).y) for e in plan.edges if e.section is oneway]
    assert sorted(blocks) == [(-400.0, -200.0), (-200.0, 0.0)]


def test_downtown_columns_run_opposite_ways() -> None:
    plan = plan_town("downtown", 0)
    heading: dict[int, set[float]] = {1: set(), 2: set()}
    for e in plan.edges:
        if e.section.name == "one_way":
            col = int(e.name.split()[2])
            a, b = plan.node(e.a), plan.node(e.b)
            assert a.x == b.x
            heading[col].add(math.copysign(1.0, b.y - a.y))
    # each column one way along its length (both of its blocks), the two columns opposite ways
    assert len(heading[1]) == 1 and len(heading[2]) == 1 and heading[1] != heading[2]


def _one_way_roads(town: Town) -> list[Road]:
    return [r for r in town.roads if r.junction == -1 and r.name.startswith("one_way")]


def test_junctions_enter_one_way_roads_at_their_start_and_leave_at_their_end(town: Town) -> None:
    ids = {r.id for r in _one_way_roads(town)}
    assert len(ids) == 4
    roads = {r.id: r for r in town.roads}
    into: dict[int, int] = dict.fromkeys(ids, 0)
    out_of: dict[int, int] = dict.fromkeys(ids, 0)
    for r in town.roads:
        if r.junction == -1 or r.sections[0].right[0].type != "driving":
            continue
        if r.successor.element_id in ids:
            assert r.successor.contact == "start", f"connecting road {r.id} enters a one-way road at its end"
            into[r.successor.element_id] += 1
        if r.predecessor.element_id in ids:
            assert r.predecessor.contact == "end", f"connecting road {r.id} leaves a one-way road at its start"
            out_of[r.predecessor.element_id] += 1
    # every one-way block is reached and left; at a T or 4-way the other arms turn or go straight into it
    assert all(into[i] >= 2 for i in ids) and all(out_of[i] >= 2 for i in ids), (into, out_of)
    # the one-way roads hold no lane against their direction
    assert all(not roads[i].sections[0].left for i in ids)


def test_sidewalks_turn_both_corners_of_a_one_way_road(town: Town) -> None:
    """Lane -1 (left kerb) and -6 (right kerb) sidewalks are joined round the corners at both ends of every block."""
    ids = {r.id for r in _one_way_roads(town)}
    touched: set[tuple[int, str, int]] = set()
    for r in town.roads:
        if r.junction == -1:
            continue
        for lane in r.sections[0].right:
            if lane.type != "sidewalk":
                continue
            if r.predecessor.element_id in ids:
                touched.add((r.predecessor.element_id, r.predecessor.contact, lane.predecessor))
            if r.successor.element_id in ids:
                touched.add((r.successor.element_id, r.successor.contact, lane.successor))
    for i in ids:
        for contact in ("start", "end"):
            assert (i, contact, -1) in touched and (i, contact, -6) in touched, (i, contact)


def test_crosswalks_span_the_one_way_road_between_its_sidewalks(town: Town) -> None:
    # seed 0: lanes 3.48 m, parking 2.23 m: 2 × 3.48 + 2 × 2.23 = 11.42 m between the sidewalks, centred on the
    # reference line (the lane offset centres the 18.0 m road on it)
    walks = [o for r in _one_way_roads(town) for o in r.objects if o.type == "crosswalk"]
    assert len(walks) == 8  # both ends of four blocks
    for o in walks:
        assert o.length == pytest.approx(11.42, abs=1e-6) and o.t == pytest.approx(0.0, abs=1e-6)
