"""A still scene at a place of a town, for previews: the ego, a few placed vehicles and walkers, lights and signs.

Nothing is simulated: :func:`town_snapshot` builds a :class:`~b2d_data.sim.api.Snapshot` directly from the map
(vehicles on the lanes around the ego, walkers on nearby sidewalks, the town's traffic lights and signs), so that
the sensor suite can render a town without running a simulator.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorState, Snapshot, TrafficLightInfo, TrafficLightState, TrafficSignInfo
from b2d_data.sim.builtin.sensors.synthetic import actor_state, snapshot_of

log = logging.getLogger(__name__)

EGO_ID = 1
_CARS = (
    "vehicle.tesla.model3", "vehicle.audi.a2", "vehicle.nissan.patrol", "vehicle.mercedes.coupe_2020",
    "vehicle.toyota.prius", "vehicle.citroen.c3", "vehicle.dodge.charger_2020", "vehicle.mini.cooper_s_2021",
    "vehicle.volkswagen.t2", "vehicle.carlamotors.carlacola", "vehicle.ford.crown", "vehicle.jeep.wrangler_rubicon",
)  # fmt: skip
_WALKERS = tuple(f"walker.pedestrian.{n:04d}" for n in (1, 2, 5, 7, 15, 16, 19, 26, 30, 34))


def _default_place(town) -> Transform:
    """A spawn point 20–45 m before a junction, preferring the one nearest the middle of the town."""
    points = town.get_spawn_points()
    if not points:
        raise ValueError(f"{town.name}: no spawn points to place the ego on")
    centres = [j.bounding_box.location.to_array()[:2] for j in getattr(town, "junctions", {}).values()]
    mid = np.mean([p.location.to_array()[:2] for p in points], axis=0)
    best, best_score = points[0], math.inf
    for p in points:
        loc = p.location.to_array()[:2]
        fwd = np.array([math.cos(math.radians(p.rotation.yaw)), math.sin(math.radians(p.rotation.yaw))])
        ahead = [float((c - loc) @ fwd) for c in centres if np.linalg.norm(c - loc) < 60.0]
        approaching = any(20.0 <= a <= 45.0 for a in ahead)
        score = np.linalg.norm(loc - mid) + (0.0 if approaching else 1000.0)
        if score < best_score:
            best, best_score = p, score
    return best


def _ground(wp) -> Transform:
    loc = wp.transform.location
    return Transform(Location(loc.x, loc.y, loc.z), Rotation(yaw=wp.transform.rotation.yaw))


def _lights_and_signs(town, rng: np.random.Generator) -> tuple[dict[int, TrafficLightInfo], dict[int, TrafficSignInfo]]:
    """The town's traffic lights (random red/green) and signs, as the builtin world would create them."""
    try:
        from b2d_data.sim.builtin.furniture import furniture_from_map
        from b2d_data.sim.builtin.traffic_lights import sign_info
    except ImportError as exc:
        log.warning("no traffic furniture: %s", exc)
        return {}, {}
    lights_spec, signs_spec = furniture_from_map(town)
    lights: dict[int, TrafficLightInfo] = {}
    signs: dict[int, TrafficSignInfo] = {}
    next_id = 1000
    for spec in lights_spec:
        state = TrafficLightState.GREEN if rng.random() < 0.5 else TrafficLightState.RED
        lights[next_id] = TrafficLightInfo(
            id=next_id, transform=spec.transform, state=state, trigger_volume=spec.trigger_volume,
            stop_waypoints=spec.stop_waypoints, affected_lane_waypoints=spec.affected_lane_waypoints,
            group_id=int(spec.group_key), opendrive_id=spec.opendrive_id, level_bbox=spec.level_bbox,
            level_bbox_transform=spec.level_bbox_transform, pole_base=spec.pole_base,
        )  # fmt: skip
        next_id += 1
    for spec in signs_spec:
        signs[next_id] = sign_info(next_id, spec)
        next_id += 1
    return lights, signs


