"""Reference-line primitives and lane width/offset evaluation, against values worked out by hand."""

from __future__ import annotations

import math

import numpy as np

from b2d_data.maps import load_opendrive
from b2d_data.maps.geometry import evaluate_cubic, evaluate_geometry, evaluate_reference_line
from b2d_data.maps.opendrive_parser import GeometryRecord, Poly3


def test_line_moves_along_heading():
    # hdg 30°: 10 m ahead of (1, 2) is (1 + 10·cos30°, 2 + 10·sin30°) = (9.6603, 7).
    g = GeometryRecord(0.0, 1.0, 2.0, math.radians(30), 20.0, "line")
    x, y, hdg, k = evaluate_geometry(g, np.array([10.0]))
    np.testing.assert_allclose([x[0], y[0]], [1 + 10 * math.sqrt(3) / 2, 7.0], atol=1e-12)
    assert hdg[0] == math.radians(30) and k[0] == 0.0


def test_quarter_arc_ends_at_10_10_and_flips_to_carla():
    # Curvature 1/10 from the origin heading east: a quarter circle of radius 10 around (0, 10) ends at (10, 10)
    # heading north. In CARLA's frame (y negated) that is (10, -10), yaw -90°.
    g = GeometryRecord(0.0, 0.0, 0.0, 0.0, 10 * math.pi / 2, "arc", (0.1,))
    x, y, hdg, k = evaluate_geometry(g, np.array([10 * math.pi / 2]))
    np.testing.assert_allclose([x[0], y[0]], [10.0, 10.0], atol=1e-9)
    assert abs(hdg[0] - math.pi / 2) < 1e-12 and k[0] == 0.1
    carla_xy = (x[0], -y[0])
    np.testing.assert_allclose(carla_xy, (10.0, -10.0), atol=1e-9)


def test_spiral_end_heading_and_constant_curvature_limit():
    # Heading after L: hdg + k0·L + (k1 − k0)·L/2 = 0.2 + 0.01·40 + 0.04·20 = 1.4 rad.
    g = GeometryRecord(0.0, 0.0, 0.0, 0.2, 40.0, "spiral", (0.01, 0.05))
    _, _, hdg, k = evaluate_geometry(g, np.array([40.0]))
    assert abs(hdg[0] - 1.4) < 1e-12 and abs(k[0] - 0.05) < 1e-12
    # A spiral whose curvature does not change is an arc: compare with the arc's closed form.
    s = np.linspace(0.0, 30.0, 7)
    spiral = evaluate_geometry(GeometryRecord(0.0, 3.0, 4.0, 1.0, 30.0, "spiral", (0.05, 0.05)), s)
    arc = evaluate_geometry(GeometryRecord(0.0, 3.0, 4.0, 1.0, 30.0, "arc", (0.05,)), s)
    np.testing.assert_allclose(spiral[0], arc[0], atol=1e-4)
    np.testing.assert_allclose(spiral[1], arc[1], atol=1e-4)


def test_clothoid_from_zero_curvature_matches_fresnel_series():
    # Clothoid k(s) = s/A² with A² = 100 (k0 = 0, k1 = 0.5 over 50 m), θ = s²/(2A²). Fresnel series:
    # x = s − s⁵/(40A⁴) + s⁹/(3456A⁸) = 10 − 0.25 + 0.002894 = 9.752894 at s = 10;
    # y = s³/(6A²) − s⁷/(336A⁶) + s¹¹/(42240A¹⁰) = 1.666667 − 0.029762 + 0.000237 = 1.637142 (next terms < 2e-5).
    g = GeometryRecord(0.0, 0.0, 0.0, 0.0, 50.0, "spiral", (0.0, 0.5))
    x, y, _, _ = evaluate_geometry(g, np.array([10.0]))
    assert abs(x[0] - 9.752894) < 1e-4
    assert abs(y[0] - 1.637142) < 1e-4


def test_poly3_straight_diagonal_and_parabola_heading():
    # v(u) = u: a 45° line, so arc length 10·√2 reaches (10, 10).
    g = GeometryRecord(0.0, 0.0, 0.0, 0.0, 10 * math.sqrt(2), "poly3", (0.0, 1.0, 0.0, 0.0))
    x, y, hdg, _ = evaluate_geometry(g, np.array([10 * math.sqrt(2)]))
    np.testing.assert_allclose([x[0], y[0], hdg[0]], [10.0, 10.0, math.pi / 4], atol=1e-6)
    # v(u) = 0.1·u²: heading at the start is the start heading, curvature 2c = 0.2.
    g2 = GeometryRecord(0.0, 0.0, 0.0, 0.5, 5.0, "poly3", (0.0, 0.0, 0.1, 0.0))
    _, _, hdg2, k2 = evaluate_geometry(g2, np.array([0.0]))
    assert abs(hdg2[0] - 0.5) < 1e-12 and abs(k2[0] - 0.2) < 1e-12


