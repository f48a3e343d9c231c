"""Issue 23 item 10 and its neighbours: the obstacle scenarios' lane walks, opposite flow, warning sign and
construction site as scenario_runner's ``leaderboard-2.0`` branch (Bench2Drive ``da12001``) has them.

Each test names the reference file and works out the expected value by hand from it. The scenarios are built on the
generated town without a simulator (their constructors need only the map and the route).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from b2d_data.format.transform import BoundingBox, Location, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.maps import LaneType, load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.road_geometry import (
    first_junction_ahead,
    lane_walk,
    offset_transform,
    opposite_driving_neighbour,
)
from b2d_data.scenarios.framework import ScenarioContext, scenario_class
from b2d_data.scenarios.placement import make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import ActorKind, ActorState, Snapshot, VehicleControl

EGO = 1


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def build(town, scenario_type: str, index: int = 0, **params: str):
    """Generated route ``index`` (seed 0) of ``scenario_type`` and its scenario, XML ``params`` (tag → value)
    overridden."""
    route = make_routes(town, scenario_type, index + 1, seed=0)[index]
    config = route.scenarios[0]
    other = dict(config.other_parameters)
    other.update({tag: {"value": value} for tag, value in params.items()})
    config = replace(config, other_parameters=other)
    route = replace(route, scenarios=(config,))
    dense = DenseRoute.from_route(town, route)
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
    return dense, scenario_class(scenario_type)(ctx)


def ego_at(transform: Transform) -> Snapshot:
    """A snapshot with only the ego, standing still at ``transform``."""
    ego = ActorState(
        id=EGO, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE, transform=transform,
        velocity=Vector3D(), angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.45, 1.06, 0.75)), semantic_tags=(14,),
        role_name="hero",
    )  # fmt: skip
    return Snapshot(frame=1, timestamp=0.0, actors={EGO: ego}, traffic_lights={}, traffic_signs={},
                    collisions=(), weather=ROUTE_DEFAULT)  # fmt: skip


def along(dense: DenseRoute, a: Location, b: Location) -> float:
    """Route distance from ``a`` to ``b`` (both projected onto the dense route)."""
    s = dense.cumulative_length
    return float(s[dense.closest_index(b)] - s[dense.closest_index(a)])


# ------------------------------------------------------------------------------------------------ item 10: lane walks


@pytest.mark.parametrize("scenario_type", ("ParkedObstacle", "ParkedObstacleTwoWays", "Accident", "AccidentTwoWays"))
def test_an_obstacle_beyond_a_junction_stops_before_it(town, scenario_type):
    # route_obstacles.py _initialize_actors: the obstacle's point is _move_waypoint_forward(starting_wp, distance),
    # which takes 1 m steps of next(1)[0] and stops at the last point whose next step lies in a junction. With
    # distance 5000 m the first junction ahead is reached first: if its first point is J m on (1 m steps), the
    # obstacle stands J - 1 m after the trigger point (we refused the place, or walked on through the junction).
    _, scenario = build(town, scenario_type, distance="5000")
    junction = first_junction_ahead(scenario.trigger_waypoint, 5000.0)
    assert junction is not None
    _, metres = junction
    obstacle = scenario.obstacle_waypoint
    assert not obstacle.is_junction
    expected = lane_walk(scenario.trigger_waypoint, metres - 1.0)
    assert len(expected) == metres  # J - 1 steps of 1 m, none of them a dead end
    assert obstacle.transform.location.distance_2d(expected[-1].transform.location) < 1e-6


@pytest.mark.parametrize("scenario_type", ("HazardAtSideLane", "HazardAtSideLaneTwoWays"))
def test_the_bicycles_ride_ends_before_a_junction(town, scenario_type):
    # A deviation of ours (hazard_side_lane.py): the ride (LB2.0: bicycle_drive_distance, then the hand brake)
    # ends junction_margin (3 m) before the junction the front bicycle's lane enters. If that junction's first
    # point is J m on (1 m steps), its lane ends after J - 1 m, so both bicycles ride J - 1 - 3 m.
    _, scenario = build(town, scenario_type, bicycle_drive_distance="5000")
    found = first_junction_ahead(scenario._waypoints[-1], 5000.0)
    assert found is not None
    _, metres = found
    assert metres > 60.0  # the layout keeps 130 m after the trigger junction-free: the bicycles start on it
    assert scenario.ride() == pytest.approx(metres - 1.0 - 3.0)
    # a ride that ends before the junction is the drawn one
    _, short = build(town, scenario_type, bicycle_drive_distance="20")
    assert short.ride() == 20.0


def test_the_accident_cars_and_the_end_stop_before_a_junction(town):
    # route_obstacles.py Accident: both crashed cars (police + 10, + 6) and the end (2nd car + 50) are
    # _move_waypoint_forward walks. The police car stands 1 m before the junction (previous test), so no step is
    # taken: the three points coincide with the police car's.
    _, scenario = build(town, "Accident", distance="5000")
    police = scenario.obstacle_waypoint.transform.location
    for wp in scenario._car_waypoints:
        assert wp.transform.location.distance_2d(police) < 1e-6
    assert scenario.end_reference.transform.location.distance_2d(police) < 1e-6


def test_the_opposite_flow_stops_before_the_junction_ahead(town):
    # atomic_behaviors.py OppositeActorFlow.initialise: source = _move_waypoint_backwards(reference_wp, d), sink =
    # _move_waypoint_forward(reference_wp, d) with d = 1.5 x limit + 30. reference_wp is the opposite lane beside
    # the obstacle, which here stands 1 m before a junction; walking that lane backwards (towards the junction)
    # stops at once, so the flow's source is the opposite-lane point beside the obstacle (we walked d m on, through
    # the junction).
    _, scenario = build(town, "ParkedObstacleTwoWays", distance="5000")
    opposite = opposite_driving_neighbour(scenario.obstacle_waypoint)
    flow = scenario._make_flow()
    assert flow is not None
    assert flow.waypoints[0].transform.location.distance_2d(opposite.transform.location) < 1.0


def test_the_opposite_flow_takes_the_ego_speed_limit(town):
    # atomic_behaviors.py OppositeActorFlow.initialise: speed = reference_actor.get_speed_limit() with the ego as
    # reference actor, flow distance = 1.5 x speed + 30. With the ego's route point at a 30 km/h limit: cars at
    # 30 / 3.6 = 8.33 m/s and source and sink 1.5 x 30 + 30 = 75 m either side of the anchor, 150 m apart (the
    # stretch is junction-free; we took the map's limit at the obstacle).
    dense, scenario = build(town, "ParkedObstacleTwoWays")
    dense.speed_limits[:] = 30.0
    assert scenario.ctx.map.speed_limit(scenario.obstacle_waypoint) != 30.0
    snapshot = ego_at(scenario.trigger_waypoint.transform)
    scenario._reference_limit = scenario.ego_speed_limit(snapshot)
    flow = scenario._make_flow()
    assert flow is not None
    assert flow.speed == pytest.approx(30.0 / 3.6)
    assert len(flow.waypoints) - 1 == pytest.approx(150, abs=2)


def test_the_accident_two_ways_flow_is_anchored_beside_the_second_car(town):
    # route_obstacles.py AccidentTwoWays._create_behavior: reference_wp = self._accident_wp.get_left_lane(), and
    # _initialize_actors sets self._accident_wp = second_vehicle_wp, 10 + 6 = 16 m past the police car. The flow's
    # sink is reach m from it towards the ego, reach = 1.5 x 30 + 30 = 75 m at a 30 km/h limit, so it lies
    # 75 - 16 = 59 m before the police car along the ego's route (we anchored beside the police car: 75 m).
    dense, scenario = build(town, "AccidentTwoWays")
    scenario._reference_limit = 30.0
    reach = 1.5 * 30.0 + 30.0
    flow = scenario._make_flow()
    assert flow is not None
    police = scenario.obstacle_waypoint.transform.location
    assert along(dense, flow.waypoints[-1].transform.location, police) == pytest.approx(reach - 16.0, abs=1.5)


# ------------------------------------------------------------------------------------------------ row 9: the sign


def test_the_warning_sign_stands_on_the_first_lane_that_is_neither_driving_nor_parking(town):
    # route_obstacles.py _spawn_side_prop: walk to the `direction` side while the lane is Driving or Parking;
    # prop_wp is the last such lane, wp the next one. The sign stands at wp's pose + 0.3 x prop_wp.lane_width along
    # prop_wp's right vector (negated for left), z + 0.2, yaw + 90. This route draws direction=left on a one-way
    # road: the lane left of the ego's is a 0.785 m median, so the sign stands on it, 0.3 x 3.74 = 1.12 m further
    # left.
    _, scenario = build(town, "ParkedObstacle")
    side = scenario.direction
    step = (lambda wp: wp.get_right_lane()) if side == "right" else (lambda wp: wp.get_left_lane())
    prop_wp = scenario.trigger_waypoint
    while step(prop_wp).lane_type & (LaneType.DRIVING | LaneType.PARKING):
        prop_wp = step(prop_wp)
    beyond = step(prop_wp)
    yaw = math.radians(prop_wp.transform.rotation.yaw)
    d = (0.3 if side == "right" else -0.3) * prop_wp.lane_width
    expected = Location(beyond.transform.location.x - math.sin(yaw) * d, beyond.transform.location.y + math.cos(yaw) * d)
    sign = scenario.warning_sign_transform()
    assert sign is not None
    assert sign.location.distance_2d(expected) < 1e-6
    assert sign.location.z == pytest.approx(beyond.transform.location.z + 0.2)
    assert sign.rotation.yaw == pytest.approx(beyond.transform.rotation.yaw + 90.0)
    # (we stood 0.6 m beyond the outer edge of the outermost driving lane, at the trigger point's yaw + 180)


def test_a_left_warning_sign_on_a_two_way_road_has_no_lane(town):
    # route_obstacles.py _spawn_side_prop with direction=left: get_left_lane of lane -1 is lane 1 and of lane 1 is
    # lane -1 (CARLA's Map::GetLeft swaps the sign of |id| = 1), both Driving, so LB2.0's walk never ends. We place
    # no sign there (we used to put it beyond the ego's own lane).
    _, scenario = build(town, "ParkedObstacleTwoWays", direction="left")
    assert scenario.trigger_waypoint.lane_id in (-1, 1)
    assert scenario.warning_sign_transform() is None


# ------------------------------------------------------------------------------------------------ row 39: construction


@pytest.mark.parametrize("scenario_type", ("ConstructionObstacle", "ConstructionObstacleTwoWays"))
def test_construction_site_props_as_lb20(town, scenario_type):
    # construction_crash_vehicle.py _create_construction_setup, from the site pose T = next(distance)[0]:
    # board: yaw + 180, 5 m along that heading (= 5 m back), then yaw + 90: 5 m behind the site, yaw T + 270;
    # debris: 2 m ahead, z + 1, yaw T + 90; first cone: 0.85 x lane_width / 2 to the left (direction right; to
    # the right for left) and 2 m ahead, z + 0.1.
    _, scenario = build(town, scenario_type)
    t = scenario.obstacle_waypoint.transform
    r = math.radians(t.rotation.yaw)
    fwd = (math.cos(r), math.sin(r))
    right = (-math.sin(r), math.cos(r))
    board = scenario.board_transform()
    assert board.location.distance_2d(Location(t.location.x - 5 * fwd[0], t.location.y - 5 * fwd[1])) < 1e-6
    assert (board.rotation.yaw - t.rotation.yaw) % 360.0 == pytest.approx(270.0)
    debris = scenario.debris_transform()
    assert debris.location.distance_2d(Location(t.location.x + 2 * fwd[0], t.location.y + 2 * fwd[1])) < 1e-6
    assert debris.location.z == pytest.approx(t.location.z + 1.0)
    assert (debris.rotation.yaw - t.rotation.yaw) % 360.0 == pytest.approx(90.0)
    k = scenario.sign * 0.85 * scenario.trigger_waypoint.lane_width / 2.0
    cone = scenario.cone_transforms()[0]
    expected = Location(t.location.x - k * right[0] + 2 * fwd[0], t.location.y - k * right[1] + 2 * fwd[1])
    assert cone.location.distance_2d(expected) < 1e-6


def test_construction_reaction_watches_the_site_and_ends_50_m_past_it(town):
    # construction_crash_vehicle.py _create_behavior: InTriggerDistanceToLocation(ego, construction_wp, 30) and
    # WaitUntilInFrontPosition(ego, _move_waypoint_forward(construction_wp, 50)): the watched point is the site
    # point (we watched the board, 5 m before it) and the end is 50 m past it (we: 8 m of cones + 50 m).
    dense, scenario = build(town, "ConstructionObstacle")
    assert scenario.approach_actor_id() is None
    site = scenario.obstacle_waypoint.transform.location
    ego = ego_at(scenario.trigger_waypoint.transform)
    scenario.update(ego)
    assert along(dense, site, scenario._end_transform.location) == pytest.approx(50.0, abs=0.6)


# ------------------------------------------------------------------------------------------------ row 40: ControlLoss


class _SpawnRecorder:
    """The one simulator call ``Scenario.spawn`` makes, recording what was spawned."""

    def __init__(self) -> None:
        self.spawned: list[str] = []

    def try_spawn_actor(self, spec, transform) -> int:
        self.spawned.append(spec.type_id)
        return 100 + len(self.spawned)


def test_control_loss_patches_act_in_sequence_with_one_debris_model(town):
    # control_loss.py _create_behavior: one Sequence of [InTriggerDistanceToLocation(patch k, 2) -> Parallel(
    # AddNoiseToRouteEgo, InTriggerDistanceToLocation(patch k, 2, operator.gt))] for k = 1, 2, 3. So the noise of
    # patch 2 cannot start before patch 1 was entered and left, and a patch's noise stops as soon as the ego is more
    # than 2 m from it (Euclidean), not 2 m past it. _initialize_actors spawns 'static.prop.dirtdebris01' three
    # times.
    _, scenario = build(town, "ControlLoss")
    recorder = _SpawnRecorder()
    scenario.ctx = replace(scenario.ctx, sim=recorder)
    scenario.build()
    assert recorder.spawned == ["static.prop.dirtdebris01"] * 3
    first, second = (p.transform for p in scenario.patches[:2])
    # standing on patch 2 first: the sequence still waits for patch 1 (we switched patch 2's noise on)
    scenario.update(ego_at(second))
    assert not scenario.noisy
    # on patch 1: noise; then 2.5 m to its side, level with it (0 m past): more than 2 m away, so noise off
    scenario.update(ego_at(first))
    assert scenario.noisy
    scenario.update(ego_at(offset_transform(first, lateral=2.5)))
    assert not scenario.noisy
    # now patch 2 is watched
    scenario.update(ego_at(second))
    assert scenario.noisy


# ------------------------------------------------------------------------------------------------ row 31: red light


def test_red_light_runner_conflict_point_is_where_the_entry_lines_cross(town):
    # opposite_vehicle_taking_priority.py _initialize_actors: _collision_location = get_geometric_linear_intersection(
    # starting_wp, source_entry_wps[0], True) (scenario_helper.py): the crossing of the line along the ego's lane
    # where it enters the junction with the line along the adversary's entry lane. On this route (direction right)
    # the ego enters heading -90 (a line x = x_entry) and the adversary's lane runs at yaw 0/180 (a line
    # y = y_adversary), so the point is (x_entry, y_adversary) (we took where the ego's route meets the adversary's
    # path, 0.5 m off).
    _, scenario = build(town, "OppositeVehicleRunningRedLight", index=2)
    assert scenario.direction == "right"
    assert scenario.ego_entry.transform.rotation.yaw % 360.0 == pytest.approx(270.0)
    assert scenario.spawn_waypoint.transform.rotation.yaw % 180.0 == pytest.approx(0.0, abs=1e-6)
    assert scenario.conflict.x == pytest.approx(scenario.ego_entry.transform.location.x, abs=0.05)
    assert scenario.conflict.y == pytest.approx(scenario.spawn_waypoint.transform.location.y, abs=0.05)


# ------------------------------------------------------------------------------------------------ row 32: collision


class _ControlRecorder:
    """The simulator calls a ConstantVelocityAgent makes, recorded."""

    def __init__(self) -> None:
        self.controls: list = []
        self.velocities: list = []

    def apply_control(self, actor_id, control) -> None:
        self.controls.append(control)

    def set_target_velocity(self, actor_id, velocity) -> None:
        self.velocities.append(velocity)


def test_the_red_light_runner_drops_its_forced_velocity_at_its_first_collision(town):
    # CARLA PythonAPI agents/navigation/constant_velocity_agent.py (ConstantVelocityAgentBehavior's agent): its
    # collision sensor calls stop_constant_velocity() (disable_constant_velocity, restart_time inf), and run_step
    # then returns an empty carla.VehicleControl() for good: no throttle, no brake, the velocity no longer forced.
    from b2d_data.scenarios.controllers import ConstantVelocityAgent, PathTrack
    from b2d_data.sim.api import CollisionEvent

    _, scenario = build(town, "OppositeVehicleRunningRedLight", index=2)
    recorder = _ControlRecorder()
    scenario.ctx = replace(scenario.ctx, sim=recorder)
    scenario.adversary = 7
    snapshot = ego_at(scenario.trigger_waypoint.transform)
    adversary = replace(snapshot.actors[EGO], id=7, role_name="scenario", transform=scenario.path[0].transform)
    conflict = Transform(scenario.conflict, scenario.trigger_waypoint.transform.rotation)
    ego_near = replace(snapshot.actors[EGO], transform=conflict)  # within 12 m: the adversary starts
    first = replace(snapshot, actors={EGO: ego_near, 7: adversary})
    scenario.update(first)
    assert isinstance(scenario._agent, ConstantVelocityAgent) and isinstance(scenario._agent.path, PathTrack)
    assert len(recorder.velocities) == 1  # driven at its forced velocity
    hit = CollisionEvent(2, 7, EGO, "vehicle.lincoln.mkz_2020", adversary.location)
    scenario.update(replace(first, frame=2, collisions=(hit,)))
    scenario.update(replace(first, frame=3))
    assert len(recorder.velocities) == 1  # never forced again
    assert recorder.controls[-2:] == [VehicleControl(), VehicleControl()]


# ------------------------------------------------------------------------------------------------ row 37: turning route


class _BackgroundRecorder:
    """Background hooks called by a scenario, recorded by name."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple]] = []

    def __getattr__(self, name: str):
        return lambda *args, **kwargs: self.calls.append((name, args))


