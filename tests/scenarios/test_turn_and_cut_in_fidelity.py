"""Issue 23 rows 23 and 24: InvadingTurn's cones and flow offset, HighwayCutIn's sync and cut-in, as
scenario_runner's ``leaderboard-2.0`` branch (Bench2Drive ``da12001``) has them.

Each test names the reference file and works out the expected value by hand from it. The scenarios are built on
small hand-written OpenDRIVE roads without a simulator where their constructors need only the map and the route.
"""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
import pytest

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import load_opendrive
from b2d_data.scenarios.catalog.road_geometry import lane_walk
from b2d_data.scenarios.framework import ScenarioContext, scenario_class
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import ScenarioConfig

EGO = 1


def _lane(lane_id: int, kind: str, width: float) -> str:
    return (f'<lane id="{lane_id}" type="{kind}" level="false">'
            f'<link><predecessor id="{lane_id}"/><successor id="{lane_id}"/></link>'
            f'<width sOffset="0" a="{width}" b="0" c="0" d="0"/><roadMark sOffset="0" type="solid" color="white" width="0.15" laneChange="none"/></lane>')  # fmt: skip


def _two_way_road(split: float, near_width: float, far_width: float) -> str:
    """A straight 400 m two-way road heading east: lane -1 (eastbound) 3.5 m; lane 1 (westbound) ``near_width`` m
    wide up to x = ``split`` and ``far_width`` m beyond."""
    sections = "".join(
        f'<laneSection s="{s}"><left>{_lane(1, "driving", w)}</left>'
        '<center><lane id="0" type="none" level="false"/></center>'
        f'<right>{_lane(-1, "driving", 3.5)}{_lane(-2, "sidewalk", 2.0)}</right></laneSection>'
        for s, w in ((0, near_width), (split, far_width))
    )
    return (
        '<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="4" name="TwoWay"/>'
        '<road name="Road 1" length="400" id="1" junction="-1"><link/>'
        '<type s="0" type="town"><speed max="50" unit="km/h"/></type>'
        '<planView><geometry s="0" x="0" y="0" hdg="0" length="400"><line/></geometry></planView>'
        '<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>'
        f'<lanes><laneOffset s="0" a="0" b="0" c="0" d="0"/>{sections}</lanes></road></OpenDRIVE>'
    )


@pytest.fixture(scope="module")
def two_way(tmp_path_factory):
    """Lane 1 is 3.0 m wide up to x = 120 and 4.0 m beyond."""
    path = tmp_path_factory.mktemp("roads") / "TwoWay.xodr"
    path.write_text(_two_way_road(120.0, 3.0, 4.0))
    return load_opendrive(path)


def _invading_turn(town, distance: float, offset: float = 0.25):
    y = 3.5 / 2.0  # lane -1's centre (CARLA y: OpenDRIVE's right is +y)
    lane = lane_walk(town.get_waypoint(Location(2.0, y, 0.0)), 390.0)
    dense = DenseRoute.from_pairs([(wp, RoadOption.LANEFOLLOW) for wp in lane], town)
    config = ScenarioConfig("InvadingTurn_1", "InvadingTurn", Transform(Location(20.0, y, 0.0), Rotation(yaw=0.0)),
                            {"distance": {"value": str(distance)}, "offset": {"value": str(offset)}})  # fmt: skip
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
    return scenario_class("InvadingTurn")(ctx)


