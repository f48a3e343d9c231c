"""Structural validity of the generated OpenDRIVE, checked with the generator's own reader and geometry (no parser).

``validate_xodr`` reads the text back and checks: ids resolve, geometries chain, every joined lane pair (road links,
lane sections, junction connecting roads) meets within 1 cm with equal widths and heights, junction lanes turn no
tighter than 6 m (lane centre), and no driving lane dead-ends.
"""

from __future__ import annotations

import math
import re
from collections import Counter

import pytest
from lxml import etree

from b2d_data.maps.towngen import TOWN_PRESETS, generate_town, validate_xodr
from b2d_data.maps.towngen.validate import lane_point
from b2d_data.maps.towngen.xodr_reader import read_town


@pytest.fixture(scope="module")
def all_text() -> str:
    return generate_town("all", 0)


@pytest.fixture(scope="module")
def all_root(all_text: str) -> etree._Element:
    return etree.fromstring(all_text.encode())


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("preset", sorted(TOWN_PRESETS))
def test_generated_towns_validate(preset: str, seed: int) -> None:
    assert validate_xodr(generate_town(preset, seed)) == []


def test_validator_catches_a_connecting_road_moved_by_5_cm(all_text: str, all_root: etree._Element) -> None:
    road = next(r for r in all_root.findall("road") if r.get("junction") != "-1")
    geo = road.find("planView/geometry")
    geo.set("x", repr(float(geo.get("x")) + 0.05))
    problems = validate_xodr(etree.tostring(all_root).decode())
    geo.set("x", repr(float(geo.get("x")) - 0.05))
    assert any(f"lane {road.get('id')}/" in p and "0.050 m apart" in p for p in problems), problems


def test_validator_catches_dangling_references(all_text: str) -> None:
    root = etree.fromstring(all_text.encode())
    victim = next(r for r in root.findall("road") if r.get("junction") != "-1")
    root.remove(victim)
    problems = validate_xodr(etree.tostring(root).decode())
    assert any(f"{victim.get('id')} missing" in p for p in problems), problems


def test_a_connecting_lane_starts_where_its_incoming_lane_ends(all_text: str) -> None:
    # Independent spot check of one straight connecting road: its lane -1 starts where the incoming lane ends.
    town = read_town(all_text)
    roads = {r.id: r for r in town.roads}
    conn = next(r for r in town.roads if r.junction != -1 and r.predecessor.contact == "end")
    lane = conn.sections[0].right[0]
    inc = roads[conn.predecessor.element_id]
    a = lane_point(conn, lane.id, 0.0)
    b = lane_point(inc, lane.predecessor, inc.length)
    assert math.hypot(a.x - b.x, a.y - b.y) < 0.01


def test_header_and_geometry_kinds(all_root: etree._Element) -> None:
    header = all_root.find("header")
    assert (header.get("revMajor"), header.get("revMinor")) == ("1", "4")
    assert "+lat_0=0 +lon_0=0" in header.find("geoReference").text
    kinds = Counter(g[0].tag for g in all_root.iter("geometry"))
    # Highway corners and ramps use clothoids, ramp junctions paramPoly3, everything else lines and arcs.
    assert {"line", "arc", "spiral", "paramPoly3"} <= set(kinds)
    offsets = {float(o.get("a")) for o in all_root.iter("laneOffset")}
    assert any(v > 0 for v in offsets)  # ramps run their reference line down the lane's middle
    heights = [float(e.get("a")) for e in all_root.iter("elevation")]
    assert max(heights) > 0.5  # the interurban road has gentle crests


def test_lane_types_and_marks(all_root: etree._Element) -> None:
    types = Counter(lane.get("type") for lane in all_root.iter("lane"))
    for lane_type in ("driving", "sidewalk", "parking", "biking", "shoulder", "median"):
        assert types[lane_type] > 0, lane_type
    marks = {(m.get("type"), m.get("color"), m.get("laneChange")) for m in all_root.iter("roadMark")}
    assert ("broken", "yellow", "both") in marks
    assert ("broken", "white", "both") in marks
    assert ("solid", "white", "none") in marks
    assert any(m[0] == "curb" for m in marks)


def _junction_roads(root: etree._Element) -> dict[str, set[str]]:
    """Junction id -> ids of the ordinary roads that touch it."""
    out: dict[str, set[str]] = {}
    for road in root.findall("road"):
        if road.get("junction") != "-1":
            continue
        for link in road.findall("link/*"):
            if link.get("elementType") == "junction":
                out.setdefault(link.get("elementId"), set()).add(road.get("id"))
    return out


def test_traffic_lights_are_grouped_by_junction(all_root: etree._Element) -> None:
    signal_road = {s.get("id"): (s, s.getparent().getparent()) for s in all_root.iter("signal")}
    touching = _junction_roads(all_root)
    controllers = {c.get("id"): c for c in all_root.findall("controller")}
    lit = 0
    for junction in all_root.findall("junction"):
        refs = [c.get("id") for c in junction.findall("controller")]
        if not refs:
            continue
        lit += 1
        assert len(refs) == 1
        ids = [c.get("signalId") for c in controllers[refs[0]].findall("control")]
        roads = {signal_road[i][1].get("id") for i in ids}
        assert all(signal_road[i][0].get("type") == "1000001" for i in ids)
        # One light per approach that carries traffic in, on a road that ends at this junction.
        assert roads <= touching[junction.get("id")]
        assert len(ids) == len(roads) >= 3
    assert lit >= 3


def test_signal_attributes(all_root: etree._Element) -> None:
    by_type = Counter(s.get("type") for s in all_root.iter("signal"))
    assert by_type["1000001"] > 0 and by_type["206"] > 0 and by_type["274"] > 0
    for sig in all_root.iter("signal"):
        validity = sig.find("validity")
        lo, hi = int(validity.get("fromLane")), int(validity.get("toLane"))
        assert lo <= hi and lo * hi > 0
        # Right lanes (negative ids) run along +s, left lanes against it.
        assert sig.get("orientation") == ("+" if hi < 0 else "-")
        if sig.get("type") == "274":
            assert sig.get("unit") == "km/h" and float(sig.get("value")) == float(sig.get("subtype")) > 0


def test_crosswalks_have_closed_outlines(all_root: etree._Element) -> None:
    crosswalks = [o for o in all_root.iter("object") if o.get("type") == "crosswalk"]
    assert crosswalks
    for obj in crosswalks:
        corners = [(float(c.get("u")), float(c.get("v"))) for c in obj.findall("outline/cornerLocal")]
        assert len(corners) == 5 and corners[0] == corners[-1]
        us = [u for u, _ in corners]
        assert max(us) - min(us) == pytest.approx(float(obj.get("length")))


def test_file_is_plain_ascii_numbers(all_text: str) -> None:
    # Numbers are written like CARLA's towns (exponent form), never as nan/inf.
    assert not re.search(r"\b(nan|inf)\b", all_text)


def test_validator_catches_a_broken_geometry_chain(all_root: etree._Element) -> None:
    road = next(r for r in all_root.findall("road") if len(r.findall("planView/geometry")) >= 3)
    geo = road.findall("planView/geometry")[1]
    geo.set("y", repr(float(geo.get("y")) + 0.01))
    problems = validate_xodr(etree.tostring(all_root).decode())
    geo.set("y", repr(float(geo.get("y")) - 0.01))
    assert any(f"road {road.get('id')}: geometry at s=" in p and "does not continue" in p for p in problems), problems
