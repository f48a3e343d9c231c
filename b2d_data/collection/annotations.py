"""Build the annotation dict of one frame (format.md §3) from the simulator's view of the world.

Every field is computed the way Bench2Drive's collector computes it (tools/data_collect.py), with its quirks,
except where a quirk is a CARLA API bug that would only lose information: walker ``speed`` holds the walker's
real forward speed here (CARLA reports 0; loaders recompute it from finite differences either way).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from b2d_data.codecs.laz import stored_points
from b2d_data.format.anno_schema import (
    DYNAMIC_VEHICLE_KEYS,
    EGO_KEYS,
    PROP_SIGN_KEYS,
    STATIC_VEHICLE_KEYS,
    WALKER_KEYS,
)
from b2d_data.format.rig import ALL_CAMERAS, LIDAR, RADARS_V0, RADARS_V004, CameraSpec, Mount
from b2d_data.format.transform import BoundingBox, Location, Transform
from b2d_data.maps import Map
from b2d_data.sim.api import (
    ActorKind,
    ActorState,
    RigConfig,
    SensorData,
    Snapshot,
    TrafficLightInfo,
    TrafficSignInfo,
    VehicleControl,
)
from b2d_data.sim.light_state import carla_str

#: Objects farther than this (2-D, from the ego) are not annotated (tools/utils.py DIS_*_SAVE).
CAPTURE_RADIUS = 100.0
#: Mesh-path fragments that make a static prop a "static vehicle" box.
_STATIC_VEHICLE_MESHES = ("Car", "Truck", "Bus", "Motorcycle", "Bicycle")
#: Props annotated as traffic signs without a trigger volume.
_SIGN_PROPS = ("warning", "dirtdebris", "cone")


def _r(values: np.ndarray | Sequence[float]) -> list:
    """Nested Python floats (json cannot write numpy scalars)."""
    return np.asarray(values, dtype=np.float64).tolist()


LaneIds = tuple[int, int, int]
_NO_LANE: LaneIds = (-1, 0, -1)


def _waypoint_ids(world_map: Map, location: Location) -> LaneIds:
    """road_id, lane_id, section_id of the driving-lane waypoint nearest to a location."""
    wp = world_map.get_waypoint(location)
    if wp is None:
        return _NO_LANE
    return int(wp.road_id), int(wp.lane_id), int(wp.section_id)


def frame_lane_ids(world_map: Map, locations: Sequence[Location]) -> list[LaneIds]:
    """:func:`_waypoint_ids` of every location, in one map query where the map is a plain :class:`Map`."""
    # Map.lane_keys gives get_waypoint's lanes without building waypoints, one KD-tree query for the frame's dozens
    # of boxes instead of one each (~45 µs). Other maps (test stubs, subclasses with their own get_waypoint), and
    # non-finite locations, whose errors should stay get_waypoint's, take the one-by-one path.
    batch = isinstance(world_map, Map) and type(world_map).get_waypoint is Map.get_waypoint
    if not batch or not all(math.isfinite(v) for loc in locations for v in (loc.x, loc.y, loc.z)):
        return [_waypoint_ids(world_map, loc) for loc in locations]
    return [_NO_LANE if key is None else (int(key[0]), int(key[1]), int(key[2]))
            for key in world_map.lane_keys(locations)]  # fmt: skip


def _distance(a: Location, b: Location) -> float:
    return math.hypot(a.x - b.x, a.y - b.y)


def _color(actor: ActorState) -> str | None:
    return actor.attributes.get("color")


#: Width (m) of the slabs of :func:`xy_slabs`: a power of two, so that ``x / width`` is exact.
_SLAB_WIDTH = 4.0
_SLAB_LIMIT = np.iinfo(np.int16).max
#: Slack (m) around a box's reach when picking slabs: far more than any rounding of the tests it stands in for.
_SLAB_SLACK = 1e-3
#: Boxes from which indexing a sweep (~0.13 ms for 60k points) beats a pass over it per box (~0.03 ms more each).
_SLAB_MIN_BOXES = 5


def xy_slabs(points_ego: np.ndarray) -> np.ndarray:
    """(2, N) int16: each point's slab along ego x and along ego y (``floor(v / 4 m)``, clipped).

    A sweep's coarse index for num_points: a box then tests only the points of the slabs its reach spans (int16
    compares over the sweep instead of float arithmetic). A slab never decreases as its coordinate grows, so no
    point within reach is missed.
    """
    xy = np.asarray(points_ego)[:, :2].T
    with np.errstate(invalid="ignore"):  # NaN coordinates land in some slab: the exact test still refuses them
        return np.clip(np.floor(xy * (1.0 / _SLAB_WIDTH)), -_SLAB_LIMIT - 1, _SLAB_LIMIT).astype(np.int16)


def _slab_of(v: float) -> int:
    """:func:`xy_slabs`' slab of one (finite) coordinate, by the same float64 arithmetic."""
    return int(min(max(math.floor(v * (1.0 / _SLAB_WIDTH)), -_SLAB_LIMIT - 1), _SLAB_LIMIT))