class _TurningSim(_SpawnRecorder, _ControlRecorder):
    def __init__(self) -> None:
        _SpawnRecorder.__init__(self)
        _ControlRecorder.__init__(self)
        self.background = _BackgroundRecorder()


@pytest.mark.parametrize("scenario_type", ("VehicleTurningRoute", "VehicleTurningRoutePedestrian"))
def test_turning_route_leaves_crossing_space_at_the_tta_trigger_only(town, scenario_type):
    # object_crash_intersection.py _create_behavior (both classes): no background request at the trigger; after the
    # TTA / 6 m trigger the sequence runs LeaveCrossingSpace(self._collision_wp) in route mode, then moves the
    # crosser (we cleared the junction and removed the exit at the trigger). VehicleTurningRoute's crosser is
    # 'vehicle.diamondback.century' (we drew any bicycle).
    dense, scenario = build(town, scenario_type)
    sim = _TurningSim()
    scenario.ctx = replace(scenario.ctx, sim=sim)
    if scenario_type == "VehicleTurningRoute":
        scenario.build()
        assert sim.spawned == ["vehicle.diamondback.century"]
    far = ego_at(scenario.trigger_waypoint.transform)
    scenario.start(far)
    assert sim.background.calls == []
    scenario.update(far)
    assert sim.background.calls == []
    at_crossing = ego_at(scenario.collision_waypoint.transform)  # within 6 m: the crosser starts
    scenario.update(at_crossing)
    assert sim.background.calls == [("leave_crossing_space", (scenario.collision_waypoint,))]


