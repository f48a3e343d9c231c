"""The expert vector's BEV raster on a hand-built snapshot of a real town: every lit cell worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.collection.expert_assessment import BevRasterizer, assessment_vector, boxes_overlap_cells
from b2d_data.format import expert_feature as ef
from b2d_data.format.expert_actions import action_control
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform
from b2d_data.format.weather import PRESETS
from b2d_data.maps import LaneType
from b2d_data.sim.api import (
    ActorKind,
    Snapshot,
    TrafficLightInfo,
    TrafficLightState,
    TrafficSignInfo,
)

from .conftest import make_actor


class _EgoFrame:
    """World poses at (forward, right) offsets from an ego pose, and turned relative to it."""

    def __init__(self, ego: Transform) -> None:
        self.ego = ego
        yaw = math.radians(ego.rotation.yaw)
        self.fwd = np.array([math.cos(yaw), math.sin(yaw)])
        self.right = np.array([-math.sin(yaw), math.cos(yaw)])

    def at(self, forward: float, right: float, turn: float = 0.0) -> Transform:
        p = np.array([self.ego.location.x, self.ego.location.y]) + forward * self.fwd + right * self.right
        return Transform(Location(p[0], p[1], self.ego.location.z), Rotation(yaw=self.ego.rotation.yaw + turn))


def _lit(channel: np.ndarray) -> set[tuple[int, int]]:
    return {(int(r), int(c)) for r, c in zip(*np.nonzero(channel))}


@pytest.fixture(scope="module")
def scene(town01):
    wp = next(w for w in town01.generate_waypoints(20.0) if abs(math.sin(math.radians(w.transform.rotation.yaw))) > 0.5)
    ego_tf = Transform(wp.transform.location, wp.transform.rotation)
    f = _EgoFrame(ego_tf)
    ego = make_actor(1, "vehicle.lincoln.mkz_2020", ActorKind.VEHICLE, ego_tf, (2.45, 1.06, 0.75), speed=5.0,
                 role_name="hero")
    # A car 10.5 m ahead (half length 2.2, half width 0.9): forward 8.3–12.7 → rows 1–3; right −0.9–0.9 → cols 7, 8.
    ahead = make_actor(2, "vehicle.audi.a2", ActorKind.VEHICLE, f.at(10.5, 0.0), (2.2, 0.9, 0.7))
    # A car 1 m ahead and 6.3 m right, turned 90°: its length runs along the ego's right axis:
    # forward 0.1–1.9 → row 7; right 4.3–8.3 → cols 10, 11, 12.
    across = make_actor(3, "vehicle.audi.a2", ActorKind.VEHICLE, f.at(1.0, 6.3, 90.0), (2.0, 0.9, 0.7))
    # A parked-car prop 12.9 m behind, 6.9 m left: forward −14.9 to −10.9 → rows 13 (−12, −10], 14, 15 (−16, −14];
    # right −7.7 to −6.1 → col 4 [−8, −6).
    parked = make_actor(4, "static.prop.mesh.Car", ActorKind.PROP, f.at(-12.9, -6.9), (2.0, 0.8, 0.7))
    # A walker 5 m ahead, 1.5 m left: forward 4.75–5.25 → row 5; right −1.75 to −1.25 → col 7.
    walker = make_actor(5, "walker.pedestrian.0001", ActorKind.WALKER, f.at(5.0, -1.5), (0.25, 0.25, 0.9))
    far = make_actor(6, "vehicle.audi.a2", ActorKind.VEHICLE, f.at(60.0, 0.0), (2.2, 0.9, 0.7))
    trigger = BoundingBox(Location(0.0, -3.0, 0.0), Location(1.0, 1.5, 1.0))
    none_box = BoundingBox(Location(), Location(0.1, 0.1, 0.1))

    def light(light_id, tf, state):
        return TrafficLightInfo(light_id, tf, state, trigger, (), (), 0, str(light_id), none_box, tf)

    # A red light 14 m ahead, 3 m right, its trigger 3 m to its left: forward 13–15 → rows 0, 1; right −1.5–1.5 →
    # cols 7, 8. A green light behind lights nothing.
    red = light(10, f.at(14.0, 3.0), TrafficLightState.RED)
    green = light(11, f.at(-8.0, 3.0), TrafficLightState.GREEN)
    # A stop sign whose trigger (centre 10 m behind, 3 m right): forward −11 to −9 → rows 12, 13; right 1.5–4.5 →
    # cols 8, 9, 10.
    stop = TrafficSignInfo(20, "traffic.stop", f.at(-10.0, 6.0), trigger, none_box, f.at(-10.0, 6.0))
    snapshot = Snapshot(
        frame=4, timestamp=0.2, actors={a.id: a for a in (ego, ahead, across, parked, walker, far)},
        traffic_lights={10: red, 11: green}, traffic_signs={20: stop}, collisions=(), weather=PRESETS[1],
    )  # fmt: skip
    # Route: points 1 m apart straight ahead from the ego origin, 0.5 m to its right.
    route = np.array([f.at(k, 0.5).location.to_array()[:2] for k in range(0, 40)])
    return town01, snapshot, ego, route, f


def test_raster_cells_by_hand(scene):
    town, snapshot, ego, route, _ = scene
    raster = BevRasterizer(town).raster(snapshot, ego, route)
    assert raster.shape == ef.SHAPE and raster.dtype == np.float32
    assert _lit(raster[ef.VEHICLES]) == {
        (1, 7), (1, 8), (2, 7), (2, 8), (3, 7), (3, 8),  # the car ahead
        (7, 10), (7, 11), (7, 12),  # the car across
        (13, 4), (14, 4), (15, 4),  # the parked car
    }  # fmt: skip
    assert _lit(raster[ef.WALKERS]) == {(5, 7)}
    assert _lit(raster[ef.STOP]) == {(0, 7), (0, 8), (1, 7), (1, 8), (12, 8), (12, 9), (12, 10), (13, 8), (13, 9),
                                      (13, 10)}  # fmt: skip
    # Route points at forward k = 0 … 15 (k = 16 is the row-0 upper edge, included), right 0.5 → col 8:
    # k = 0 → row 8; k ∈ (2r', 2r' + 2] → row 7 − r'. So rows 0–8.
    assert _lit(raster[ef.ROUTE]) == {(r, 8) for r in range(0, 9)}
    assert np.all(raster[ef.SPEED] == pytest.approx(5.0 / 25.0))


def test_drivable_channel_matches_the_map(scene):
    town, snapshot, ego, route, f = scene
    raster = BevRasterizer(town).raster(snapshot, ego, route)
    # Independent check: CARLA's rule "inside the lane" (get_waypoint without projection) at every cell centre.
    expected = np.zeros((16, 16), bool)
    for r in range(16):
        for c in range(16):
            centre = f.at(16.0 - 2.0 * r - 1.0, -16.0 + 2.0 * c + 1.0).location
            expected[r, c] = town.get_waypoint(centre, project_to_road=False, lane_type=LaneType.DRIVING) is not None
    drivable = raster[ef.DRIVABLE].astype(bool)
    assert expected[7:9, 7:9].any() and drivable[7:9, 7:9].any()  # the ego stands on its lane
    assert 0 < expected.sum() < 256
    # The lookup uses lane-centre samples 0.5 m apart, so a centre within a few cm of a lane edge may differ.
    assert (drivable != expected).sum() <= 3


def test_overlap_is_exact_at_edges():
    # A 2 m square box exactly on cell (2, 8) — forward (10, 12], right [0, 2) — lights that cell only.
    lit = boxes_overlap_cells(np.array([[11.0, 1.0]]), np.array([0.0]), np.array([[1.0, 1.0]]))
    assert _lit(lit) == {(2, 8)}
    # Turned 45°, the same box reaches 1.41 m from its centre: its corners enter the four side neighbours.
    lit = boxes_overlap_cells(np.array([[11.0, 1.0]]), np.array([math.pi / 4]), np.array([[1.0, 1.0]]))
    assert _lit(lit) == {(2, 8), (1, 8), (3, 8), (2, 7), (2, 9)}


def test_vector_holds_progress_and_the_nearest_action(scene):
    town, snapshot, ego, route, _ = scene
    anno = {"throttle": 0.74, "steer": 0.04, "brake": 0.0, "reverse": False}
    vec = assessment_vector(BevRasterizer(town), snapshot, ego, route, 0.375, anno)
    assert vec.shape == (1538,) and vec.dtype == np.float32
    assert vec[-2] == 0.375
    # (0.74, 0.04): nearest (0.7, 0) d² = 0.0016 + 0.0016; (0.7, 0.1) 0.0016 + 0.0036 → action 5.
    assert vec[-1] == 5.0 and action_control(vec[-1]).throttle == 0.7
    assert np.array_equal(ef.unflatten(vec[:-2]), BevRasterizer(town).raster(snapshot, ego, route))
