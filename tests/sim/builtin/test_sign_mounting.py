"""Signs and lights stand where their ``<signal>`` records put them, and the annotation box is what is rendered.

OpenDRIVE: ``zOffset`` is the height of the signal's bottom above the road's reference line, ``height`` its height.
The plate (head) mesh, the LiDAR returns from it and the annotated box must all span that.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.collection.annotations import traffic_light_box, trigger_sign_box
from b2d_data.format.semantic import SemanticTag as T
from b2d_data.format.transform import BoundingBox, Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.sim.api import ActorKind, ActorState
from b2d_data.sim.builtin.furniture import furniture_from_map
from b2d_data.sim.builtin.sensors.fixture_mesh import (
    fixture_of_light,
    fixture_of_sign,
    fixture_static_mesh,
    lamp_mesh,
)
from b2d_data.sim.builtin.sensors.raycast import RayCaster
from b2d_data.sim.builtin.sensors.scene_mesh import merge
from b2d_data.sim.builtin.traffic_lights import TrafficLightController, sign_info

# A 100 m straight road along +x whose reference line lies 0.5 m up (elevation a = 0.5), one 3.5 m lane each way
# and a 2 m sidewalk on the right. On the right (t = −6, CARLA y = +6), governing the eastbound lane −1:
# a stop sign at s = 50 (zOffset 1.8, 0.97 × 0.97 m), a light at s = 80 that the record does not lift (zOffset 0,
# like the generated towns' lights) and a light at s = 90 lifted by zOffset 2.5 (1.16 m high, 0.52 m wide).
_SIGNAL = (
    '<signal name="{name}" id="{id}" s="{s}" t="-6" zOffset="{z}" hOffset="0" roll="0" pitch="0" orientation="+"'
    ' dynamic="{dyn}" country="OpenDRIVE" type="{type}" subtype="-1" value="-1" height="{h}" width="{w}">'
    '<validity fromLane="-1" toLane="-1"/></signal>'
)
XODR = f"""<?xml version="1.0" standalone="yes"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="4" name="Signs" version="1.00" north="0" south="0" east="0" west="0"/>
  <road name="r" length="100.0" id="1" junction="-1">
    <link/>
    <planView><geometry s="0.0" x="0.0" y="0.0" hdg="0.0" length="100.0"><line/></geometry></planView>
    <elevationProfile><elevation s="0.0" a="0.5" b="0.0" c="0.0" d="0.0"/></elevationProfile>
    <lanes>
      <laneSection s="0.0">
        <left><lane id="1" type="driving" level="false"><link/><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
        </left>
        <center><lane id="0" type="driving" level="false"><link/></lane></center>
        <right>
          <lane id="-1" type="driving" level="false"><link/><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
          <lane id="-2" type="sidewalk" level="false"><link/><width sOffset="0" a="2.0" b="0" c="0" d="0"/></lane>
        </right>
      </laneSection>
    </lanes>
    <signals>
      {_SIGNAL.format(name="Stop", id=1, s=50, z=1.8, dyn="no", type=206, h=0.97, w=0.97)}
      {_SIGNAL.format(name="Light", id=2, s=80, z=0.0, dyn="yes", type=1000001, h=1.16, w=0.52)}
      {_SIGNAL.format(name="HighLight", id=3, s=90, z=2.5, dyn="yes", type=1000001, h=1.16, w=0.52)}
    </signals>
  </road>
