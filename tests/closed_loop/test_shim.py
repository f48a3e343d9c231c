"""The stand-in carla / leaderboard / srunner / agents modules over a tiny builtin world (expected values by hand).

Town91: two straight roads along +x, road 1 from x = 0 to 100 and road 2 from 100 to 200, each with lane 1
(westbound) and lanes -1, -2 (eastbound, 3.5 m; CARLA's y of lane -1's centre is +1.75). Geo reference 49 N, 8 E.
The hero (``vehicle.lincoln.mkz_2020``) stands at x = 20 on lane -1, a Tesla at x = 60.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import math
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from b2d_data.closed_loop import SHIM_DIR, bridge, sensor_config
from b2d_data.format import transform as fmt
from b2d_data.format.road_option import RoadOption
from b2d_data.maps import Map, load_opendrive
from b2d_data.sim import api
from b2d_data.sim.builtin.world import BuiltinSimulator

_SHIM_PACKAGES = ("carla", "leaderboard", "srunner", "agents")


def _lane(lane_id: int, link: str, mark: str) -> str:
    return (
        f'<lane id="{lane_id}" type="driving" level="false"><link>{link}</link>'
        f'<width sOffset="0" a="3.5" b="0" c="0" d="0"/>{mark}</lane>'
    )


def _road(road_id: int, x0: float, road_link: str, lane_link: str) -> str:
    broken = '<roadMark sOffset="0" type="broken" color="white" width="0.15" laneChange="both"/>'
    solid = '<roadMark sOffset="0" type="solid" color="white" width="0.15" laneChange="none"/>'
    centre = '<roadMark sOffset="0" type="solid" color="yellow" width="0.15" laneChange="none"/>'
    return (
        f'<road name="r{road_id}" length="100" id="{road_id}" junction="-1"><link>{road_link}</link>'
        f'<planView><geometry s="0" x="{x0}" y="0" hdg="0" length="100"><line/></geometry></planView>'
        '<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>'
        '<lanes><laneSection s="0">'
        f"<left>{_lane(1, lane_link.format(id=1), solid)}</left>"
        f'<center><lane id="0" type="none" level="false">{centre}</lane></center>'
        f"<right>{_lane(-1, lane_link.format(id=-1), broken)}{_lane(-2, lane_link.format(id=-2), solid)}</right>"
        "</laneSection></lanes></road>"
    )


TOWN91 = (
    '<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE><header revMajor="1" revMinor="4" name="Town91" version="1">'
    "<geoReference><![CDATA[+proj=tmerc +lat_0=49.0 +lon_0=8.0 +k=1 +x_0=0 +y_0=0]]></geoReference></header>"
    + _road(1, 0, '<successor elementType="road" elementId="2" contactPoint="start"/>', '<successor id="{id}"/>')
    + _road(2, 100, '<predecessor elementType="road" elementId="1" contactPoint="end"/>', '<predecessor id="{id}"/>')
    + "</OpenDRIVE>\n"
)

HERO = api.ActorSpec("vehicle.lincoln.mkz_2020", role_name="hero")
OTHER = api.ActorSpec("vehicle.tesla.model3", role_name="other")


@dataclass
class Shim:
    """The running route and the imported stand-in modules."""

    sim: BuiltinSimulator
    route: bridge.RouteBridge
    hero_id: int
    other_id: int
    carla: ModuleType

    def tick(self, n: int = 1) -> api.Snapshot:
        """Tick the world as the evaluator does: each tick is one agent step the bridge sees."""
        for _ in range(n):
            self.route.advance(self.sim.tick())
        return self.route.snapshot


@pytest.fixture(scope="module")
def town91(tmp_path_factory: pytest.TempPathFactory) -> Map:
    path = tmp_path_factory.mktemp("town91") / "Town91.xodr"
    path.write_text(TOWN91, encoding="utf-8")
    return load_opendrive(path)


def _purge_shim_modules() -> None:
    for name in list(sys.modules):
        if name.split(".")[0] in _SHIM_PACKAGES:
            del sys.modules[name]


@contextlib.contextmanager
def _route_installed(sim: BuiltinSimulator, town: Map, hero_id: int) -> Iterator[bridge.RouteBridge]:
    """The shim folder first on sys.path and a route bridge installed; everything undone afterwards."""
    route = bridge.RouteBridge(sim=sim, map=town, ego_id=hero_id, snapshot=sim.tick())
    _purge_shim_modules()
    sys.path.insert(0, str(SHIM_DIR))
    bridge.install(route)
    try:
        yield route
    finally:
        bridge.install(None)
        sys.path.remove(str(SHIM_DIR))
        _purge_shim_modules()
        sim.close()


@pytest.fixture
def shim(town91: Map) -> Iterator[Shim]:
    sim = BuiltinSimulator(town91, seed=0)
    hero_id = sim.spawn_actor(HERO, fmt.Transform(fmt.Location(20.0, 1.75, 0.5)))
    other_id = sim.spawn_actor(OTHER, fmt.Transform(fmt.Location(60.0, 1.75, 0.5)))
    with _route_installed(sim, town91, hero_id) as route:
        carla = importlib.import_module("carla")
        assert Path(carla.__file__).parent.parent == SHIM_DIR  # the stand-in, never a real CARLA
        yield Shim(sim, route, hero_id, other_id, carla)


def _close(v, expected: tuple[float, float, float], abs: float = 1e-9) -> None:
    assert (v.x, v.y, v.z) == pytest.approx(expected, abs=abs)


# ------------------------------------------------------------------------------------------------ value types


def test_location_arithmetic(shim: Shim) -> None:
    carla = shim.carla
    a, b = carla.Location(1.0, 2.0, 3.0), carla.Location(x=4.0, y=6.0, z=3.0)
    assert a + b == carla.Location(5.0, 8.0, 6.0) and isinstance(a + b, carla.Location)
    assert b - a == carla.Location(3.0, 4.0, 0.0)
    assert a * 2 == 2 * a == carla.Location(2.0, 4.0, 6.0)
    assert b / 2 == carla.Location(2.0, 3.0, 1.5)
    assert np.float32(2.0) * a == carla.Location(2.0, 4.0, 6.0)  # numpy scalars defer to the vector
    assert (b - a).length() == 5.0 and (b - a).squared_length() == 25.0
    assert a.distance(b) == 5.0 and a.distance_2d(b) == 5.0 and a.distance_squared(b) == 25.0
    assert a.dot(b) == 4.0 + 12.0 + 9.0 and a.dot_2d(b) == 16.0
    assert carla.Vector3D(1, 0, 0).cross(carla.Vector3D(0, 1, 0)) == carla.Vector3D(0, 0, 1)
    _close(carla.Vector3D(0, 3, 4).make_unit_vector(), (0.0, 0.6, 0.8))
    assert carla.Vector3D(1, 0, 0).get_vector_angle(carla.Vector3D(0, 2, 0)) == pytest.approx(math.pi / 2)
    assert isinstance(a, carla.Vector3D) and a != b and a == carla.Location(1, 2, 3)
    c = carla.Location(a)  # copy constructor; values are mutable, copies independent
    c.x = 10.0
    assert a.x == 1.0 and c == carla.Location(10.0, 2.0, 3.0)
    a += b
    assert a == carla.Location(5.0, 8.0, 6.0)
    assert repr(carla.Location(1, 2, 3)) == "Location(x=1.000000, y=2.000000, z=3.000000)"
    assert carla.Vector2D(3, 4).length() == 5.0 and carla.Vector2D(1, 2) + carla.Vector2D(1, 1) == carla.Vector2D(2, 3)


@pytest.mark.parametrize(
    "pose",
    [(0, 0, 0, 0, 0, 0), (10.0, -5.0, 2.0, 0.0, 90.0, 0.0), (1.5, 2.5, -3.0, 12.0, -135.0, 7.0), (0, 0, 50, -90, 0, 0)],
)
def test_transform_matrices_equal_the_format_ones(shim: Shim, pose: tuple[float, ...]) -> None:
    carla = shim.carla
    x, y, z, pitch, yaw, roll = pose
    ours = fmt.Transform(fmt.Location(x, y, z), fmt.Rotation(pitch=pitch, yaw=yaw, roll=roll))
    theirs = carla.Transform(carla.Location(x, y, z), carla.Rotation(pitch, yaw, roll))
    matrix = theirs.get_matrix()
    assert isinstance(matrix, list) and len(matrix) == 4 and all(isinstance(row, list) for row in matrix)
    assert np.array(matrix).tolist() == ours.matrix().tolist()  # exactly the same entries
    assert np.allclose(np.array(theirs.get_inverse_matrix()), ours.inverse_matrix(), atol=1e-12)


def test_transform_of_a_point(shim: Shim) -> None:
    carla = shim.carla
    t = carla.Transform(carla.Location(10.0, 0.0, 0.0), carla.Rotation(yaw=90.0))
    p = carla.Location(1.0, 0.0, 0.0)
    moved = t.transform(p)  # yaw 90 turns +x into +y (CARLA's clockwise yaw seen from above), then translates
    _close(moved, (10.0, 1.0, 0.0), abs=1e-12)
    assert isinstance(moved, carla.Location) and p == carla.Location(1.0, 0.0, 0.0)  # the argument is left as it is
    _close(t.inverse_transform(moved), (1.0, 0.0, 0.0), abs=1e-12)
    _close(t.transform_vector(carla.Vector3D(2.0, 0.0, 0.0)), (0.0, 2.0, 0.0), abs=1e-12)
    points = [carla.Location(0, 0, 0), carla.Location(0, 1, 0)]
    assert t.transform(points) is None  # CARLA's list overload moves the points in place
    _close(points[1], (9.0, 0.0, 0.0), abs=1e-12)


def test_rotation_vectors(shim: Shim) -> None:
    carla = shim.carla
    r = carla.Rotation(yaw=90.0)
    _close(r.get_forward_vector(), (0.0, 1.0, 0.0), abs=1e-12)
    _close(r.get_right_vector(), (-1.0, 0.0, 0.0), abs=1e-12)
    _close(r.get_up_vector(), (0.0, 0.0, 1.0), abs=1e-12)
    _close(carla.Rotation(pitch=90.0).get_forward_vector(), (0.0, 0.0, 1.0), abs=1e-12)
    # CARLA's up column is (−cy·sp·cr − sy·sr, −sy·sp·cr + cy·sr, cp·cr): roll 90 alone gives (0, 1, 0)
    _close(carla.Transform(rotation=carla.Rotation(roll=90.0)).get_up_vector(), (0.0, 1.0, 0.0), abs=1e-12)
    assert carla.Rotation(1, 2, 3) == carla.Rotation(pitch=1, yaw=2, roll=3)


def test_bounding_box_vertices_and_contains(shim: Shim) -> None:
    carla = shim.carla
    box = carla.BoundingBox(carla.Location(1.0, 0.0, 0.5), carla.Vector3D(2.0, 1.0, 0.5))
    local = box.get_local_vertices()
    _close(local[0], (-1.0, -1.0, 0.0))
    _close(local[7], (3.0, 1.0, 1.0))
    world = box.get_world_vertices(carla.Transform(carla.Location(0, 0, 0), carla.Rotation(yaw=90)))
    _close(world[7], (-1.0, 3.0, 1.0), abs=1e-12)
    owner = carla.Transform(carla.Location(100.0, 0.0, 0.0), carla.Rotation(yaw=90.0))
    assert box.contains(carla.Location(100.0, 2.5, 0.5), owner)  # 2.5 m ahead of the owner: local x = 2.5 ≤ 3
    assert not box.contains(carla.Location(102.5, 0.0, 0.5), owner)


def test_enums_and_controls(shim: Shim) -> None:
    carla = shim.carla
    assert (carla.TrafficLightState.Red, carla.TrafficLightState.Green) == (api.TrafficLightState.RED, 2)
    assert int(carla.LaneType.Driving) == 2 and int(carla.LaneType.Any) == -2 and int(carla.LaneType.Sidewalk) == 32
    assert str(carla.LaneMarkingType.Broken) == "Broken" and carla.LaneChange.Both == 3
    assert carla.CityObjectLabel.Car == 14 and carla.VehicleLightState.Special1 == 512
    control = carla.VehicleControl(0.5, -0.2, brake=0.1)
    assert (control.throttle, control.steer, control.brake, control.gear) == (0.5, -0.2, 0.1, 0)
    assert control == carla.VehicleControl(throttle=0.5, steer=-0.2, brake=0.1)
    assert carla.libcarla.Image is carla.Image and carla.libcarla.VehicleControl is carla.VehicleControl
    from carla import libcarla

    assert issubclass(libcarla.IMUMeasurement, libcarla.SensorData)


def test_control_conversion_clamps_and_rejects_nan(shim: Shim) -> None:
    from carla._convert import to_b2d_control

    out = to_b2d_control(shim.carla.VehicleControl(throttle=np.float32(1.7), steer=-3.0, brake=-0.5, reverse=True))
    assert out == api.VehicleControl(throttle=1.0, steer=-1.0, brake=0.0, reverse=True)
    with pytest.raises(ValueError, match="steer=nan"):
        to_b2d_control(shim.carla.VehicleControl(steer=float("nan")))
    with pytest.raises(TypeError, match="throttle"):
        to_b2d_control(object())


def test_distribution_is_carla_0_9_15(shim: Shim) -> None:
    assert importlib.metadata.version("carla") == "0.9.15"
    try:
        import pkg_resources
    except ImportError:
        return
    import pkg_resources

    assert pkg_resources.WorkingSet([str(SHIM_DIR)]).find(pkg_resources.Requirement.parse("carla")).version == "0.9.15"


# ----------------------------------------------------------------------------------------------- world views


def test_actor_list_and_hero(shim: Shim) -> None:
    world = shim.carla.Client("localhost", 2000).get_world()
    actors = world.get_actors()
    vehicles = actors.filter("vehicle.*")
    assert sorted(a.id for a in vehicles) == sorted([shim.hero_id, shim.other_id])
    assert [a.type_id for a in actors.filter("*lincoln*")] == ["vehicle.lincoln.mkz_2020"]
    assert len(actors.filter("*traffic_light*")) == 0
    hero = actors.find(shim.hero_id)
    assert isinstance(hero, shim.carla.Vehicle) and hero.attributes["role_name"] == "hero"
    assert hero == world.get_actor(shim.hero_id) and hero in vehicles
    assert world.get_actors([shim.other_id])[0].attributes["role_name"] == "other"
    assert hero.bounding_box.extent.x == pytest.approx(2.44619083404541, abs=0.05)


def test_agent_finds_the_hero(shim: Shim) -> None:
    from leaderboard.autoagents import autonomous_agent

    class MyAgent(autonomous_agent.AutonomousAgent):
        def setup(self, path_to_conf_file: str) -> None:
            self.track = autonomous_agent.Track.SENSORS

    agent = MyAgent("localhost", 2000)
    assert agent.hero_actor is not None and agent.hero_actor.id == shim.hero_id
    assert agent.track is sensor_config.Track.SENSORS and agent._global_plan is None
    assert agent.sensors() == [] and MyAgent.get_ros_version() == -1
    info = agent.get_metric_info()
    assert info["location"] == pytest.approx([20.0, 1.75, 0.0], abs=1e-6)
    assert info["rotation"] == [0.0, 0.0, 0.0] and info["forward_vector"] == pytest.approx([1.0, 0.0, 0.0])
    assert info["right_vector"] == pytest.approx([0.0, 1.0, 0.0]) and len(info["acceleration"]) == 3


def test_actor_views_read_live(shim: Shim) -> None:
    from srunner.scenariomanager.carla_data_provider import CarlaDataProvider
    from srunner.scenariomanager.timer import GameTime

    hero = CarlaDataProvider.get_hero_actor()
    assert hero.id == shim.hero_id and hero.get_velocity().length() == 0.0
    assert CarlaDataProvider.get_velocity(hero) == 0.0 and GameTime.get_time() == 0.0
    frame = GameTime.get_frame()
    shim.sim.apply_control(shim.hero_id, api.VehicleControl(throttle=1.0))
    shim.tick(10)
    v = hero.get_velocity()  # the same handle: its state is read from the new snapshot
    assert v.x > 1.0 and hero.get_location().x > 20.0 and hero.get_acceleration().x > 0.0
    assert CarlaDataProvider.get_velocity(hero) == pytest.approx(math.hypot(v.x, v.y))
    assert hero.get_control().throttle == 1.0
    assert GameTime.get_frame() == frame + 10 and GameTime.get_time() == pytest.approx(0.5)
    other = CarlaDataProvider.get_actor_by_id(shim.other_id)
    assert other.get_velocity().length() == 0.0 and CarlaDataProvider.get_location(other).x == pytest.approx(60.0)
    assert sorted(i for i, _ in CarlaDataProvider.get_actors()) == sorted([shim.hero_id, shim.other_id])
    snapshot = shim.carla.Client().get_world().get_snapshot()
    assert snapshot.frame == frame + 10 and snapshot.find(shim.hero_id).get_velocity().x == pytest.approx(v.x)


def test_mutations_are_refused(shim: Shim) -> None:
    carla = shim.carla
    world = carla.Client().get_world()
    hero = world.get_actor(shim.hero_id)
    with pytest.raises(RuntimeError, match="returning a carla.VehicleControl from run_step"):
        hero.apply_control(carla.VehicleControl(throttle=1.0))
    with pytest.raises(RuntimeError, match="Actor.destroy"):
        hero.destroy()
    with pytest.raises(RuntimeError, match="evaluator owns the clock"):
        world.tick()
    with pytest.raises(RuntimeError, match="evaluator owns"):
        carla.Client().load_world("Town01")
    with pytest.raises(AttributeError, match="World .*no attribute 'get_lightmanager'"):
        world.get_lightmanager()
    world.debug.draw_point(carla.Location(), size=0.1)  # drawing is harmless
    world.get_spectator().set_transform(carla.Transform())
    settings = world.get_settings()
    assert settings.synchronous_mode and settings.fixed_delta_seconds == 0.05
    assert world.get_weather().sun_altitude_angle == pytest.approx(70.0)


def test_map_and_waypoints(shim: Shim) -> None:
    carla = shim.carla
    from srunner.scenariomanager.carla_data_provider import CarlaDataProvider

    wmap = CarlaDataProvider.get_map()
    assert wmap.name == "Carla/Maps/Town91" and wmap.name.split("/")[-1] == "Town91"
    wp = wmap.get_waypoint(carla.Location(20.3, 2.0, 0.0))
    assert (wp.road_id, wp.lane_id, wp.lane_type, wp.is_junction) == (1, -1, carla.LaneType.Driving, False)
    _close(wp.transform.location, (20.3, 1.75, 0.0), abs=1e-6)
    assert wp.lane_width == pytest.approx(3.5) and wp.right_lane_marking.type == carla.LaneMarkingType.Broken
    assert wp.left_lane_marking.color == carla.LaneMarkingColor.Yellow and wp.lane_change == carla.LaneChange.Right
    ahead = wp.next(10.0)
    assert len(ahead) == 1 and ahead[0].transform.location.x == pytest.approx(30.3)
    assert wp.get_right_lane().lane_id == -2 and wp.get_left_lane().lane_id == 1
    assert wmap.get_waypoint(carla.Location(20.0, 30.0, 0.0), project_to_road=False) is None
    assert wmap.get_waypoint_xodr(2, -2, 5.0).transform.location.x == pytest.approx(105.0)
    assert all(isinstance(a, carla.Waypoint) for a, _ in wmap.get_topology())
    geo = wmap.transform_to_geolocation(carla.Location(0.0, 0.0, 0.0))
    assert (geo.latitude, geo.longitude) == pytest.approx((49.0, 8.0))
    assert "<OpenDRIVE>" in wmap.to_opendrive()


def test_global_route_planner(shim: Shim) -> None:
    carla = shim.carla
    from agents.navigation.global_route_planner import GlobalRoutePlanner
    from agents.navigation.local_planner import RoadOption as ShimRoadOption

    assert ShimRoadOption is RoadOption and ShimRoadOption.CHANGELANELEFT == 5
    grp = GlobalRoutePlanner(carla.Client().get_world().get_map(), 1.0)
    route = grp.trace_route(carla.Location(10.0, 1.75, 0.0), carla.Location(150.0, 1.75, 0.0))
    assert len(route) > 100 and all(isinstance(w, carla.Waypoint) for w, _ in route)
    assert {option for _, option in route} == {RoadOption.LANEFOLLOW}
    assert route[0][0].road_id == 1 and route[-1][0].road_id == 2


# ---------------------------------------------------------------------------------------- route manipulation


def _straight_route(carla: ModuleType, options: list[RoadOption]) -> list[tuple]:
    return [(carla.Transform(carla.Location(float(i), 0.0, 0.0)), option) for i, option in enumerate(options)]


def test_downsample_route(shim: Shim) -> None:
    from leaderboard.utils.route_manipulation import downsample_route

    lf, left = RoadOption.LANEFOLLOW, RoadOption.LEFT
    route = _straight_route(shim.carla, [lf] * 60 + [left] * 20 + [lf] * 40)
    # 0: first point. The distance counts over the points not kept: at i = 52 it is 51 m > 50 → kept.
    # 60: LANEFOLLOW → LEFT; 80: LEFT → LANEFOLLOW; 119: the last point (only 39 m after 80).
    assert downsample_route(route, 50) == [0, 52, 60, 80, 119]
    change = RoadOption.CHANGELANELEFT
    route = _straight_route(shim.carla, [lf] * 10 + [change] * 3 + [lf] * 18)
    # every lane-change point is kept; the switch back to LANEFOLLOW after a lane change is not a decision point
    assert downsample_route(route, 50) == [0, 10, 11, 12, 30]


def test_set_global_plan_downsamples_to_50_m(shim: Shim) -> None:
    from leaderboard.autoagents.autonomous_agent import AutonomousAgent
    from leaderboard.utils.route_manipulation import location_route_to_gps

    lf, left = RoadOption.LANEFOLLOW, RoadOption.LEFT
    world_route = _straight_route(shim.carla, [lf] * 60 + [left] * 20 + [lf] * 40)
    gps_route = location_route_to_gps(world_route, 49.0, 8.0)
    agent = AutonomousAgent("localhost", 2000)
    agent.set_global_plan(gps_route, world_route)
    assert [t.location.x for t, _ in agent._global_plan_world_coord] == [0.0, 52.0, 60.0, 80.0, 119.0]
    assert agent._global_plan == [gps_route[i] for i in (0, 52, 60, 80, 119)]
    assert agent._plan_HACK is world_route and agent._plan_gps_HACK is gps_route


def test_location_to_gps(shim: Shim) -> None:
    from leaderboard.utils.route_manipulation import _location_to_gps

    carla = shim.carla
    assert _location_to_gps(0.0, 0.0, carla.Location(0.0, 0.0, 0.0)) == {"lat": 0.0, "lon": 0.0, "z": 0.0}
    # one degree of longitude on the equator is 2π·6378137 / 360 = 111319.49 m
    east = _location_to_gps(0.0, 0.0, carla.Location(111319.49, 0.0, 3.0))
    assert east["lon"] == pytest.approx(1.0, abs=1e-7) and east["lat"] == pytest.approx(0.0) and east["z"] == 3.0
    south = _location_to_gps(0.0, 0.0, carla.Location(0.0, 1000.0, 0.0))  # CARLA's +y points south
    assert south["lat"] < 0.0 and south["lon"] == 0.0


def test_get_latlon_ref(shim: Shim) -> None:
    from leaderboard.utils.route_manipulation import _get_latlon_ref, _parse_latlon_ref
    from srunner.scenariomanager.carla_data_provider import CarlaDataProvider

    assert _get_latlon_ref(CarlaDataProvider.get_world()) == (49.0, 8.0)
    assert CarlaDataProvider.get_latlon_ref() == (49.0, 8.0)
    header = "<OpenDRIVE><header><geoReference><![CDATA[+proj=tmerc +lon_0=-3.5 +lat_0=40.25]]></geoReference></header>"
    assert _parse_latlon_ref(header + "</OpenDRIVE>") == (40.25, -3.5)
    assert _parse_latlon_ref("<OpenDRIVE><header/></OpenDRIVE>") == (42.0, 2.0)


def test_interpolate_trajectory(shim: Shim) -> None:
    carla = shim.carla
    from leaderboard.utils.route_manipulation import interpolate_trajectory

    gps, route = interpolate_trajectory([carla.Location(10.0, 1.75, 0.0), carla.Location(150.0, 1.75, 0.0)])
    assert len(gps) == len(route) > 100
    transform, option = route[0]
    assert isinstance(transform, carla.Transform) and option is RoadOption.LANEFOLLOW
    assert transform.location.x == pytest.approx(10.0, abs=1.0)
    assert gps[0][0]["lat"] == pytest.approx(49.0, abs=1e-3) and gps[0][0]["lon"] == pytest.approx(8.0, abs=1e-3)


# ------------------------------------------------------------------------------------------ sensor interface


def test_sensor_interface_get_data(shim: Shim) -> None:
    from leaderboard.envs import sensor_interface as si

    assert si.SensorConfigurationInvalid is sensor_config.SensorConfigurationInvalid
    assert si.SensorReceivedNoData is sensor_config.SensorReceivedNoData
    interface = si.SensorInterface()
    interface.register_sensor("CAM_FRONT", "sensor.camera.rgb", None)
    interface.register_sensor("SPEED", "sensor.speedometer", None)
    interface.register_sensor("OpenDRIVE", "sensor.opendrive_map", None)
    with pytest.raises(si.SensorConfigurationInvalid, match=r"Duplicated sensor tag \[SPEED\]"):
        interface.register_sensor("SPEED", "sensor.speedometer", None)
    with pytest.raises(si.SensorConfigurationInvalid, match=r"\[GPS\] has not been created"):
        interface.update_sensor("GPS", None, 5)
    interface.update_sensor("CAM_FRONT", "old image", 4)  # another frame's data is dropped
    interface.update_sensor("CAM_FRONT", "image", 5)
    interface.update_sensor("SPEED", {"speed": 1.5}, 5)
    assert interface.get_data(5) == {"CAM_FRONT": (5, "image"), "SPEED": (5, {"speed": 1.5})}  # no map: not waited for
    interface.update_sensor("SPEED", {"speed": 2.0}, 6)
    with pytest.raises(si.SensorReceivedNoData, match="frame 6 from sensor\\(s\\) CAM_FRONT"):
        interface.get_data(6)  # at once: the evaluator pushes every sensor's data before the step
    interface.update_sensor("CAM_FRONT", "image 6", 6)
    interface.update_sensor("OpenDRIVE", {"opendrive": "<OpenDRIVE/>"}, 6)
    data = interface.get_data(6)
    assert data["SPEED"] == (6, {"speed": 2.0}) and data["OpenDRIVE"] == (6, {"opendrive": "<OpenDRIVE/>"})
    assert si.GenericMeasurement({"speed": 1.0}, 3).frame == 3


def test_agent_call_runs_a_step(shim: Shim) -> None:
    carla = shim.carla
    from leaderboard.autoagents.autonomous_agent import AutonomousAgent
    from srunner.scenariomanager.timer import GameTime

    class Agent(AutonomousAgent):
        def run_step(self, input_data, timestamp):
            self.seen = (input_data, timestamp)
            return carla.VehicleControl(throttle=0.3, manual_gear_shift=True)

    agent = Agent("localhost", 2000)
    agent.sensor_interface.register_sensor("SPEED", "sensor.speedometer", None)
    shim.tick()
    agent.sensor_interface.update_sensor("SPEED", {"speed": 0.0}, GameTime.get_frame())
    control = agent()
    assert control.throttle == 0.3 and control.manual_gear_shift is False
    assert agent.seen == ({"SPEED": (GameTime.get_frame(), {"speed": 0.0})}, pytest.approx(0.05))


def test_agent_wrapper_reexports_the_rules(shim: Shim) -> None:
    from leaderboard.autoagents import agent_wrapper

    assert agent_wrapper.validate_sensor_configuration is sensor_config.validate_sensor_configuration
    assert agent_wrapper.SENSORS_LIMITS["sensor.camera.rgb"] == 8 and agent_wrapper.MAX_ALLOWED_RADIUS_SENSOR in (
        3,
        100,
    )


def test_outside_a_route_the_views_say_so(shim: Shim) -> None:
    carla = shim.carla
    bridge.install(None)
    try:
        assert carla.Location(1, 2, 3).x == 1.0  # value types need no route
        with pytest.raises(bridge.NoRouteRunning, match="b2d-eval run"):
            carla.Client().get_world()
    finally:
        bridge.install(shim.route)


def test_traffic_light_views(carla_maps_dir: Path) -> None:
    town = load_opendrive(carla_maps_dir / "Town01.xodr")
    sim = BuiltinSimulator(town, seed=0)
    light = min(sim.snapshot().traffic_lights.values(), key=lambda info: info.id)
    stop = light.stop_waypoints[0].transform  # the centre of the light's trigger volume on a governed lane
    at_stop = fmt.Transform(fmt.Location(stop.location.x, stop.location.y, stop.location.z + 0.5), stop.rotation)
    hero_id = sim.spawn_actor(HERO, at_stop)
    with _route_installed(sim, town, hero_id) as route:
        from srunner.scenariomanager.carla_data_provider import CarlaDataProvider

        carla = importlib.import_module("carla")
        lights = CarlaDataProvider.get_world().get_actors().filter("*traffic_light*")
        assert len(lights) == len(route.snapshot.traffic_lights) > 0
        view = lights.find(light.id)
        assert isinstance(view, carla.TrafficLight) and view.type_id == "traffic.traffic_light"
        assert view.state == int(route.snapshot.traffic_lights[light.id].state) and view.get_state() == view.state
        group = view.get_group_traffic_lights()
        assert view in group and {g.id for g in group} == {
            i.id for i in route.snapshot.traffic_lights.values() if i.group_id == light.group_id
        }
        trigger = CarlaDataProvider.get_trafficlight_trigger_location(view)
        assert trigger.distance_2d(carla.Location(stop.location.x, stop.location.y, 0.0)) < 0.01
        hero = CarlaDataProvider.get_hero_actor()
        assert hero.get_traffic_light() == view and hero.is_at_traffic_light()
        assert hero.get_traffic_light_state() == view.state
        assert view.get_stop_waypoints()[0].transform.location.distance(trigger) < 0.5
        assert view.get_opendrive_id() == light.opendrive_id and not view.is_frozen()
        assert CarlaDataProvider.get_world().get_actor(hero.id).get_speed_limit() > 0.0
