"""Scene meshing: the static town mesh, actor shapes fitted to their boxes, traffic-light fixtures."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from b2d_data.format.semantic import SemanticTag as T
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform
from b2d_data.sim.api import TrafficLightInfo, TrafficLightState, VehicleDoor
from b2d_data.sim.builtin.sensors.actor_mesh import ActorMeshBuilder
from b2d_data.sim.builtin.sensors.fixture_mesh import fixture_of_light, fixture_static_mesh, lamp_mesh
from b2d_data.sim.builtin.sensors.map_mesh import SIDEWALK_HEIGHT, build_static_scene
from b2d_data.sim.builtin.sensors.scene_mesh import Material
from b2d_data.sim.builtin.sensors.synthetic import actor_state, crossroads_layout


@pytest.fixture(scope="module")
def street_scene():
    return build_static_scene(crossroads_layout(), seed=5)


def test_static_scene_has_every_class_and_is_seeded(street_scene):
    mesh = street_scene.mesh
    tags = set(np.unique(mesh.tags).tolist())
    for tag in (T.ROAD, T.SIDEWALK, T.BUILDING, T.POLE, T.VEGETATION, T.TERRAIN, T.ROAD_LINE):
        assert int(tag) in tags
    assert len(mesh) < 50_000  # the rasteriser's budget
    assert len(street_scene.lamps) > 4
    again = build_static_scene(crossroads_layout(), seed=5).mesh
    np.testing.assert_array_equal(mesh.vertices, again.vertices)
    other = build_static_scene(crossroads_layout(), seed=6).mesh
    first = mesh.vertices[mesh.tags == T.BUILDING][:10]
    assert not np.array_equal(first, other.vertices[other.tags == T.BUILDING][:10])


def test_sidewalks_are_raised_and_lines_sit_on_the_road(street_scene):
    mesh = street_scene.mesh
    # Sidewalk tops 15 cm up (curb faces span 0..0.15); lines 2 cm above the asphalt at z = 0.
    side_z = mesh.vertices[mesh.tags == T.SIDEWALK][..., 2]
    assert np.isclose(side_z.max(), SIDEWALK_HEIGHT) and np.isclose(side_z.min(), 0.0)
    np.testing.assert_allclose(mesh.vertices[mesh.tags == T.ROAD_LINE][..., 2], 0.02, atol=1e-6)
    # Yellow centre lines and white lane lines.
    colors = {tuple(c) for c in mesh.colors[mesh.tags == T.ROAD_LINE].tolist()}
    assert len(colors) == 2


def test_buildings_keep_off_roads_and_sidewalks(street_scene):
    layout = crossroads_layout()
    pts = np.concatenate([s.left + (s.right - s.left) * f for s in layout.lanes for f in np.linspace(0, 1, 9)])
    tree = cKDTree(pts[:, :2])
    mesh = street_scene.mesh
    footprint = mesh.vertices[mesh.tags == T.BUILDING].reshape(-1, 3)
    dist, _ = tree.query(footprint[:, :2])
    assert dist.min() > 1.0


def test_vehicle_shape_fills_its_box_and_doors_open_outwards():
    builder = ActorMeshBuilder()
    car = actor_state(5, "vehicle.tesla.model3", 0.0, 0.0, 0.0)
    mesh = builder.local_mesh(car, night=False, timestamp=0.0)
    corners = car.bounding_box.local_corners()
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    v = mesh.vertices.reshape(-1, 3)
    assert (v >= lo - 1e-4).all() and (v <= hi + 1e-4).all()
    # The body spans the full length, width and height of the box.
    np.testing.assert_allclose(v.min(axis=0)[:2], lo[:2], atol=1e-4)
    np.testing.assert_allclose(v.max(axis=0), hi, atol=1e-4)
    assert (mesh.instance_ids == 5).all() and set(np.unique(mesh.tags).tolist()) == {int(T.CAR)}
    opened = actor_state(5, "vehicle.tesla.model3", 0.0, 0.0, 0.0, open_doors=(VehicleDoor.FL,))
    door_mesh = builder.local_mesh(opened, night=False, timestamp=0.0)
    # The front-left door swings out to the left (−y in CARLA's frame), beyond the box.
    assert door_mesh.vertices[..., 1].min() < lo[1] - 0.5 and door_mesh.vertices[..., 1].max() <= hi[1] + 1e-4


def test_two_wheeler_has_a_rider_and_walker_is_a_pedestrian():
    builder = ActorMeshBuilder()
    bike = builder.local_mesh(actor_state(6, "vehicle.bh.crossbike", 0.0, 0.0, 0.0), False, 0.0)
    assert set(np.unique(bike.tags).tolist()) == {int(T.BICYCLE), int(T.RIDER)}
    walker = builder.local_mesh(actor_state(7, "walker.pedestrian.0001", 0.0, 0.0, 0.0), False, 0.0)
    assert set(np.unique(walker.tags).tolist()) == {int(T.PEDESTRIAN)}
    # A walker stands on the ground: its origin is the capsule centre, 0.93 m up.
    assert np.isclose(walker.vertices[..., 2].min(), -0.93, atol=0.05)


def test_lamps_glow_at_night_only_when_lit():
    builder = ActorMeshBuilder()
    car = actor_state(5, "vehicle.tesla.model3", 0.0, 0.0, 0.0)
    day = builder.local_mesh(car, night=False, timestamp=0.0)
    night = builder.local_mesh(car, night=True, timestamp=0.0)
    assert (day.materials == Material.EMISSIVE).sum() == 0
    assert (night.materials == Material.EMISSIVE).sum() > 0


#: The head of the traffic light :func:`_light_info` makes.
HEAD = Transform(Location(10.0, 5.0, 3.0), Rotation(yaw=90.0))


def _light_info(state: TrafficLightState) -> TrafficLightInfo:
    """A traffic light at (10, 5) whose head (:data:`HEAD`) faces +y."""
    return TrafficLightInfo(
        id=900, transform=Transform(Location(10.0, 5.0, 0.0), Rotation(yaw=0.0)), state=state,
        trigger_volume=BoundingBox(Location(0.0, 8.0, 1.0), Location(2.0, 1.5, 1.0)), stop_waypoints=(),
        affected_lane_waypoints=(), group_id=0, opendrive_id="1",
        level_bbox=BoundingBox(HEAD.location, Location(0.25, 0.3, 0.6), HEAD.rotation), level_bbox_transform=HEAD,
    )  # fmt: skip


def test_traffic_light_head_fills_its_level_box():
    info = _light_info(TrafficLightState.GREEN)
    fixture = fixture_of_light(info)
    static = fixture_static_mesh([fixture])
    heads = static.vertices[static.tags == T.TRAFFIC_LIGHT].reshape(-1, 3)
    # The housing is the level box (yaw 90° swaps its x/y extents in the world) less the lamps' 2 cm slice on the
    # face the level box's +x axis points to (yaw 90°: +y, towards the traffic).
    np.testing.assert_allclose(heads.min(axis=0), [10.0 - 0.3, 5.0 - 0.25, 2.4], atol=1e-6)
    np.testing.assert_allclose(heads.max(axis=0), [10.0 + 0.3, 5.0 + 0.25 - 0.02, 3.6], atol=1e-6)
    assert int(T.POLE) in static.tags and (static.instance_ids == 900).all()
    lamps = lamp_mesh([fixture], {900: TrafficLightState.GREEN})
    lit = lamps.materials == Material.EMISSIVE
    assert lit.sum() == 12  # one box of three glows
    # Green is the lowest lamp, in that slice: flush with the box's face, so lamps and housing are exactly the box.
    assert lamps.vertices[lit][..., 2].max() < 3.0
    np.testing.assert_allclose(lamps.vertices[..., 1].min(), 5.25 - 0.02, atol=1e-6)
    np.testing.assert_allclose(lamps.vertices[..., 1].max(), 5.25, atol=1e-6)


def test_town_scene_is_built_once_per_layout_whatever_the_route_seed():
    from b2d_data.sim.builtin.sensors import suite
    from b2d_data.sim.builtin.sensors.map_mesh import RoadLayout

    suite._SCENES.clear()
    layout = crossroads_layout()
    first = suite.town_scene(layout)
    # An equal layout (rebuilt, not the same object) gets the very same scene: the scenery is the town's.
    assert suite.town_scene(crossroads_layout()) is first
    np.testing.assert_array_equal(first.mesh.vertices, build_static_scene(layout, seed=0).mesh.vertices)
    other = suite.town_scene(RoadLayout(layout.lanes[:2]))
    assert other is not first and len(other.mesh) < len(first.mesh)
    # Two layouts are kept; a third pushes out the least recently used one.
    suite.town_scene(crossroads_layout())
    suite.town_scene(RoadLayout(layout.lanes[:1]))
    assert suite.town_scene(crossroads_layout()) is first and len(suite._SCENES) == 2


class _Recorder:
    """Stands in for the renderer and the ray caster: keeps every dynamic mesh it is handed."""

    hardware = False

    def __init__(self) -> None:
        self.meshes = []

    def set_static(self, mesh) -> None:
        pass

    def set_lightmap(self, *args) -> None:
        pass

    def set_dynamic(self, mesh) -> None:
        self.meshes.append(mesh)

    def render(self, *args):
        return []

    def close(self) -> None:
        pass


def _same_mesh(a, b) -> None:
    for field in ("vertices", "normals", "colors", "tags", "instance_ids", "materials"):
        x, y = getattr(a, field), getattr(b, field)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), field


def test_the_tick_meshes_are_the_merged_actor_shapes_and_lamps():
    # What the renderer and the ray caster get each tick, worked out afresh every tick (a new builder: no shape,
    # pose or lamp kept from earlier ticks) and merged as the parts list says: every actor then the lamps for the
    # renderer, the same less the ego for the caster. Over the ticks a car drives, a van stays parked and brakes
    # (same pose, other tail lamps), a walker walks, the ego drives and brakes, and the light turns green.
    from dataclasses import replace

    from b2d_data.sim.api import VehicleControl
    from b2d_data.sim.builtin.sensors import suite
    from b2d_data.sim.builtin.sensors.map_mesh import StaticScene
    from b2d_data.sim.builtin.sensors.scene_mesh import TriangleMesh, merge
    from b2d_data.sim.builtin.sensors.synthetic import snapshot_of

    light = _light_info(TrafficLightState.RED)
    scene = suite.SensorScene()
    empty = StaticScene(TriangleMesh.empty(), np.zeros((0, 3)), np.zeros(3), np.ones(3))
    renderer, caster = _Recorder(), _Recorder()
    scene._setup_scene(empty, renderer, rays=False)  # type: ignore[arg-type]
    scene.caster = caster  # type: ignore[assignment]
    for k in range(6):
        actors = [
            actor_state(2, "vehicle.tesla.model3", 8.0 + 0.7 * k, 1.5, 2.0 * k),
            actor_state(1, "vehicle.lincoln.mkz_2020", -5.0 + 0.5 * k, -1.5, 0.0, role_name="hero",
                        control=VehicleControl(brake=1.0 if k >= 3 else 0.0)),
            actor_state(3, "vehicle.mercedes.sprinter", -9.0, -6.0, 30.0,
                        control=VehicleControl(brake=1.0 if k >= 2 else 0.0)),
            actor_state(4, "walker.pedestrian.0001", 3.0, -6.0 + 0.12 * k, 90.0, velocity=(0.0, 1.2, 0.0)),
        ]  # fmt: skip
        state = TrafficLightState.RED if k < 4 else TrafficLightState.GREEN
        snap = snapshot_of(actors, frame=k, timestamp=0.1 * k, traffic_lights={900: replace(light, state=state)})
        tick = scene._prepare(snap, 1)
        scene._render_views(tick, [[]])
        parts = ActorMeshBuilder().build_parts(snap.actors, False, snap.timestamp)
        lamps = lamp_mesh([fixture_of_light(snap.traffic_lights[900])], {900: state})
        _same_mesh(renderer.meshes[-1], merge([m for _, m in parts] + [lamps]))
        _same_mesh(caster.meshes[-1], merge([m for i, m in parts if i != 1] + [lamps]))
    assert len(renderer.meshes) == len(caster.meshes) == 6