</OpenDRIVE>
"""


@pytest.fixture(scope="module")
def signs_town(tmp_path_factory):
    path = tmp_path_factory.mktemp("xodr") / "Signs.xodr"
    path.write_text(XODR)
    return load_opendrive(path)


@pytest.fixture(scope="module")
def furniture(signs_town):
    lights, signs = furniture_from_map(signs_town)
    (stop,) = signs
    infos = TrafficLightController([(10 + i, spec) for i, spec in enumerate(lights)]).infos()
    by_signal = {info.opendrive_id: info for info in infos.values()}
    return sign_info(1, stop), by_signal["2"], by_signal["3"]


def _ego() -> ActorState:
    return ActorState(
        id=99, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE, transform=Transform(Location(30.0, 1.75, 0.5)),
        velocity=Location(), angular_velocity=Location(), acceleration=Location(),
        bounding_box=BoundingBox(Location(0.0, 0.0, 0.75), Location(2.4, 1.0, 0.75)), semantic_tags=(14,),
    )  # fmt: skip


def test_stop_plate_box_and_mesh_span_the_signal_record(signs_town, furniture):
    stop, _, _ = furniture
    # Reference line at z 0.5: bottom 0.5 + 1.8 = 2.3, top 2.3 + 0.97 = 3.27 ⇒ centre 2.785, half height 0.485;
    # half width 0.97 / 2; at s = 50, t = −6 ⇒ CARLA (50, 6). The pole stands on the reference line (z 0.5).
    box = trigger_sign_box(signs_town, _ego(), stop, None, False)
    np.testing.assert_allclose(box["center"], [50.0, 6.0, 2.785], atol=1e-9)
    np.testing.assert_allclose(box["location"], [50.0, 6.0, 2.785], atol=1e-9)
    np.testing.assert_allclose(box["extent"], [0.05, 0.485, 0.485], atol=1e-9)
    mesh = fixture_static_mesh([fixture_of_sign(stop)])
    plate = mesh.vertices[mesh.tags == T.TRAFFIC_SIGN].reshape(-1, 3)
    # The lane runs east (yaw 0): the plate faces west (−x), 2 cm thick around x = 50, 0.97 m wide across y.
    np.testing.assert_allclose(plate.min(axis=0), [49.98, 6.0 - 0.485, 2.3], atol=1e-5)
    np.testing.assert_allclose(plate.max(axis=0), [50.02, 6.0 + 0.485, 3.27], atol=1e-5)
    pole = mesh.vertices[mesh.tags == T.POLE].reshape(-1, 3)
    assert pole[:, 2].min() == pytest.approx(0.5)
    # Behind the plate (+x): its axis at 50 + 0.05 (box half depth) + 0.09 (pole radius).
    assert pole[:, 0].mean() == pytest.approx(50.14, abs=1e-5)


def test_lidar_returns_from_the_plate_lie_in_its_box(furniture):
    stop, _, _ = furniture
    caster = RayCaster(fixture_static_mesh([fixture_of_sign(stop)]))
    heights = np.array([2.2, 2.35, 2.785, 3.2, 3.35], np.float32)
    origins = np.stack([np.full(5, 40.0), np.full(5, 6.0), heights], axis=1).astype(np.float32)
    hits = caster.cast(origins, np.tile(np.float32([1.0, 0.0, 0.0]), (5, 1)), 50.0)
    # From 10 m in front, level rays along the plate's centre column (y = 6): below the plate (2.2) the pole
    # behind it (front of the 6-sided pole at 50.14 − 0.09 · cos 30° … 50.14 − 0.09); 2.35 … 3.2 the plate's
    # front face at x = 49.98 (tag 8, id 1); above the plate's top (3.27) nothing.
    assert hits.hit.tolist() == [True, True, True, True, False]
    assert hits.tags[:4].tolist() == [T.POLE, T.TRAFFIC_SIGN, T.TRAFFIC_SIGN, T.TRAFFIC_SIGN]
    assert hits.actor_ids[:4].tolist() == [1, 1, 1, 1]
    np.testing.assert_allclose(hits.t[1:4], 9.98, atol=1e-4)
    assert 50.14 - 0.09 - 40.0 - 1e-4 <= hits.t[0] <= 50.14 - 0.09 * math.cos(math.pi / 6) - 40.0 + 1e-4


def test_light_heads_fill_their_boxes(signs_town, furniture):
    _, low, high = furniture
    ego = _ego()
    # zOffset 0 does not lift the light: the standard head, centred 3.0 m above the lane (z 0.5) ⇒ 3.5, half
    # height 1.16 / 2 = 0.58. zOffset 2.5: bottom 0.5 + 2.5 = 3.0, top 4.16 ⇒ centre 3.58.
    for info, centre_z in ((low, 3.5), (high, 3.58)):
        box = traffic_light_box(signs_town, ego, info, None, False)
        assert box["center"][2] == pytest.approx(centre_z)
        np.testing.assert_allclose(box["extent"], [0.25, 0.26, 0.58], atol=1e-9)
        mesh = fixture_static_mesh([fixture_of_light(info)])
        head = mesh.vertices[mesh.tags == T.TRAFFIC_LIGHT].reshape(-1, 3)
        assert (head[:, 2].min(), head[:, 2].max()) == pytest.approx((centre_z - 0.58, centre_z + 0.58))
        pole = mesh.vertices[mesh.tags == T.POLE].reshape(-1, 3)
        assert pole[:, 2].min() == pytest.approx(0.5)  # on the reference line, not lifted by zOffset


@pytest.mark.parametrize("town", ["Town07", "Town10HD"])
def test_every_shipped_sign_and_light_fills_its_box(carla_maps_dir, town):
    lights, signs = furniture_from_map(load_opendrive(carla_maps_dir / f"{town}.xodr"))
    infos = [(fixture_of_sign(sign_info(i, s)), s.level_bbox, T.TRAFFIC_SIGN) for i, s in enumerate(signs)]
    controller = TrafficLightController([(1000 + i, spec) for i, spec in enumerate(lights)])
    infos += [(fixture_of_light(t), t.level_bbox, T.TRAFFIC_LIGHT) for t in controller.infos().values()]
    for fixture, level, tag in infos:
        mesh = merge([fixture_static_mesh([fixture]), lamp_mesh([fixture], {})])  # lamps: lights only
        v = mesh.vertices[mesh.tags == tag].reshape(-1, 3) - level.location.to_array()
        a = math.radians(level.rotation.yaw)
        local = np.stack([math.cos(a) * v[:, 0] + math.sin(a) * v[:, 1], -math.sin(a) * v[:, 0] + math.cos(a) * v[:, 1],
                          v[:, 2]], axis=1)  # fmt: skip
        half = level.extent.to_array()
        # Inside the box (within 0.1 mm: float32 vertices), and spanning its full width and height (the face the
        # cameras and the LiDAR see); a light's housing and lamps span its depth too.
        assert (np.abs(local) <= half + 1e-4).all(), fixture.instance_id
        spanned = slice(0, 3) if tag == T.TRAFFIC_LIGHT else slice(1, 3)
        np.testing.assert_allclose(local[:, spanned].max(axis=0), half[spanned], atol=1e-4)
        np.testing.assert_allclose(local[:, spanned].min(axis=0), -half[spanned], atol=1e-4)
