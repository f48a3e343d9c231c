"""Annotation building on a synthetic snapshot of a real town: key orders and computed fields by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.collection.annotations import PlannerFields, build_annotation, count_points_in_box
from b2d_data.format.anno_schema import check_anno
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import PRESETS
from b2d_data.sim.api import (
    ActorKind,
    GnssReading,
    ImuReading,
    RigConfig,
    SensorData,
    Snapshot,
    VehicleControl,
)

from .conftest import make_actor


def test_count_points_uses_the_actor_origin_box():
    ego = make_actor(1, "vehicle.lincoln.mkz_2020", ActorKind.VEHICLE, Transform(), (2.4, 1.0, 0.75), (14,))
    # Other car 10 m ahead, turned 90°: its length (2 m half) runs along the ego's y axis.
    other = make_actor(2, "vehicle.audi.a2", ActorKind.VEHICLE, Transform(Location(10, 0, 0), Rotation(yaw=90)),
                   (2.0, 1.0, 0.8), (14,))
    pts = np.array([
        [10.0, 1.9, 0.5],   # inside: 1.9 < 2.0 along its length
        [10.0, 2.1, 0.5],   # outside its length
        [10.9, 0.0, 0.5],   # inside: 0.9 < 1.0 across its width
        [11.1, 0.0, 0.5],   # outside its width
        [10.0, 0.0, 1.0],   # outside: z 1.0 above the *origin* exceeds the 0.8 half height (released rule)
    ])  # fmt: skip
    assert count_points_in_box(pts, ego, other) == 2
    assert count_points_in_box(None, ego, other) == -1


def test_count_points_matches_testing_every_point():
    """The count skips points far along ego x; it must equal the box test applied to every point."""
    rng = np.random.default_rng(5)
    for k in range(20):
        ego_tf = Transform(Location(*rng.uniform(-50, 50, 2), 0.0), Rotation(yaw=float(rng.uniform(-180, 180))))
        ego = make_actor(1, "vehicle.lincoln.mkz_2020", ActorKind.VEHICLE, ego_tf, (2.4, 1.0, 0.75), (14,))
        rel = rng.uniform(-15, 15, 2)
        other_tf = Transform(ego_tf.transform_point(Location(float(rel[0]), float(rel[1]), 0.0)),
                             Rotation(yaw=float(rng.uniform(-180, 180))))  # fmt: skip
        other = make_actor(2, "vehicle.audi.a2", ActorKind.VEHICLE, other_tf, (2.0, 1.0, 0.8), (14,))
        around = np.zeros((500, 3))
        around[:, :2] = rel + rng.uniform(-2.5, 2.5, (500, 2))  # a cloud on and around the other car
        around[:, 2] = rng.uniform(-1.0, 1.0, 500)
        pts = np.concatenate([rng.uniform(-40, 40, (3000, 3)) * [1, 1, 0.05], around])
        pts = pts.astype(np.float32)
        # Every point through the box rule (the actor origin in the ego frame, relative yaw, half extents).
        o = ego_tf.inverse_transform_points(other_tf.location.to_array()[None, :])[0]
        yaw = np.radians(other_tf.rotation.yaw - ego_tf.rotation.yaw)
        d = pts - o
        lx, ly = np.cos(yaw) * d[:, 0] + np.sin(yaw) * d[:, 1], -np.sin(yaw) * d[:, 0] + np.cos(yaw) * d[:, 1]
        expected = int(np.count_nonzero((np.abs(lx) < 2.0) & (np.abs(ly) < 1.0) & (np.abs(d[:, 2]) < 0.8)))
        assert count_points_in_box(pts, ego, other) == expected, k
        assert expected > 0 or k > 0


def test_annotation_follows_the_schema_and_values(town01):
    wp = town01.generate_waypoints(20.0)[5]
    ego_tf = Transform(wp.transform.location, wp.transform.rotation)
    ego = make_actor(7, "vehicle.lincoln.mkz_2020", ActorKind.VEHICLE, ego_tf, (2.451, 1.064, 0.755), (14,), speed=5.0,
                 role_name="hero", base_type="car", control=VehicleControl(throttle=0.3, steer=-0.1),
                 attributes={"color": "10,20,30"})
    fwd = ego_tf.get_forward_vector()
    ahead = Transform(Location(ego_tf.location.x + 20 * fwd.x, ego_tf.location.y + 20 * fwd.y, ego_tf.location.z),
                      ego_tf.rotation)
    car = make_actor(8, "vehicle.audi.a2", ActorKind.VEHICLE, ahead, (1.85, 0.9, 0.77), (14,), speed=3.0,
                 base_type="car", control=VehicleControl(brake=1.0))
    walker = make_actor(9, "walker.pedestrian.0001", ActorKind.WALKER,
                    Transform(Location(ego_tf.location.x + 5 * fwd.x, ego_tf.location.y + 5 * fwd.y, 0.0)),
                    (0.25, 0.25, 0.9), (12,), speed=1.2, attributes={"gender": "female", "age": "adult"})
    far_away = make_actor(10, "vehicle.audi.a2", ActorKind.VEHICLE,
                      Transform(Location(ego_tf.location.x + 500, ego_tf.location.y, 0.0)), (1.85, 0.9, 0.77), (14,))
    snapshot = Snapshot(frame=3, timestamp=0.15, actors={a.id: a for a in (ego, car, walker, far_away)},
                        traffic_lights={}, traffic_signs={}, collisions=(), weather=PRESETS[3])
    lidar = ego_tf.inverse_transform_points(np.array([[ahead.location.x, ahead.location.y, ahead.location.z + 0.5]]))
    geo = town01.transform_to_geolocation(ego_tf.location)
    sensors = SensorData(
        frame=3, cameras={}, lidar=lidar, lidar_tags=np.array([14]), lidar_actor_ids=np.array([8]), radar={},
        imu=ImuReading((0.1, 0.2, 9.8), (0.0, 0.0, 0.01), 1.25), gnss=GnssReading(geo.latitude, geo.longitude, 0.0),
        speed=5.0,
    )  # fmt: skip
    plan = PlannerFields(1.0, 2.0, 4, 3.0, 4.0, 1, 5.0, 6.0, 3)
    route_ahead = np.array([[ego_tf.location.x + k * fwd.x, ego_tf.location.y + k * fwd.y] for k in range(50)])
    anno = build_annotation(town01, snapshot, ego, sensors, RigConfig(width=160, height=90), plan,
                            (ego_tf.location.x, ego_tf.location.y), True, False, route_ahead)
    assert check_anno(anno) == []
    boxes = anno["bounding_boxes"]
    assert [b["class"] for b in boxes] == ["ego_vehicle", "vehicle", "walker"]  # the 500 m car is not captured
    assert boxes[0]["semantic_tags"] == [[14]] and boxes[0]["color"] == "10,20,30"
    assert boxes[0]["road_id"] == wp.road_id and boxes[0]["lane_id"] == wp.lane_id
    np.testing.assert_allclose(np.array(boxes[0]["world2ego"]) @ ego_tf.matrix(), np.eye(4), atol=1e-9)
    assert boxes[1]["num_points"] == 1 and boxes[1]["brake"] == 1.0
    assert boxes[1]["distance"] == pytest.approx(20.0, abs=1e-6)
    assert boxes[2]["speed"] == pytest.approx(1.2) and boxes[2]["gender"] == "female"
    assert len(boxes[2]["bone"]) == 6
    # The world corners of the car: its centre is 0.77 m above its origin, so the top corners are at +1.54 m.
    corners = np.array(boxes[1]["world_cord"])
    assert corners[:, 2].max() == pytest.approx(ahead.location.z + 1.54)
    assert anno["theta"] == 1.25 and anno["command_near"] == 1 and anno["should_brake"] is True
    cam = anno["sensors"]["CAM_FRONT"]
    # 160 px wide, FOV 70°: f = 80 / tan(35°) = 114.25 px.
    assert cam["intrinsic"][0][0] == pytest.approx(80 / math.tan(math.radians(35)))
    np.testing.assert_allclose(np.array(cam["cam2ego"])[:3, 3], [0.8, 0.0, 1.6])
    assert list(anno["sensors"]) == [
        "CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_BACK_RIGHT", "TOP_DOWN",
        "RADAR_FRONT", "RADAR_FRONT_LEFT", "RADAR_FRONT_RIGHT", "RADAR_BACK_LEFT", "RADAR_BACK_RIGHT", "LIDAR_TOP",
    ]  # fmt: skip


def test_num_points_counts_the_points_as_the_laz_file_stores_them(town01, tmp_path):
    from b2d_data.codecs.laz import read_laz, write_laz

    ego = make_actor(7, "vehicle.lincoln.mkz_2020", ActorKind.VEHICLE, Transform(), (2.451, 1.064, 0.755), (14,))
    # A car 20 m ahead, its box 1.8503 m long (half) around its origin: its front face at ego x = 21.8503.
    car = make_actor(8, "vehicle.audi.a2", ActorKind.VEHICLE, Transform(Location(20.0, 0.0, 0.0)), (1.8503, 0.9, 0.77),
                     (14,))  # fmt: skip
    snapshot = Snapshot(frame=3, timestamp=0.15, actors={7: ego, 8: car}, traffic_lights={}, traffic_signs={},
                        collisions=(), weather=PRESETS[3])  # fmt: skip
    # A return 0.1 mm in front of that face (outside the box) and one at the ego origin, which makes every LAZ
    # offset 0: stored in 1 mm steps the return becomes x = round(21850.4) · 1 mm = 21.850, inside the box.
    lidar = np.array([[0.0, 0.0, 0.0], [21.8504, 0.0, 0.3]], np.float32)
    sensors = SensorData(
        frame=3, cameras={}, lidar=lidar, lidar_tags=np.array([0, 14]), lidar_actor_ids=np.array([0, 8]), radar={},
        imu=ImuReading((0.0, 0.0, 9.8), (0.0, 0.0, 0.0), 1.57), gnss=GnssReading(0.0, 0.0, 0.0), speed=0.0,
    )  # fmt: skip
    anno = build_annotation(town01, snapshot, ego, sensors, RigConfig(width=160, height=90),
                            PlannerFields(1.0, 2.0, 4, 3.0, 4.0, 1, 5.0, 6.0, 3), (0.0, 0.0), False, False,
                            np.zeros((0, 2)))  # fmt: skip
    (box,) = [b for b in anno["bounding_boxes"] if b["id"] == "8"]
    assert box["num_points"] == 1
    # What a reader of the written file gets: the return at 21.850, 0.35 mm inside the face.
    write_laz(tmp_path / "00000.laz", lidar)
    np.testing.assert_allclose(read_laz(tmp_path / "00000.laz")[1], [21.85, 0.0, 0.3], atol=1e-9)


def _crowded_frame(town, seed: int):
    """A frame with dozens of boxes of every actor kind around a Town01 lane, and a LiDAR-like sweep."""
    rng = np.random.default_rng(seed)
    wps = town.generate_waypoints(8.0)
    wp = wps[int(rng.integers(len(wps)))]
    ego_tf = Transform(wp.transform.location, wp.transform.rotation)
    ego = make_actor(1, "vehicle.lincoln.mkz_2020", ActorKind.VEHICLE, ego_tf, (2.451, 1.064, 0.755), (14,), speed=4.0)
    actors = {1: ego}
    kinds = [("vehicle.audi.a2", ActorKind.VEHICLE, (1.85, 0.9, 0.77), (14,)),
             ("walker.pedestrian.0001", ActorKind.WALKER, (0.25, 0.25, 0.9), (12,)),
             ("static.prop.mesh.Car.parked", ActorKind.PROP, (2.2, 1.0, 0.8), (14,)),
             ("static.prop.warningconstruction", ActorKind.PROP, (0.5, 0.6, 0.9), (20,))]  # fmt: skip
    for actor_id in range(2, 60):
        type_id, kind, extent, tags = kinds[int(rng.integers(len(kinds)))]
        near = wps[int(rng.integers(len(wps)))].transform.location if rng.random() < 0.3 else ego_tf.location
        loc = Location(near.x + float(rng.uniform(-40, 40)), near.y + float(rng.uniform(-40, 40)), near.z)
        tf = Transform(loc, Rotation(yaw=float(rng.uniform(-180, 180))))
        actors[actor_id] = make_actor(actor_id, type_id, kind, tf, extent, tags, speed=float(rng.uniform(0, 8)))
    # Ground and object returns around the ego, in its frame (some right on box faces: 1 mm steps after stored_points).
    ground = rng.uniform(-60, 60, (20_000, 3)) * [1, 1, 0.02]
    others = [a for a in actors.values() if a.id != 1]
    on_boxes = np.concatenate([
        ego_tf.inverse_transform_points(a.transform.transform_points(
            rng.uniform(-1.1, 1.1, (150, 3)) * a.bounding_box.extent.to_array())) for a in others
    ])  # fmt: skip
    lidar = np.concatenate([ground, on_boxes]).astype(np.float32)
    snapshot = Snapshot(frame=5, timestamp=0.25, actors=actors, traffic_lights={}, traffic_signs={}, collisions=(),
                        weather=PRESETS[1])  # fmt: skip
    sensors = SensorData(
        frame=5, cameras={}, lidar=lidar, lidar_tags=np.zeros(len(lidar), np.uint32),
        lidar_actor_ids=np.zeros(len(lidar), np.uint32), radar={},
        imu=ImuReading((0.0, 0.0, 9.8), (0.0, 0.0, 0.0), 0.5), gnss=GnssReading(0.0, 0.0, 0.0), speed=4.0,
    )  # fmt: skip
    fwd = ego_tf.get_forward_vector()
    route = np.array([[ego_tf.location.x + k * fwd.x, ego_tf.location.y + k * fwd.y] for k in range(50)])
    return snapshot, ego, sensors, route


class _OneByOne:
    """A map that only answers get_waypoint: the annotation asks it box by box (the path before batching)."""

    def __init__(self, town) -> None:
        self.get_waypoint = town.get_waypoint


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_batched_lanes_and_counts_are_the_box_by_box_values(town01, seed):
    import json

    from b2d_data.codecs.laz import stored_points
    from b2d_data.collection import annotations

    snapshot, ego, sensors, route = _crowded_frame(town01, seed)
    args = (snapshot, ego, sensors, RigConfig(width=160, height=90), PlannerFields(1.0, 2.0, 4, 3.0, 4.0, 1, 5.0, 6.0, 3),
            (0.0, 0.0), False, False, route)  # fmt: skip
    anno = build_annotation(town01, *args)
    boxes = anno["bounding_boxes"]
    assert len(boxes) > 25 and {b["class"] for b in boxes} >= {"vehicle", "walker", "traffic_sign"}
    # Lanes: one KD-tree query for the frame gives each box what get_waypoint gives it.
    assert json.dumps(build_annotation(_OneByOne(town01), *args), indent=4) == json.dumps(anno, indent=4)
    for box in boxes:
        wp = town01.get_waypoint(Location(*box["location"]))
        assert (box["road_id"], box["lane_id"], box["section_id"]) == (wp.road_id, wp.lane_id, wp.section_id)
    # num_points: the slab index changes nothing against the whole-sweep count of each box.
    points = stored_points(sensors.lidar)
    counted = [b for b in boxes if "num_points" in b]
    assert sum(b["num_points"] > 0 for b in counted) > 10
    for box in counted:
        actor = snapshot.actors[int(box["id"])]
        assert box["num_points"] == count_points_in_box(points, ego, actor)
    # Pose fields are Transform's own (bit for bit).
    for box in boxes[1:]:
        actor = snapshot.actors[int(box["id"])]
        matrices = [key for key in box if key.startswith("world2")]
        assert matrices and all(box[key] == actor.transform.inverse_matrix().tolist() for key in matrices)
        if "world_cord" in box:
            assert box["world_cord"] == actor.bounding_box.world_corners(actor.transform).tolist()
        if "center" in box:
            assert box["center"] == actor.transform.transform_point(actor.bounding_box.location).to_list()
    assert annotations.frame_lane_ids(town01, []) == []


def test_slab_index_never_drops_a_point_near_a_box():
    """Boxes whose reach ends on slab borders, points on those borders and in box corners: counts unchanged."""
    from b2d_data.collection.annotations import points_in_origin_box, xy_slabs

    rng = np.random.default_rng(11)
    edges = np.arange(-40.0, 41.0, 4.0)
    jitter = [-1e-12, 0.0, 1e-12]
    border = np.column_stack([np.repeat(edges, 20) + rng.choice(jitter, len(edges) * 20),
                              np.tile(edges, 20)[: len(edges) * 20] + rng.choice(jitter, len(edges) * 20),
                              rng.uniform(-0.5, 0.5, len(edges) * 20)])  # fmt: skip
    base = np.concatenate([rng.uniform(-45, 45, (4000, 3)) * [1, 1, 0.02], border])
    total = 0
    for _ in range(300):
        ex, ey, ez = rng.uniform(0.2, 3.0, 3)
        reach = math.hypot(ex, ey)
        x0 = float(rng.choice(edges)) + float(rng.choice([-reach, reach, 0.0])) + float(rng.normal(0, 1e-9))
        y0 = float(rng.choice(edges)) + float(rng.choice([-reach, reach, 0.0])) + float(rng.normal(0, 1e-9))
        yaw = float(rng.choice([0.0, 45.0, 90.0, -135.0, rng.uniform(-180, 180)]))
        # Points filling the box and a hair beyond, corners included (where |y - y0| comes closest to the reach).
        c, s_ = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
        local = rng.uniform(-1.0001, 1.0001, (300, 3)) * [ex, ey, ez]
        local[:40, :2] = np.sign(local[:40, :2]) * [ex, ey] * (1 - 1e-12)  # on the corners' verticals
        box = np.column_stack([x0 + c * local[:, 0] - s_ * local[:, 1], y0 + s_ * local[:, 0] + c * local[:, 1],
                               local[:, 2]])  # fmt: skip
        pts = np.concatenate([base, box])
        loc = [x0, y0, 0.0]
        want = points_in_origin_box(pts, np.eye(4), loc, yaw, (ex, ey, ez))
        assert points_in_origin_box(pts, np.eye(4), loc, yaw, (ex, ey, ez), xy_slabs(pts)) == want
        total += want
    assert total > 300 * 100  # the boxes hold most of their points: the test exercises full boxes


def test_sensor_calibrations_cached_matrices_are_fresh_and_exact():
    from b2d_data.collection.annotations import sensor_calibrations
    from b2d_data.format.rig import ALL_CAMERAS, LIDAR, RADARS_V0

    ego = make_actor(1, "vehicle.lincoln.mkz_2020", ActorKind.VEHICLE,
                     Transform(Location(3.0, -7.5, 0.2), Rotation(yaw=31.0, pitch=1.5)), (2.4, 1.0, 0.75), (14,))  # fmt: skip
    config = RigConfig(width=160, height=90)
    first, second = sensor_calibrations(ego, config), sensor_calibrations(ego, config)
    assert first == second
    for spec in ALL_CAMERAS:
        w, h = (config.top_down_width, config.top_down_height) if spec.sensor_id == "TOP_DOWN" else (160, 90)
        entry = first[spec.sensor_id]
        assert entry["cam2ego"] == spec.mount.matrix().tolist() and entry["intrinsic"] == spec.intrinsic(w, h).tolist()
        pose = Transform.from_matrix(ego.transform.matrix() @ spec.mount.matrix())
        assert entry["world2cam"] == pose.inverse_matrix().tolist()
    for radar in RADARS_V0:
        assert first[radar.sensor_id]["radar2ego"] == radar.mount.matrix().tolist()
    assert first[LIDAR.sensor_id]["lidar2ego"] == LIDAR.mount.matrix().tolist()
    # Each annotation owns its lists: changing one frame's matrix leaves the next frame's alone.
    first["CAM_FRONT"]["cam2ego"][0][0] = 99.0
    first["LIDAR_TOP"]["lidar2ego"][0].append(1.0)
    assert sensor_calibrations(ego, config) == second