def points_in_origin_box(
    points_ego: np.ndarray, world2ego: np.ndarray, location: Sequence[float], rel_yaw_deg: float,
    extent: Sequence[float], slabs: np.ndarray | None = None,
) -> int:  # fmt: skip
    """Bench2Drive's ``num_points`` rule: points strictly inside a box centred on the actor *origin*.

    ``location`` is the actor origin in the world, mapped into the ego frame by ``world2ego``; the box turns by
    the yaw relative to the ego and has the half ``extent``. The annotation and ``b2d-verify --deep`` both count
    with this function, from the same numbers the annotation stores, so a recount from a file is exact.
    ``slabs`` (:func:`xy_slabs` of the same points) only makes the count faster where many boxes share a sweep.
    """
    if len(points_ego) == 0:
        return 0
    m = np.asarray(world2ego, dtype=np.float64)
    rel = m[:3, :3] @ np.asarray(location, dtype=np.float64) + m[:3, 3]
    yaw = math.radians(rel_yaw_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    ex, ey, ez = (float(v) for v in extent)
    # Only points within the box's circumradius along ego x can be inside (the same test then runs on those):
    # one pass over the sweep per actor instead of a dozen.
    reach = math.hypot(ex, ey) * (1.0 + 1e-9) + 1e-9
    x0, y0 = float(rel[0]), float(rel[1])
    if slabs is not None and math.isfinite(x0) and math.isfinite(y0) and math.isfinite(reach):
        # Along x: the slabs of [x0 - reach, x0 + reach] widened by 1 mm, far more than the rounding of
        # |x - x0| <= reach, so every point that test accepts is among these rows (and it runs on them unchanged).
        # Along y: a point inside the turned box is within its circumradius of the centre, so |y - y0| < reach
        # too, up to roundings of ~1e-15 relative (c² + s² = 1 ± 2⁻⁵²); the same slack covers them.
        x_lo, x_hi = _slab_of(x0 - reach - _SLAB_SLACK), _slab_of(x0 + reach + _SLAB_SLACK)
        y_lo, y_hi = _slab_of(y0 - reach - _SLAB_SLACK), _slab_of(y0 + reach + _SLAB_SLACK)
        sx, sy = slabs[0], slabs[1]
        points_ego = points_ego[np.flatnonzero((sx >= x_lo) & (sx <= x_hi) & (sy >= y_lo) & (sy <= y_hi))]
    near = np.flatnonzero(np.abs(points_ego[:, 0] - rel[0]) <= reach)
    d = points_ego[near] - rel
    local_x = c * d[:, 0] + s * d[:, 1]
    local_y = -s * d[:, 0] + c * d[:, 1]
    inside = (np.abs(local_x) < ex) & (np.abs(local_y) < ey) & (np.abs(d[:, 2]) < ez)
    return int(np.count_nonzero(inside))


def count_points_in_box(
    points_ego: np.ndarray | None, ego: ActorState, actor: ActorState, *, world2ego: np.ndarray | None = None,
    slabs: np.ndarray | None = None,
) -> int:  # fmt: skip
    """LiDAR points strictly inside the actor's box as Bench2Drive counts them (−1 without LiDAR).

    The box is centred on the actor *origin* (not its bounding-box centre) in the ego frame, turned by the
    relative yaw, with the half extents — the released collector's rule, kept so counts are comparable. Pass the
    points as they are stored (:func:`b2d_data.codecs.laz.stored_points`), so the count is the file's.
    ``world2ego`` (the ego's inverse matrix) and ``slabs`` (:func:`xy_slabs`) may be passed once per frame.
    """
    if points_ego is None:
        return -1
    rel_yaw = float(actor.transform.rotation.yaw) - float(ego.transform.rotation.yaw)
    return points_in_origin_box(
        points_ego, ego.transform.inverse_matrix() if world2ego is None else world2ego, actor.location.to_list(),
        rel_yaw, actor.bounding_box.extent.to_list(), slabs,
    )  # fmt: skip


def anno_points_in_box(points_ego: np.ndarray, anno: Mapping, box: Mapping) -> int:
    """``num_points`` of an annotation box recounted from ego-frame points with the annotation's own fields."""
    ego = anno["bounding_boxes"][0]
    rel_yaw = float(box["rotation"][2]) - float(ego["rotation"][2])
    return points_in_origin_box(points_ego, np.asarray(ego["world2ego"]), box["location"], rel_yaw, box["extent"])


def _brake(actor: ActorState) -> float:
    control = actor.control
    return float(control.brake) if isinstance(control, VehicleControl) else 0.0


def _actor_values(world_map: Map, ego: ActorState, actor: ActorState, lane: LaneIds | None = None) -> dict:
    """Every field an actor-based box entry may hold; each class picks its keys in its own order.

    ``lane`` is the actor's :func:`_waypoint_ids` when already known (:func:`frame_lane_ids`).
    """
    bbox = actor.bounding_box
    road_id, lane_id, section_id = _waypoint_ids(world_map, actor.location) if lane is None else lane
    world2actor = _r(actor.transform.inverse_matrix())
    return {
        "id": str(actor.id),
        "type_id": actor.type_id,
        "base_type": actor.base_type,
        "location": actor.location.to_list(),
        "rotation": actor.transform.rotation.to_anno(),
        "bbx_loc": bbox.location.to_list(),
        "center": actor.transform.transform_point(bbox.location).to_list(),
        "extent": bbox.extent.to_list(),
        "world_cord": _r(bbox.world_corners(actor.transform)),
        "semantic_tags": list(actor.semantic_tags),
        "color": _color(actor),
        "distance": _distance(actor.location, ego.location),
        "speed": float(actor.forward_speed()),
        "brake": _brake(actor),
        "light_state": carla_str(actor.light_state),
        "road_id": road_id,
        "lane_id": lane_id,
        "section_id": section_id,
        "world2ego": world2actor,
        "world2vehicle": world2actor,
        "world2ped": world2actor,
        "world2sign": world2actor,
    }


def _ordered(keys: Sequence[str], values: Mapping) -> dict:
    """Project ``values`` onto a schema key order (format/anno_schema.py)."""
    return {key: values[key] for key in keys}


def ego_box(world_map: Map, ego: ActorState, lane: LaneIds | None = None) -> dict:
    """The ``ego_vehicle`` entry (always first)."""
    values = _actor_values(world_map, ego, ego, lane)
    # Bench2Drive wraps the ego's tag list in one more list.
    values.update({"class": "ego_vehicle", "semantic_tags": [list(ego.semantic_tags)]})
    return _ordered(EGO_KEYS, values)


def _counted_values(
    world_map: Map, ego: ActorState, actor: ActorState, points_ego: np.ndarray | None, lane: LaneIds | None,
    num_points: int | None,
) -> dict:
    """:func:`_actor_values` and the sweep's points in the actor's box (counted here unless given)."""
    values = _actor_values(world_map, ego, actor, lane)
    values["num_points"] = count_points_in_box(points_ego, ego, actor) if num_points is None else num_points
    return values


def vehicle_box(
    world_map: Map, ego: ActorState, actor: ActorState, points_ego: np.ndarray | None, lane: LaneIds | None = None,
    num_points: int | None = None,
) -> dict:
    """A ``vehicle`` entry with state ``dynamic``."""
    values = _counted_values(world_map, ego, actor, points_ego, lane, num_points)
    values.update({"class": "vehicle", "state": "dynamic"})
    return _ordered(DYNAMIC_VEHICLE_KEYS, values)


def static_vehicle_box(
    world_map: Map, ego: ActorState, actor: ActorState, points_ego: np.ndarray | None, lane: LaneIds | None = None,
    num_points: int | None = None,
) -> dict:
    """A ``vehicle`` entry with state ``static`` (parked-car props)."""
    values = _counted_values(world_map, ego, actor, points_ego, lane, num_points)
    values.update({"class": "vehicle", "state": "static", "brake": 1.0, "light_state": "NONE"})
    return _ordered(STATIC_VEHICLE_KEYS, values)


def _bone_segments(actor: ActorState) -> list:
    """A stick skeleton scaled to the walker's box (the builtin walkers have no skinned skeleton)."""
    h = 2.0 * actor.bounding_box.extent.z
    base = actor.bounding_box.location.z - actor.bounding_box.extent.z
    w = min(actor.bounding_box.extent.y, 0.25)
    joints = {
        "head": (0.0, 0.0, base + 0.93 * h), "neck": (0.0, 0.0, base + 0.82 * h),
        "pelvis": (0.0, 0.0, base + 0.52 * h), "l_hand": (0.0, -w, base + 0.50 * h),
        "r_hand": (0.0, w, base + 0.50 * h), "l_foot": (0.0, -0.6 * w, base), "r_foot": (0.0, 0.6 * w, base),
    }  # fmt: skip
    pairs = (("head", "neck"), ("neck", "pelvis"), ("neck", "l_hand"), ("neck", "r_hand"),
             ("pelvis", "l_foot"), ("pelvis", "r_foot"))  # fmt: skip
    local = np.array([[joints[a], joints[b]] for a, b in pairs], dtype=np.float64).reshape(-1, 3)
    return _r(actor.transform.transform_points(local).reshape(-1, 2, 3))


def walker_box(
    world_map: Map, ego: ActorState, actor: ActorState, points_ego: np.ndarray | None, lane: LaneIds | None = None,
    num_points: int | None = None,
) -> dict:
    """A ``walker`` entry."""
    values = _counted_values(world_map, ego, actor, points_ego, lane, num_points)
    values.update({
        "class": "walker", "gender": actor.attributes.get("gender", "male"),
        "age": actor.attributes.get("age", "adult"), "bone": _bone_segments(actor),
    })  # fmt: skip
    return _ordered(WALKER_KEYS, values)


def _trigger_fields(transform: Transform, trigger: BoundingBox, level: BoundingBox) -> dict:
    """World trigger-volume location, level-bbox-relative rotation sum (mod 360) and half extents."""
    rot = [(a + b) % 360.0 for a, b in zip(level.rotation.to_anno(), trigger.rotation.to_anno())]
    return {
        "trigger_volume_location": transform.transform_point(trigger.location).to_list(),
        "trigger_volume_rotation": rot,
        "trigger_volume_extent": trigger.extent.to_list(),
    }


def traffic_light_box(
    world_map: Map, ego: ActorState, light: TrafficLightInfo, actor: ActorState | None, affects_ego: bool,
    lane: LaneIds | None = None,
) -> dict:  # fmt: skip
    """A ``traffic_light`` entry; pose fields come from the light's level bounding box."""
    level = light.level_bbox
    road_id, lane_id, section_id = _waypoint_ids(world_map, level.location) if lane is None else lane
    trigger = _trigger_fields(light.transform, light.trigger_volume, level)
    return {
        "class": "traffic_light",
        "id": str(light.id),
        "location": level.location.to_list(),
        "rotation": level.rotation.to_anno(),
        "center": level.location.to_list(),
        "extent": level.extent.to_list(),
        "semantic_tags": list(actor.semantic_tags) if actor else [7],
        "type_id": actor.type_id if actor else "traffic.traffic_light",
        "distance": _distance(level.location, ego.location),
        "state": int(light.state),
        "affects_ego": bool(affects_ego),
        **trigger,
        "road_id": road_id,
        "lane_id": lane_id,
        "section_id": section_id,
    }


def trigger_sign_box(
    world_map: Map, ego: ActorState, sign: TrafficSignInfo, actor: ActorState | None, affects_ego: bool,
    lane: LaneIds | None = None,
) -> dict:  # fmt: skip
    """A ``traffic_sign`` entry with a trigger volume (stop, yield, speed limit)."""
    level = sign.level_bbox
    road_id, lane_id, section_id = _waypoint_ids(world_map, level.location) if lane is None else lane
    trigger = _trigger_fields(sign.transform, sign.trigger_volume, level)
    return {
        "class": "traffic_sign",
        "id": str(sign.id),
        "location": level.location.to_list(),
        "rotation": level.rotation.to_anno(),
        "center": level.location.to_list(),
        "extent": level.extent.to_list(),
        "semantic_tags": list(actor.semantic_tags) if actor else [8],
        "type_id": sign.type_id,
        "distance": _distance(level.location, ego.location),
        "affects_ego": bool(affects_ego),
        **trigger,
        "road_id": road_id,
        "lane_id": lane_id,
        "section_id": section_id,
        "world2sign": _r(sign.transform.inverse_matrix()),
    }


def prop_sign_box(
    world_map: Map, ego: ActorState, actor: ActorState, affects_ego: bool, lane: LaneIds | None = None
) -> dict:
    """A ``traffic_sign`` entry without trigger volume (warning boards, cones, dirt debris)."""
    values = _actor_values(world_map, ego, actor, lane)
    values.update({"class": "traffic_sign", "affects_ego": bool(affects_ego)})
    return _ordered(PROP_SIGN_KEYS, values)


def is_static_vehicle(actor: ActorState) -> bool:
    """A parked-car mesh prop (annotated as a static vehicle)."""
    return actor.kind is ActorKind.PROP and any(m in actor.type_id for m in _STATIC_VEHICLE_MESHES)


def is_sign_prop(actor: ActorState) -> bool:
    """A prop annotated as a traffic sign without trigger volume."""
    return actor.kind is ActorKind.PROP and any(p in actor.type_id for p in _SIGN_PROPS)


def _ahead(ego: ActorState, location: Location) -> bool:
    fwd = ego.transform.get_forward_vector()
    return (location.x - ego.location.x) * fwd.x + (location.y - ego.location.y) * fwd.y > 0.0


def _trigger_hits_route(transform: Transform, trigger: BoundingBox, route_ahead: np.ndarray) -> bool:
    """Whether one of the upcoming route points lies inside the trigger volume enlarged 1.5×."""
    if len(route_ahead) == 0:
        return False
    centre = transform.transform_point(trigger.location)
    yaw = math.radians(transform.rotation.yaw + trigger.rotation.yaw)
    c, s = math.cos(yaw), math.sin(yaw)
    dx = route_ahead[:, 0] - centre.x
    dy = route_ahead[:, 1] - centre.y
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    ex, ey = 1.5 * max(trigger.extent.x, 0.5), 1.5 * max(trigger.extent.y, 0.5)
    return bool(np.any((np.abs(lx) <= ex) & (np.abs(ly) <= ey)))


def most_affecting(
    ego: ActorState, candidates: Sequence[tuple[int, Transform, BoundingBox]], route_ahead: np.ndarray
) -> int | None:
    """Id of the closest light/sign ahead whose trigger volume covers one of the next route points."""
    best: tuple[float, int] | None = None
    for actor_id, transform, trigger in candidates:
        centre = transform.transform_point(trigger.location)
        if not _ahead(ego, centre) or not _trigger_hits_route(transform, trigger, route_ahead):
            continue
        d = _distance(centre, ego.location)
        if best is None or d < best[0]:
            best = (d, actor_id)
    return None if best is None else best[1]


def nearest_prop_ahead(
    ego: ActorState, props: Sequence[ActorState], route_ahead: np.ndarray, lane_half_width: float = 3.5
) -> int | None:
    """The nearest sign prop ahead that stands within ``lane_half_width`` of the upcoming route."""
    best: tuple[float, int] | None = None
    for prop in props:
        if not _ahead(ego, prop.location) or len(route_ahead) == 0:
            continue
        gap = np.min(np.hypot(route_ahead[:, 0] - prop.location.x, route_ahead[:, 1] - prop.location.y))
        if gap > lane_half_width:
            continue
        d = _distance(prop.location, ego.location)
        if best is None or d < best[0]:
            best = (d, prop.id)
    return None if best is None else best[1]


def bounding_boxes(
    world_map: Map,
    snapshot: Snapshot,
    ego: ActorState,
    points_ego: np.ndarray | None,
    route_ahead: np.ndarray,
    radius: float = CAPTURE_RADIUS,
) -> list[dict]:
    """All box entries of a frame, in Bench2Drive's order: ego, vehicles, static vehicles, walkers, lights, signs."""
    near = [
        a for a in snapshot.actors.values()
        if a.id != ego.id and a.parent_id is None and _distance(a.location, ego.location) <= radius
    ]  # fmt: skip
    vehicles = [a for a in near if a.kind is ActorKind.VEHICLE]
    statics = [a for a in near if is_static_vehicle(a)]
    walkers = [a for a in near if a.kind is ActorKind.WALKER]
    sign_props = [a for a in near if is_sign_prop(a) and not is_static_vehicle(a)]
    lights = [t for t in snapshot.traffic_lights.values() if _distance(t.level_bbox.location, ego.location) <= radius]
    signs = [s for s in snapshot.traffic_signs.values() if _distance(s.level_bbox.location, ego.location) <= radius]

    light_hit = most_affecting(ego, [(t.id, t.transform, t.trigger_volume) for t in lights], route_ahead)
    sign_hit = most_affecting(ego, [(s.id, s.transform, s.trigger_volume) for s in signs], route_ahead)
    prop_hit = nearest_prop_ahead(ego, sign_props, route_ahead)

    vehicles.sort(key=lambda a: a.id)
    statics.sort(key=lambda a: a.id)
    walkers.sort(key=lambda a: a.id)
    lights.sort(key=lambda t: t.id)
    signs.sort(key=lambda s: s.id)
    sign_props.sort(key=lambda a: a.id)
    # Every box's lane in one query, in the order the boxes are built below.
    located = [ego, *vehicles, *statics, *walkers]
    lanes = iter(frame_lane_ids(
        world_map,
        [a.location for a in located] + [t.level_bbox.location for t in lights]
        + [s.level_bbox.location for s in signs] + [a.location for a in sign_props],
    ))  # fmt: skip

    # num_points of every box against one ego matrix and one slab index of the sweep.
    counted = [*vehicles, *statics, *walkers]
    if points_ego is not None and len(points_ego) and len(counted) >= _SLAB_MIN_BOXES:
        world2ego, slabs = ego.transform.inverse_matrix(), xy_slabs(points_ego)
        counts = iter([count_points_in_box(points_ego, ego, a, world2ego=world2ego, slabs=slabs) for a in counted])
    else:
        counts = iter([count_points_in_box(points_ego, ego, a) for a in counted])

    boxes = [ego_box(world_map, ego, next(lanes))]
    boxes += [vehicle_box(world_map, ego, a, points_ego, next(lanes), next(counts)) for a in vehicles]
    boxes += [static_vehicle_box(world_map, ego, a, points_ego, next(lanes), next(counts)) for a in statics]
    boxes += [walker_box(world_map, ego, a, points_ego, next(lanes), next(counts)) for a in walkers]
    actors = snapshot.actors
    boxes += [traffic_light_box(world_map, ego, t, actors.get(t.id), t.id == light_hit, next(lanes)) for t in lights]
    boxes += [trigger_sign_box(world_map, ego, s, actors.get(s.id), s.id == sign_hit, next(lanes)) for s in signs]
    boxes += [prop_sign_box(world_map, ego, a, a.id == prop_hit, next(lanes)) for a in sign_props]
    return boxes


@lru_cache(maxsize=256)
def _mount_rows(mount: Mount) -> tuple[tuple[float, ...], ...]:
    """``_r(mount.matrix())``, frozen: a rig's mounts do not change, so each matrix is built once."""
    return tuple(map(tuple, _r(mount.matrix())))


@lru_cache(maxsize=256)
def _intrinsic_rows(spec: CameraSpec, width: int, height: int) -> tuple[tuple[float, ...], ...]:
    """``_r(spec.intrinsic(width, height))``, frozen (constant for a rig and an image size)."""
    return tuple(map(tuple, _r(spec.intrinsic(width, height))))


def _rows(frozen: tuple[tuple[float, ...], ...]) -> list[list[float]]:
    """Fresh nested lists (each annotation owns its lists) of a cached matrix."""
    return [list(row) for row in frozen]


def _camera_entry(spec: CameraSpec, world: Transform, width: int, height: int) -> dict:
    return {
        "location": world.location.to_list(),
        "rotation": world.rotation.to_anno(),
        "intrinsic": _rows(_intrinsic_rows(spec, width, height)),
        "world2cam": _r(world.inverse_matrix()),
        "cam2ego": _rows(_mount_rows(spec.mount)),
        "fov": float(spec.fov),
        "image_size_x": int(width),
        "image_size_y": int(height),
    }


def sensor_calibrations(
    ego: ActorState, config: RigConfig, sensor_transforms: Mapping[str, Transform] | None = None
) -> dict:
    """The ``sensors`` dict: every camera (incl. TOP_DOWN), radar and the LiDAR, in Bench2Drive's order.

    World poses come from the sensors' reported transforms when given, else from the ego pose and the mount.
    """
    poses = dict(sensor_transforms or {})
    ego_matrix: list[np.ndarray] = []  # built once, on the first sensor without a reported pose

    def world_pose(sensor_id: str, mount: Mount) -> Transform:
        if sensor_id in poses:
            return poses[sensor_id]
        if not ego_matrix:
            ego_matrix.append(ego.transform.matrix())
        return Transform.from_matrix(ego_matrix[0] @ mount.matrix())

    out: dict[str, dict] = {}
    for spec in ALL_CAMERAS:
        w, h = (
            (config.top_down_width, config.top_down_height)
            if spec.sensor_id == "TOP_DOWN"
            else (config.width, config.height)
        )
        out[spec.sensor_id] = _camera_entry(spec, world_pose(spec.sensor_id, spec.mount), w, h)
    for radar in RADARS_V004 if config.radar_v004_mounts else RADARS_V0:
        pose = world_pose(radar.sensor_id, radar.mount)
        out[radar.sensor_id] = {
            "location": pose.location.to_list(),
            "rotation": pose.rotation.to_anno(),
            "world2radar": _r(pose.inverse_matrix()),
            "radar2ego": _rows(_mount_rows(radar.mount)),
        }
    pose = world_pose(LIDAR.sensor_id, LIDAR.mount)
    out[LIDAR.sensor_id] = {
        "location": pose.location.to_list(),
        "rotation": pose.rotation.to_anno(),
        "world2lidar": _r(pose.inverse_matrix()),
        "lidar2ego": _rows(_mount_rows(LIDAR.mount)),
    }
    return out


@dataclass(frozen=True)
class PlannerFields:
    """Route-derived fields of the top level (see route_planners.py)."""

    x_command_far: float
    y_command_far: float
    command_far: int
    x_command_near: float
    y_command_near: float
    command_near: int
    x_target: float
    y_target: float
    next_command: int


def build_annotation(
    world_map: Map,
    snapshot: Snapshot,
    ego: ActorState,
    sensors: SensorData,
    config: RigConfig,
    plan: PlannerFields,
    gnss_xy: tuple[float, float],
    should_brake: bool,
    only_ap_brake: bool,
    route_ahead: np.ndarray,
) -> dict:
    """The complete annotation dict of one frame, keys in Bench2Drive's order."""
    control = ego.control if isinstance(ego.control, VehicleControl) else VehicleControl()
    imu = sensors.imu
    # Counted on the sweep as the LAZ file will hold it: 1 mm steps move points lying on a box face across it.
    points = stored_points(sensors.lidar) if config.lidar else None
    return {
        "x": float(gnss_xy[0]),
        "y": float(gnss_xy[1]),
        "throttle": float(control.throttle),
        "steer": float(control.steer),
        "brake": float(control.brake),
        "reverse": bool(control.reverse),
        "theta": float(imu.compass),
        "speed": float(sensors.speed),
        "x_command_far": plan.x_command_far,
        "y_command_far": plan.y_command_far,
        "command_far": plan.command_far,
        "x_command_near": plan.x_command_near,
        "y_command_near": plan.y_command_near,
        "command_near": plan.command_near,
        "should_brake": bool(should_brake),
        "x_target": plan.x_target,
        "y_target": plan.y_target,
        "next_command": plan.next_command,
        "weather": snapshot.weather.to_anno(),
        "acceleration": [float(v) for v in imu.accelerometer],
        "angular_velocity": [float(v) for v in imu.gyroscope],
        "bounding_boxes": bounding_boxes(world_map, snapshot, ego, points, route_ahead),
        "sensors": sensor_calibrations(ego, config, sensors.sensor_transforms),
        "only_ap_brake": bool(only_ap_brake),
    }