# ------------------------------------------------------------------------------------------------ row 21: EV in front


class _IdleAgent:
    """Stands in for the emergency vehicle's agent: takes its speed, drives nothing."""

    speed = 0.0

    def run_step(self, snapshot) -> None:
        return None


@pytest.mark.parametrize(("ahead", "passed"), ((1.0, False), (7.9, True), (16.9, False)))
def test_the_emergency_vehicle_counts_as_in_front_as_wait_until_in_front(town, ahead, passed):
    # yield_to_emergency_vehicle.py end condition 2: WaitUntilInFront(ev, ego) with factor 1 and check_distance
    # (atomic_trigger_conditions.py): the reference is the ego's lane point ev.extent.x + ego.extent.x ahead of it,
    # here 2.45 + 2.45 = 4.9 m; the EV must be past it (dot > 0) and within 10 m of it. EV centres 1 m ahead of the
    # ego: 3.9 m short of it, not in front (we: in front of the ego's centre); 7.9 m: 3 m past it, in front;
    # 16.9 m: past it but 12 m away, not yet (we: in front).
    _, scenario = build(town, "YieldToEmergencyVehicle")
    scenario.ev = 7
    scenario._agent = _IdleAgent()
    ego = ego_at(scenario.trigger_waypoint.transform).actors[EGO]
    ev = replace(ego, id=7, role_name="scenario",
                 transform=offset_transform(scenario.trigger_waypoint, forward=ahead))  # fmt: skip
    snapshot = replace(ego_at(ego.transform), actors={EGO: ego, 7: ev})
    scenario.update(snapshot)
    assert scenario._passed is passed