def town_snapshot(
    town,
    place: Location | Transform | None,
    weather: WeatherParameters,
    seed: int = 0,
    vehicles: int = 10,
    walkers: int = 6,
) -> tuple[Snapshot, int]:
    """A snapshot with the ego at ``place`` (snapped to the nearest driving lane) and a few actors around it.

    Returns the snapshot and the ego id.
    """
    from b2d_data.maps import LaneType

    rng = np.random.default_rng([seed, 31337])
    if place is None:
        place = _default_place(town)
    loc = place.location if isinstance(place, Transform) else place
    ego_wp = town.get_waypoint(loc, project_to_road=True, lane_type=LaneType.DRIVING)
    if ego_wp is None:
        raise ValueError(f"{town.name}: no driving lane near {loc}")
    ego_pose = place if isinstance(place, Transform) else _ground(ego_wp)
    if isinstance(place, Transform):
        ego_pose = Transform(Location(place.location.x, place.location.y, ego_wp.transform.location.z), place.rotation)
    actors: list[ActorState] = [
        actor_state(EGO_ID, "vehicle.lincoln.mkz_2020", ego_pose.location.x, ego_pose.location.y,
                    ego_pose.rotation.yaw, ego_pose.location.z, role_name="hero")
    ]  # fmt: skip
    taken: list[np.ndarray] = [ego_pose.location.to_array()]

    def free(p: np.ndarray, clearance: float) -> bool:
        return all(np.linalg.norm(p[:2] - q[:2]) > clearance for q in taken)

    # Candidate lane poses: ahead and behind on the ego lane and its neighbours (both directions).
    lanes = [ego_wp]
    for getter in ("get_left_lane", "get_right_lane"):
        w = getattr(ego_wp, getter)()
        hops = 0
        while w is not None and hops < 3:
            if w.lane_type & LaneType.DRIVING:
                lanes.append(w)
            w = getattr(w, getter)() if w.lane_id * ego_wp.lane_id > 0 else None
            hops += 1
    candidates = []
    for lane in lanes:
        for d in (9.0, 17.0, 26.0, 36.0, 48.0):
            candidates += lane.next(d)[:1]
            candidates += lane.previous(d)[:1] if lane is not ego_wp or d > 12.0 else []
    order = rng.permutation(len(candidates))
    next_id = EGO_ID + 1
    for k in order:
        if next_id - EGO_ID > vehicles:
            break
        wp = candidates[k]
        pose = _ground(wp)
        p = pose.location.to_array()
        if not free(p, 7.0):
            continue
        type_id = _CARS[int(rng.integers(len(_CARS)))]
        paint = blueprints.random_color(blueprints.find(type_id), rng)
        attrs = {"color": paint} if paint else None
        actors.append(actor_state(next_id, type_id, p[0], p[1], pose.rotation.yaw, p[2], attributes=attrs))
        taken.append(p)
        next_id += 1
    # Walkers on the sidewalks near the ego.
    placed = 0
    for _ in range(walkers * 6):
        if placed >= walkers:
            break
        offset = rng.uniform(-30.0, 30.0, size=2)
        probe = Location(ego_pose.location.x + offset[0], ego_pose.location.y + offset[1], ego_pose.location.z)
        wp = town.get_waypoint(probe, project_to_road=True, lane_type=LaneType.SIDEWALK)
        if wp is None:
            continue
        p = wp.transform.location.to_array()
        if np.linalg.norm(p[:2] - taken[0][:2]) > 40.0 or not free(p, 1.5):
            continue
        yaw = wp.transform.rotation.yaw + (180.0 if rng.random() < 0.5 else 0.0)
        type_id = _WALKERS[int(rng.integers(len(_WALKERS)))]
        speed = 1.3
        vel = (speed * math.cos(math.radians(yaw)), speed * math.sin(math.radians(yaw)), 0.0)
        actors.append(actor_state(next_id, type_id, p[0], p[1], yaw, p[2] + 0.15, velocity=vel))
        taken.append(p)
        next_id += 1
        placed += 1
    lights, signs = _lights_and_signs(town, rng)
    return snapshot_of(actors, weather, traffic_lights=lights, traffic_signs=signs), EGO_ID