def test_param_poly3_normalized_and_arclength_agree():
    # u(p) = L·p, v(p) = 0 in normalized form is a straight line of length L, as is u(p) = p with pRange
    # arcLength; rotated by hdg = π/2 both go north: the end point is (x0, y0 + L).
    normalized = GeometryRecord(0.0, 1.0, 1.0, math.pi / 2, 12.0, "paramPoly3", (0, 12, 0, 0, 0, 0, 0, 0), True)
    arclength = GeometryRecord(0.0, 1.0, 1.0, math.pi / 2, 12.0, "paramPoly3", (0, 1, 0, 0, 0, 0, 0, 0), False)
    for g in (normalized, arclength):
        x, y, hdg, _ = evaluate_geometry(g, np.array([6.0, 12.0]))
        np.testing.assert_allclose([x[1], y[1]], [1.0, 13.0], atol=1e-9)
        np.testing.assert_allclose([x[0], y[0]], [1.0, 7.0], atol=1e-9)
        assert abs(hdg[1] - math.pi / 2) < 1e-12


def test_reference_line_picks_the_geometry_of_each_s():
    # A 10 m line east, then an arc of curvature 1/10 from (10, 0): at s = 10 + 5π the arc has turned 90°.
    geoms = [
        GeometryRecord(0.0, 0.0, 0.0, 0.0, 10.0, "line"),
        GeometryRecord(10.0, 10.0, 0.0, 0.0, 5 * math.pi, "arc", (0.1,)),
    ]
    x, y, hdg, _ = evaluate_reference_line(geoms, np.array([5.0, 10.0 + 5 * math.pi]))
    np.testing.assert_allclose([x[0], y[0], x[1], y[1], hdg[1]], [5, 0, 20, 10, math.pi / 2], atol=1e-9)


def test_piecewise_cubic_value_and_slope():
    # Second record from s = 4: 1 + 2·ds + 3·ds² at s = 6 → ds = 2: 1 + 4 + 12 = 17; slope 2 + 6·2 = 14.
    records = [Poly3(0.0, 5.0, 0.0, 0.0, 0.0), Poly3(4.0, 1.0, 2.0, 3.0, 0.0)]
    value, slope = evaluate_cubic(records, np.array([1.0, 6.0]))
    np.testing.assert_allclose(value, [5.0, 17.0])
    np.testing.assert_allclose(slope, [0.0, 14.0])


_OFFSET_ROAD = """<?xml version="1.0"?>
<OpenDRIVE><header revMajor="1" revMinor="6" name="offsets"/>
<road name="r" length="40" id="5" junction="-1">
 <planView><geometry s="0" x="0" y="0" hdg="0" length="40"><line/></geometry></planView>
 <elevationProfile><elevation s="0" a="1.0" b="0.1" c="0" d="0"/></elevationProfile>
 <lanes>
  <laneOffset s="0" a="0.5" b="0.01" c="0" d="0"/>
  <laneSection s="0">
   <center><lane id="0" type="none"/></center>
   <right>
    <lane id="-1" type="driving"><width sOffset="0" a="3" b="0.02" c="0" d="0"/></lane>
    <lane id="-2" type="parking"><border sOffset="0" a="8" b="0" c="0" d="0"/></lane>
   </right>
  </laneSection>
  <laneSection s="20">
   <center><lane id="0" type="none"/></center>
   <left><lane id="1" type="biking"><width sOffset="5" a="2" b="0" c="0" d="0"/>
     <width sOffset="0" a="1" b="0" c="0" d="0"/></lane></left>
   <right><lane id="-1" type="driving"><width sOffset="0" a="3" b="0" c="0" d="0"/></lane></right>
  </laneSection>
 </lanes>
</road></OpenDRIVE>
"""


def test_lane_width_offset_and_border(tmp_path):
    path = tmp_path / "offsets.xodr"
    path.write_text(_OFFSET_ROAD)
    m = load_opendrive(path)
    # s = 10: offset 0.5 + 0.1 = 0.6; lane -1 width 3 + 0.2 = 3.2, centre t = 0.6 − 1.6 = −1.0 → CARLA y = +1.0.
    wp = m.get_waypoint_xodr(5, -1, 10.0)
    assert abs(wp.lane_width - 3.2) < 1e-6
    np.testing.assert_allclose(wp.transform.location.to_list(), [10.0, 1.0, 2.0], atol=1e-6)  # z = 1 + 0.1·10
    # Pitch: slope 0.1 uphill along +s → atan(0.1) = 5.7106°.
    assert abs(wp.transform.rotation.pitch - math.degrees(math.atan(0.1))) < 1e-6
    # Lane -2 ends 8 m from the centre lane: inner 3.2, outer 8 → width 4.8, centre t = 0.6 − 5.6 = −5.0.
    wp2 = m.get_waypoint_xodr(5, -2, 10.0)
    assert abs(wp2.lane_width - 4.8) < 1e-6 and abs(wp2.transform.location.y - 5.0) < 1e-6
    # Second section (from s = 20): lane 1 widths sorted by sOffset: 1 m until s = 25, then 2 m.
    # At s = 30: offset 0.8, lane 1 centre t = 0.8 + 1 = 1.8 → CARLA y = −1.8. It drives west; its centre drifts
    # left of the reference by the offset slope 0.01, so its OpenDRIVE direction is π + atan(0.01) and the CARLA
    # yaw −(180° + 0.573°) wraps to 180° − 0.573° = 179.427°.
    wp3 = m.get_waypoint_xodr(5, 1, 30.0)
    assert wp3.section_id == 1 and abs(wp3.lane_width - 2.0) < 1e-9
    expected_yaw = 180.0 - math.degrees(math.atan(0.01))
    np.testing.assert_allclose([wp3.transform.location.y, wp3.transform.rotation.yaw], [-1.8, expected_yaw], atol=1e-6)