# ------------------------------------------------------------------------------------------------ rows 41, 10: the flow lane


def _lane(lane_id: int, kind: str, width: float) -> str:
    return (f'<lane id="{lane_id}" type="{kind}" level="false"><width sOffset="0" a="{width}" b="0" c="0" d="0"/>'
            '<roadMark sOffset="0" type="solid" color="white" width="0.15" laneChange="none"/></lane>')  # fmt: skip


def _straight_road(name: str, left: str, right: str) -> str:
    """One straight 400 m road heading east (40 km/h) with the given OpenDRIVE left and right lanes."""
    return (
        f'<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="4" name="{name}"/>'
        '<road name="Road 1" length="400" id="1" junction="-1"><link/>'
        '<type s="0" type="town"><speed max="40" unit="km/h"/></type>'
        '<planView><geometry s="0" x="0" y="0" hdg="0" length="400"><line/></geometry></planView>'
        '<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>'
        '<lanes><laneOffset s="0" a="0" b="0" c="0" d="0"/><laneSection s="0">'
        f'{"<left>" + left + "</left>" if left else ""}'
        '<center><lane id="0" type="none" level="false"/></center>'
        f'<right>{right}</right>'
        "</laneSection></lanes></road></OpenDRIVE>"
    )


def _left_parking_road() -> str:
    """Lane 1 driving (westbound), -1 parking 2.5 m, -2 driving, -3 sidewalk."""
    return _straight_road("LeftParking", _lane(1, "driving", 3.5),
                          _lane(-1, "parking", 2.5) + _lane(-2, "driving", 3.5) + _lane(-3, "sidewalk", 2.0))