@pytest.mark.parametrize(("distance", "cones"), [(100.0, 10), (90.0, 9), (95.0, 10)])
def test_invading_turn_cones_as_lb20(two_way, distance, cones):
    # invading_turn.py _create_obstacle: next_wp = source.next(10)[0]; dist = 0; while dist < 0.5 * distance:
    # next_wp = next_wp.next(5)[0], a cone there, dist += 5. So ceil(distance / 10) cones, 15, 20, ... m from the
    # source: distance 100 -> dist 0..45, 10 cones (15..60 m); 90 -> 9 (15..55 m); 95 -> dist 0..45 (45 < 47.5),
    # 10. (Ours had 11, 10 and 10: `s <= 15 + distance / 2`.) The source is on lane 1 abreast of the trigger point
    # + distance + 30: x = 20 + distance + 30; lane 1 runs west, so cone k stands at x = source - 15 - 5 k; each
    # 0.8 x width / 2 right of lane 1's centre, toward the road's edge.
    scenario = _invading_turn(two_way, distance)
    source_x = 20.0 + distance + 30.0
    assert scenario.flow_waypoints[0].transform.location.x == pytest.approx(source_x, abs=0.01)
    transforms = scenario.cone_transforms()
    assert len(transforms) == cones
    for k, t in enumerate(transforms):
        assert t.location.x == pytest.approx(source_x - 15.0 - 5.0 * k, abs=0.01)
        # lane 1 (width w: 4.0 m from x = 120 on, 3.0 m before) has its centre at CARLA y = -w / 2 (left of the
        # reference line) and its right toward -y: the cone at -(w / 2 + 0.4 w) = -0.9 w
        width = 4.0 if t.location.x > 120.0 else 3.0
        assert t.location.y == pytest.approx(-0.9 * width, abs=0.01)


def test_invading_turn_offset_uses_the_sink_lane_width(two_way):
    # invading_turn.py _initialize_actors: _true_offset = -(offset + sink_wp.lane_width / 2 - 0.7), sink_wp =
    # trigger waypoint's left lane (lane 1 at x = 20: 3.0 m), not the source's (x = 150: 4.0 m):
    # -(0.25 + 1.5 - 0.7) = -1.05 (ours was -(0.25 + 2.0 - 0.7) = -1.55).
    scenario = _invading_turn(two_way, 100.0)
    assert scenario.flow_waypoints[0].lane_width == pytest.approx(4.0)
    assert scenario.lateral == pytest.approx(-1.05)


# ------------------------------------------------------------------------------------------------ row 24: HighwayCutIn

CAR = 2


@pytest.fixture(scope="module")
def cut_in(tmp_path_factory):
    """HighwayCutIn on the first generated route (seed 0) of the generated town with every layout."""
    from b2d_data.maps.towngen import write_town
    from b2d_data.scenarios.placement import make_routes

    town = load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))
    route = make_routes(town, "HighwayCutIn", 1, seed=0)[0]
    dense = DenseRoute.from_route(town, route)
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=route.scenarios[0],  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
    scenario = scenario_class("HighwayCutIn")(ctx)
    scenario.actor_id = CAR
    return scenario


def _vehicle(actor_id: int, transform: Transform, speed: float, role: str = "scenario"):
    from b2d_data.format.transform import BoundingBox, Vector3D
    from b2d_data.sim.api import ActorKind, ActorState

    f = transform.get_forward_vector()
    return ActorState(
        id=actor_id, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE, transform=transform,
        velocity=Vector3D(f.x * speed, f.y * speed, 0.0), angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.45, 1.06, 0.75)), semantic_tags=(14,),
        role_name=role,
    )  # fmt: skip


def _snapshot(*actors):
    from b2d_data.format.weather import ROUTE_DEFAULT
    from b2d_data.sim.api import Snapshot

    return Snapshot(frame=1, timestamp=0.0, actors={a.id: a for a in actors}, traffic_lights={}, traffic_signs={},
                    collisions=(), weather=ROUTE_DEFAULT)  # fmt: skip


def _on_route(scenario, metres_before_exit: float) -> Transform:
    """The ego's route pose ``metres_before_exit`` m (along the route) before its junction exit (negative: past it)."""
    dense = scenario.ctx.route
    s = dense.cumulative_length
    k = int(np.argmin(np.abs(s - (s[scenario.exit_index] - metres_before_exit))))
    return dense.waypoints[k].transform


def _on_walk(scenario, metres_before_target: float) -> Transform:
    """The cut-in car's pose on its lane walk ``metres_before_target`` m before its target (1 m steps)."""
    k = scenario.path.index(scenario.target_wp) - round(metres_before_target)
    return scenario.path[k].transform


