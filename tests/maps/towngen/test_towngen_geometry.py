"""Plan-view primitives and path solvers of the town generator, against values worked out by hand."""

from __future__ import annotations

import math

import pytest

from b2d_data.maps.towngen.geometry import (
    Arc,
    Line,
    Pose,
    RefLine,
    Spiral,
    bump_prims,
    chain_end,
    hermite_poly3,
    tangent_lengths,
    turn_prims,
)
from b2d_data.maps.towngen.paths import Corner, PathError, connector, line_turn_line, polyline_path


def test_quarter_arc_ends_on_the_circle() -> None:
    # Radius 10 to the left from the origin heading east: centre (0, 10), a quarter turn ends at (10, 10) heading north.
    end = chain_end(Pose(0.0, 0.0, 0.0), (Arc(10.0 * math.pi / 2.0, 0.1),))
    assert end.x == pytest.approx(10.0, abs=1e-9)
    assert end.y == pytest.approx(10.0, abs=1e-9)
    assert end.hdg == pytest.approx(math.pi / 2.0, abs=1e-12)


def test_spiral_matches_the_clothoid_series() -> None:
    # Clothoid from curvature 0 to 1/R over L, A^2 = R L = 3000: x = L - L^5/(40 A^4), y = L^3/(6 A^2) - L^7/(336 A^6)
    # (first two series terms): x = 30 - 0.0675 = 29.9325, y = 1.5 - 0.00241 = 1.49759; heading L/(2R) = 0.15 rad.
    end = chain_end(Pose(0.0, 0.0, 0.0), (Spiral(30.0, 0.0, 0.01),))
    assert end.x == pytest.approx(29.9325, abs=1e-4)
    assert end.y == pytest.approx(1.49759, abs=1e-4)
    assert end.hdg == pytest.approx(0.15, abs=1e-12)


def test_spiral_arc_spiral_turn_turns_by_the_requested_angle() -> None:
    # Heading change of the turn = sum of the curvature integrals = the requested 90 degrees.
    prims = turn_prims(math.pi / 2.0, 100.0, 40.0)
    assert [type(p) for p in prims] == [Spiral, Arc, Spiral]
    assert chain_end(Pose(0.0, 0.0, 0.0), prims).hdg == pytest.approx(math.pi / 2.0, abs=1e-12)
    d0, d1 = tangent_lengths(prims)
    # Symmetric turn: equal tangents, longer than the plain arc's R tan(45 deg) = 100 because the spirals shift it.
    assert d0 == pytest.approx(d1, abs=1e-6)
    assert 100.0 < d0 < 100.0 + 40.0


def test_plain_arc_tangents_equal_the_radius() -> None:
    d0, d1 = tangent_lengths(turn_prims(math.pi / 2.0, 25.0, 0.0))
    assert d0 == pytest.approx(25.0, abs=1e-9)
    assert d1 == pytest.approx(25.0, abs=1e-9)


def test_bump_returns_to_its_line() -> None:
    # Heading rises to +a, falls to -a, returns to 0, antisymmetric about the middle: no net lateral shift.
    end = chain_end(Pose(0.0, 0.0, 0.0), bump_prims(math.radians(4.0), 100.0))
    assert end.y == pytest.approx(0.0, abs=1e-9)
    assert end.hdg == pytest.approx(0.0, abs=1e-12)
    assert 99.0 < end.x < 100.0


def test_hermite_paramPoly3_lands_on_its_target() -> None:
    start, target = Pose(5.0, 5.0, 0.3), Pose(25.0, 12.0, 0.1)
    curve = hermite_poly3(start, target)
    end = chain_end(start, (curve,))
    assert (end.x, end.y) == pytest.approx((target.x, target.y), abs=1e-9)
    assert end.hdg == pytest.approx(target.hdg, abs=1e-9)
    chord = math.hypot(20.0, 7.0)
    assert chord < curve.length < chord * 1.2


def test_connector_fillets_a_right_angle_into_one_arc() -> None:
    # Start (0,0) east, end (10,10) north: both tangents 10 m long, so a single arc of radius 10 and no lines.
    prims = connector(Pose(0.0, 0.0, 0.0), Pose(10.0, 10.0, math.pi / 2.0))
    assert len(prims) == 1 and isinstance(prims[0], Arc)
    assert prims[0].curvature_value == pytest.approx(0.1)


def test_connector_keeps_straights_straight_and_shifts_with_a_cubic() -> None:
    assert connector(Pose(0.0, 0.0, 0.0), Pose(30.0, 0.0, 0.0)) == (Line(30.0),)
    shifted = connector(Pose(0.0, 0.0, 0.0), Pose(30.0, -1.0, 0.0))
    end = chain_end(Pose(0.0, 0.0, 0.0), shifted)
    assert (end.x, end.y) == pytest.approx((30.0, -1.0), abs=1e-9)


def test_line_turn_line_solves_the_straights() -> None:
    # An arc of radius 20 turning left by 90 degrees moves (20, 20); the rest is 80 m east then 30 m north.
    path = line_turn_line(Pose(0.0, 0.0, 0.0), Pose(100.0, 50.0, math.pi / 2.0), 20.0, 0.0)
    assert [type(p) for p in path.prims] == [Line, Arc, Line]
    assert path.prims[0].length == pytest.approx(80.0)
    assert path.prims[2].length == pytest.approx(30.0)


def test_line_turn_line_refuses_a_turn_that_does_not_fit() -> None:
    with pytest.raises(PathError):
        line_turn_line(Pose(0.0, 0.0, 0.0), Pose(10.0, 10.0, math.pi / 2.0), 20.0, 0.0)


def test_polyline_rounds_corners_and_reports_turns() -> None:
    # Corner at (100, 0) with radius 30: 70 m line, quarter arc, 70 m line (the end is 100 m north of the corner).
    path = polyline_path(Pose(0.0, 0.0, 0.0), (Corner(100.0, 0.0, 30.0),), Pose(100.0, 100.0, math.pi / 2.0))
    assert [p.length for p in path.prims] == pytest.approx([70.0, 30.0 * math.pi / 2.0, 70.0])
    assert path.turn_bounds == (1, 2)
    line = RefLine(path.start, path.prims)
    assert line.end.y == pytest.approx(100.0, abs=1e-9)
    assert [piece.length for piece in line.split([1, 2])] == pytest.approx([70.0, 15.0 * math.pi, 70.0])