def _one_way_road() -> str:
    """One-way, eastbound: lanes -1 and -2 driving, -3 parking 2.5 m, -4 sidewalk; nothing left of lane -1."""
    return _straight_road("OneWay", "", _lane(-1, "driving", 3.5) + _lane(-2, "driving", 3.5)
                          + _lane(-3, "parking", 2.5) + _lane(-4, "sidewalk", 2.0))


def _on_road(tmp_path, xodr: str, scenario_type: str, y: float, **params: str):
    """``scenario_type`` triggered at x = 150 on the eastbound lane at CARLA ``y``, on a route along that lane."""
    from b2d_data.format.road_option import RoadOption
    from b2d_data.format.transform import Rotation
    from b2d_data.scenarios.route_xml import ScenarioConfig

    path = tmp_path / "Road.xodr"
    path.write_text(xodr)
    town = load_opendrive(path)
    lane = lane_walk(town.get_waypoint(Location(5.0, y, 0.0)), 390.0)
    dense = DenseRoute.from_pairs([(wp, RoadOption.LANEFOLLOW) for wp in lane], town)
    config = ScenarioConfig(f"{scenario_type}_1", scenario_type, Transform(Location(150.0, y, 0.0), Rotation(yaw=0.0)),
                            {tag: {"value": value} for tag, value in params.items()})  # fmt: skip
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
    return scenario_class(scenario_type)(ctx)


