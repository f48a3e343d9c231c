"""Bench2Drive HD-map npz layout (format.md §6) on the tiny town."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def hdmap_path(tiny_map, tmp_path_factory):
    return tiny_map.save_hdmap(tmp_path_factory.mktemp("hd") / "Town90_HD_map.npz")


@pytest.fixture(scope="module")
def hdmap(hdmap_path):
    with np.load(hdmap_path, allow_pickle=True) as npz:  # our own file, so numpy's unrestricted reader is the reference
        assert list(npz.keys()) == ["arr"]
        arr = npz["arr"]
    assert arr.dtype == object and arr.ndim == 2 and arr.shape[1] == 2
    return dict(arr)


def test_roads_and_lane_keys(hdmap):
    # Only driving lanes with successors start walks (CARLA's topology): roads 1, 10, 11, 12; the exits have no
    # successor lanes and are never reached within their own road. Road 2 appears for its stop-sign volume.
    assert set(hdmap) == {1, 2, 10, 11, 12}
    assert all(isinstance(k, int) for k in hdmap)
    assert set(hdmap[1]) == {-1, -2, "Trigger_Volumes"}
    assert set(hdmap[2]) == {"Trigger_Volumes"}


def test_centre_line_element(hdmap):
    centre = [e for e in hdmap[1][-1] if e["Type"] == "Center"]
    assert len(centre) == 1
    e = centre[0]
    assert set(e) == {"Points", "Type", "Color", "Topology", "TopologyType", "Left", "Right"}
    # 0.05 m steps over the 50 m lane: s = 0, 0.05, …, 50 → 1001 points of ((x, y, z), (roll, pitch, yaw), junction).
    points = e["Points"]
    assert len(points) == 1001
    (xyz, rot, junction) = points[0]
    assert len(xyz) == 3 and len(rot) == 3 and junction is False
    xs = np.array([p[0][0] for p in points])
    np.testing.assert_allclose(np.diff(xs), 0.05, atol=1e-9)
    np.testing.assert_allclose([p[0][1] for p in points], 1.75, atol=1e-9)
    assert e["Color"] == "White" and e["TopologyType"] == "Normal"
    assert e["Topology"] == [(10, -1), (11, -1)]
    assert e["Left"] == (1, 1) and e["Right"] == (1, -2)
    junction_centre = [x for x in hdmap[11][-1] if x["Type"] == "Center"][0]
    assert junction_centre["TopologyType"] == "Junction" and junction_centre["Points"][0][2] is True


def test_boundary_elements(hdmap):
    by_type = {e["Type"]: e for e in hdmap[1][-1] if e["Type"] != "Center"}
    # Left of lane -1 is the solid yellow centre line at y = 1.75 − 1.75 = 0; right is its broken white line at 3.5.
    left, right = by_type["Solid"], by_type["Broken"]
    assert left["Color"] == "Yellow" and right["Color"] == "White"
    assert set(left) == {"Points", "Type", "Color", "Topology"}
    assert len(left["Points"][0]) == 2 and len(left["Points"][0][0]) == 3
    np.testing.assert_allclose([p[0][1] for p in left["Points"]], 0.0, atol=1e-9)
    np.testing.assert_allclose([p[0][1] for p in right["Points"]], 3.5, atol=1e-9)


def test_trigger_volumes(hdmap):
    (light,) = hdmap[1]["Trigger_Volumes"]
    assert light["Type"] == "TrafficLight"
    # Two lanes × (2 points at the last non-junction waypoint + 2 points 0.5 m earlier), each ±0.4·3.5 = ±1.4 m.
    pts = np.array(light["Points"])
    assert pts.shape == (8, 3)
    np.testing.assert_allclose(sorted(set(np.round(pts[:, 1], 6))), [0.35, 3.15, 3.85, 6.65], atol=1e-6)
    np.testing.assert_allclose(light["ParentActor_Location"], [48.0, 8.0, 0.0], atol=1e-9)
    stop_volumes = hdmap[2]["Trigger_Volumes"]
    assert {v["Type"] for v in stop_volumes} == {"StopSign"} and len(stop_volumes) == 2
    corners = np.array(stop_volumes[0]["Points"])
    # Five corners of a square of half size 1.575 around the box centre (88.425, 1.75).
    assert corners.shape == (5, 3)
    np.testing.assert_allclose(corners[:, 0], 88.425 + 1.575 * np.array([-1, 1, 1, 1, -1]), atol=1e-6)


def test_written_map_reads_with_the_restricted_unpickler(hdmap_path, hdmap):
    from b2d_data.codecs.object_npz import load_object_npz
    from b2d_data.loaders import HDMap

    # The loaders' reader admits only numpy's array globals; the map we write must need no other.
    assert dict(load_object_npz(hdmap_path, "arr")) == hdmap
    # Every lane element and trigger volume becomes one polyline (each has at least the 2 points a line needs).
    elements = sum(len(v) for road in hdmap.values() for v in road.values())
    assert HDMap.load(hdmap_path).num_polylines == elements