def test_highway_cut_in_sync_speed_from_straight_line_distances(cut_in):
    # atomic_behaviors.py SyncArrivalWithAgent.update: distance = calculate_distance(actor, actor_target) (straight
    # line), time_reference = calculate_distance(ego, reference_target) / ego speed, desired velocity = distance /
    # time_reference. Car 100 m up its walk, ego 120 m before its exit (along its route) at 20 m/s.
    car, ego = _on_walk(cut_in, 100.0), _on_route(cut_in, 120.0)
    snap = _snapshot(_vehicle(EGO, ego, 20.0, "hero"), _vehicle(CAR, car, 10.0))
    d_car = car.location.distance(cut_in.target_wp.transform.location)
    d_ego = ego.location.distance(cut_in.ego_exit.transform.location)
    # the route bends there: the straight line is far shorter than the route (ours used route and walk lengths:
    # 100 x 20 / 120 = 16.7 m/s)
    assert d_ego < 100.0
    expected = d_car * 20.0 / d_ego
    assert expected > 19.0
    assert cut_in.sync_step(snap) == (False, pytest.approx(expected))
    # an ego standing still: infinite time to arrival, speed 0
    snap = _snapshot(_vehicle(EGO, ego, 0.0, "hero"), _vehicle(CAR, car, 10.0))
    assert cut_in.sync_step(snap) == (False, 0.0)


@pytest.mark.parametrize(
    ("car_before", "ego_before", "cut"),
    [
        (4.0, 3.0, True),  # within end_dist = 5 m, the ego's exit still ahead of it: SUCCESS, cut in
        (6.0, 3.0, False),  # 6 m from the target: still syncing (ours ended at 0.5 m)
        (4.0, -2.0, False),  # the ego passed its exit: (reference - ego) . forward < 0, no SUCCESS
    ],
)
def test_highway_cut_in_sync_ends_within_5_m_while_the_ego_is_before_its_exit(cut_in, car_before, ego_before, cut):
    # highway_cut_in.py: SyncArrivalWithAgent(car, ego, target_wp.transform, reference_wp.transform, 5); its update
    # returns SUCCESS when distance < end_dist and (reference_target - ego) . reference_forward > 0.
    car, ego = _on_walk(cut_in, car_before), _on_route(cut_in, ego_before)
    snap = _snapshot(_vehicle(EGO, ego, 20.0, "hero"), _vehicle(CAR, car, 18.0))
    assert cut_in.sync_step(snap)[0] is cut


class _RecordingSim:
    """Records the velocities a controller forces."""

    def __init__(self) -> None:
        self.velocity = None

    def apply_control(self, actor_id, control) -> None:
        pass

    def set_target_velocity(self, actor_id, velocity) -> None:
        self.velocity = velocity


@pytest.mark.parametrize(("gap", "brakes"), [(15.0, True), (25.0, False)])
def test_highway_cut_in_agent_brakes_for_a_vehicle_in_its_path(cut_in, gap, brakes):
    # CutIn drives a BasicAgent at 3.6 x ego speed x 80 / 100 km/h; BasicAgent.run_step looks for vehicles in its
    # path within _base_vehicle_threshold (5 m) + _speed_ratio (1) x its speed [m/s] and emergency-brakes
    # (_max_brake 0.5). Ego at 20 m/s: the car cuts in at 16 m/s and sees 5 + 16 = 21 m: a car standing 15 m ahead
    # on its path makes it brake (0.5 x 8 m/s^2 x 0.05 s: 16 -> 15.8 m/s at most), one 25 m ahead does not.
    # (Ours looked for no vehicle and kept 16 m/s.)
    sim = _RecordingSim()
    scenario = copy.copy(cut_in)
    scenario.ctx = replace(cut_in.ctx, sim=sim)
    car = _on_walk(scenario, 4.0)
    car_state = _vehicle(CAR, car, 16.0)
    scenario._begin_cut_in(_snapshot(car_state), 20.0)
    assert scenario.cut_in_speed == pytest.approx(16.0)
    # a standing car whose rear is `gap` m ahead of the cut-in car's front (half lengths 2.45 m), on its path
    path = scenario.agent.path
    k = int(np.argmin(np.abs(path.s - (gap + 2 * 2.45))))
    blocker = Transform(Location(float(path.points[k][0]), float(path.points[k][1]), car.location.z), car.rotation)
    scenario.agent.run_step(_snapshot(car_state, _vehicle(9, blocker, 0.0, "background")))
    speed = math.hypot(sim.velocity.x, sim.velocity.y)
    assert (speed < 16.0 - 0.1) is brakes
    assert speed >= 16.0 - 0.5 * 8.0 * 0.05 - 1e-6