def test_vehicle_opens_door_left_anchors_the_flow_two_lanes_left(tmp_path):
    # vehicle_opens_door.py with direction=left: front_wp = starting_wp.next(50)[0], parked_wp =
    # front_wp.get_left_lane() (the parking lane -1), and the flow's reference_wp = parked_wp.get_left_lane(), which
    # for lane -1 is lane 1 (CARLA's GetLeft flips |id| = 1): the westbound driving lane. OppositeActorFlow walks
    # that lane its own way: with the 40 km/h limit, 1.5 x 40 + 30 = 90 m, so from x = 200 + 90 = 290 (source,
    # previous) to 200 - 90 = 110 (sink, next). (We refused: no opposite driving lane left of the ego's lane.)
    y = 2.5 + 3.5 / 2.0  # lane -2's centre, CARLA y (OpenDRIVE's right is CARLA's +y)
    scenario = _on_road(tmp_path, _left_parking_road(), "VehicleOpensDoorTwoWays", y, direction="left",
                        distance="50")  # fmt: skip
    assert scenario.side_waypoint.lane_id == -1
    scenario._reference_limit = 40.0
    flow = scenario._make_flow()
    assert flow is not None
    assert {wp.lane_id for wp in flow.waypoints} == {1}
    assert flow.waypoints[0].transform.location.x == pytest.approx(290.0, abs=1.0)
    assert flow.waypoints[-1].transform.location.x == pytest.approx(110.0, abs=1.0)


@pytest.mark.parametrize(("scenario_type", "anchor_x"), (
    ("ParkedObstacleTwoWays", 200.0), ("AccidentTwoWays", 216.0), ("ConstructionObstacleTwoWays", 200.0),
    ("VehicleOpensDoorTwoWays", 200.0),
))  # fmt: skip
def test_two_way_types_on_a_one_way_road_run_their_flow_on_the_left_lane(tmp_path, scenario_type, anchor_x):
    # route_obstacles.py AccidentTwoWays / ParkedObstacleTwoWays / ConstructionObstacleTwoWays._create_behavior:
    # reference_wp = <obstacle wp>.get_left_lane(), ValueError only when it is None; vehicle_opens_door.py the same
    # with parked_wp (for direction=right the lane right of the ego's, so reference_wp is the ego's lane). CARLA's
    # Map::GetLeft returns any lane present, whatever its type or direction. OppositeActorFlow then walks
    # reference_wp its own way (_move_waypoint_backwards / _forward, 1.5 x 40 + 30 = 90 m here): on this one-way
    # road the "opposite" flow drives east like the ego, from anchor - 90 to anchor + 90. The obstacle (the door
    # car) stands 50 m after the trigger at x = 150; AccidentTwoWays anchors beside its 2nd car, 10 + 6 m further.
    # Bench2Drive v0.0.4 validation routes 25783, 25727 (AccidentTwoWays) and 25986 (ParkedObstacleTwoWays) on
    # Town04 are such places; we refused them ("no opposite driving lane left of road 39 lane 4").
    y = 3.5 + 3.5 / 2.0  # lane -2's centre
    scenario = _on_road(tmp_path, _one_way_road(), scenario_type, y, distance="50")
    scenario._reference_limit = 40.0
    flow = scenario._make_flow()
    assert flow is not None
    lane = -2 if scenario_type == "VehicleOpensDoorTwoWays" else -1
    assert {wp.lane_id for wp in flow.waypoints} == {lane}
    assert flow.waypoints[0].transform.location.x == pytest.approx(anchor_x - 90.0, abs=1.0)
    assert flow.waypoints[-1].transform.location.x == pytest.approx(anchor_x + 90.0, abs=1.0)


def test_two_way_types_refuse_only_where_no_lane_lies_left(tmp_path):
    # route_obstacles.py: `if not reference_wp: raise ValueError("Couldnt find a left lane ...")`: on the one-way
    # road's lane -1 nothing lies to the left (no lane 1), the one place LB2.0 refuses.
    from b2d_data.scenarios.framework import ScenarioSetupError

    with pytest.raises(ScenarioSetupError, match="no lane left of road 1 lane -1"):
        _on_road(tmp_path, _one_way_road(), "ParkedObstacleTwoWays", 3.5 / 2.0, distance="50")


def _narrow_shoulder_road() -> str:
    """Lane 1 driving (westbound), -1 driving, -2 shoulder only 1 m wide, -3 sidewalk."""
    return _straight_road("NarrowShoulder", _lane(1, "driving", 3.5),
                          _lane(-1, "driving", 3.5) + _lane(-2, "shoulder", 1.0) + _lane(-3, "sidewalk", 2.0))


@pytest.mark.parametrize(("xodr", "y", "side_lane", "side_type"), (
    pytest.param(_narrow_shoulder_road, 3.5 / 2.0, -2, LaneType.SHOULDER, id="1m-shoulder"),
    pytest.param(_one_way_road, 3.5 / 2.0, -2, LaneType.DRIVING, id="driving-lane"),
))  # fmt: skip
def test_vehicle_opens_door_parks_in_whatever_lane_lies_to_its_side(tmp_path, xodr, y, side_lane, side_type):
    # vehicle_opens_door.py VehicleOpensDoorTwoWays._initialize_actors: parked_wp = front_wp.get_right_lane() (for
    # direction=right), of any lane type and width; it raises only where that is None (or the car cannot spawn),
    # and _create_behavior only where parked_wp.get_left_lane() is None. So a 1 m shoulder, or the driving lane
    # right of the ego's on a one-way road, holds the car. (We refused both: "no parking lane or shoulder at least
    # 2 m wide".)
    scenario = _on_road(tmp_path, xodr(), "VehicleOpensDoorTwoWays", y, distance="50")
    assert (scenario.side_waypoint.lane_id, scenario.side_waypoint.lane_type) == (side_lane, side_type)
    assert scenario.side_waypoint.transform.location.x == pytest.approx(200.0, abs=0.5)
    assert scenario.flow_lane().lane_id == -1


def test_vehicle_opens_door_refuses_only_where_no_lane_lies_to_its_side(tmp_path):
    # vehicle_opens_door.py: `if self._parked_wp is None: raise ValueError("Couldn't find a spot ...")`; lane -1 of
    # this road with direction=left has nothing to its left (a one-way road).
    from b2d_data.scenarios.framework import ScenarioSetupError

    with pytest.raises(ScenarioSetupError, match="no lane left of road 1 lane -1 at the car"):
        _on_road(tmp_path, _one_way_road(), "VehicleOpensDoorTwoWays", 3.5 / 2.0, distance="50", direction="left")


def test_dynamic_object_crossing_leaves_crossing_space_as_the_walker_sets_off(town):
    # object_crash_vehicle.py DynamicObjectCrossing._create_behavior: after the TTA / min-distance trigger the
    # sequence runs LeaveCrossingSpace(self._collision_wp) in route mode, then KeepVelocity moves the walker;
    # _collision_wp is the ego lane's point abreast of the blocker (ours: lane_waypoint, the TTA reference too)
    _, scenario = build(town, "DynamicObjectCrossing")
    sim = _TurningSim()
    scenario.ctx = replace(scenario.ctx, sim=sim)
    scenario.walker = 99  # as start() would have spawned it
    far = ego_at(scenario.trigger_waypoint.transform)
    scenario.update(far)
    assert sim.background.calls == []
    scenario.update(ego_at(scenario.lane_waypoint.transform))  # at the point: the TTA trigger fires
    assert sim.background.calls == [("leave_crossing_space", (scenario.lane_waypoint,))]
