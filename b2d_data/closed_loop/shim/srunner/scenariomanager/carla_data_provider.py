"""``srunner.scenariomanager.carla_data_provider.CarlaDataProvider`` backed by the running route.

scenario_runner's provider caches the world, the map and per-actor velocity/location/transform, refreshed on each
tick; here every read goes to the route's last snapshot, which is the same thing in a synchronous world. Calls that
would spawn, remove or tick are refused (the evaluator owns the world). ``get_b2d_route()`` is a b2d-data extension
that hands privileged agents (such as our expert) the running :class:`~b2d_data.closed_loop.bridge.RouteBridge`.
"""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING, Any

import carla
from carla._world import EVALUATOR_OWNS_WORLD

from b2d_data.closed_loop import bridge as _bridge
from b2d_data.sim.api import ActorKind

if TYPE_CHECKING:
    from agents.navigation.global_route_planner import GlobalRoutePlanner

log = logging.getLogger(__name__)

#: The kinds of actor scenario_runner keeps in its actor pool (it spawned them); lights and signs belong to the map.
_POOL_KINDS = (ActorKind.VEHICLE, ActorKind.WALKER, ActorKind.PROP)


def _refused(name: str) -> RuntimeError:
    return RuntimeError(
        f"CarlaDataProvider.{name}() is not available in b2d-data's closed-loop evaluation: {EVALUATOR_OWNS_WORLD}"
    )


def calculate_velocity(actor: Any) -> float:
    """Horizontal speed (m/s) of an actor: the norm of the velocity's x and y, as scenario_runner computes it."""
    velocity = actor.get_velocity()
    return math.sqrt(velocity.x**2 + velocity.y**2)


class CarlaDataProvider:
    """Frequently used world data (static methods, as scenario_runner's), read live from the running route."""

    _traffic_manager_port = 8000
    _random_seed = 2000
    _latlon_cache: tuple[Any, tuple[float, float]] | None = None

    # -- world, client, map -----------------------------------------------------------------------------------------
    @staticmethod
    def get_world() -> carla.World:
        """The running world."""
        _bridge.current()
        return carla.World()

    @staticmethod
    def get_client() -> carla.Client:
        """A client whose ``get_world()`` is the running world."""
        return carla.Client()

    @staticmethod
    def get_map(world: Any = None) -> carla.Map:
        """The running town."""
        return CarlaDataProvider.get_world().get_map()

    @staticmethod
    def is_sync_mode() -> bool:
        """Always True: the evaluator runs the world synchronously at 20 Hz."""
        return True

    @staticmethod
    def is_runtime_init_mode() -> bool:
        """Always False."""
        return False

    @staticmethod
    def get_traffic_manager_port() -> int:
        """The Leaderboard's default port (no traffic manager runs)."""
        return CarlaDataProvider._traffic_manager_port

    @staticmethod
    def set_traffic_manager_port(tm_port: int) -> None:
        """Remembered and otherwise ignored."""
        CarlaDataProvider._traffic_manager_port = int(tm_port)

    @staticmethod
    def get_random_seed() -> int:
        """scenario_runner's default seed."""
        return CarlaDataProvider._random_seed

    @staticmethod
    def set_client(client: Any) -> None:
        """Accepted and ignored (the evaluator owns the connection)."""
        return

    @staticmethod
    def set_world(world: Any) -> None:
        """Accepted and ignored (the evaluator owns the world)."""
        return

    # -- actors -----------------------------------------------------------------------------------------------------
    @staticmethod
    def register_actor(actor: Any, transform: Any = None) -> None:
        """Accepted and ignored: every actor is read live from the world."""
        return

    @staticmethod
    def register_actors(actors: Any, transforms: Any = None) -> None:
        """Accepted and ignored."""
        return

    @staticmethod
    def on_carla_tick() -> None:
        """Accepted and ignored: the evaluator ticks the world."""
        return

    @staticmethod
    def get_actors() -> list[tuple[int, carla.Actor]]:
        """(id, actor) of the vehicles, walkers and props (scenario_runner's actor pool: the ego included)."""
        snapshot = _bridge.current().snapshot
        world = CarlaDataProvider.get_world()
        out = []
        for actor_id, state in snapshot.actors.items():
            if state.kind in _POOL_KINDS:
                out.append((actor_id, world.get_actor(actor_id)))
        return out

    @staticmethod
    def get_all_actors() -> carla.ActorList:
        """Every actor of the world (lights and signs included)."""
        return CarlaDataProvider.get_world().get_actors()

    @staticmethod
    def actor_id_exists(actor_id: int) -> bool:
        """Whether the pool holds this id."""
        state = _bridge.current().snapshot.actors.get(actor_id)
        return state is not None and state.kind in _POOL_KINDS

    @staticmethod
    def get_actor_by_id(actor_id: int) -> carla.Actor | None:
        """The pooled actor with this id, or None (logged, as scenario_runner prints it)."""
        if CarlaDataProvider.actor_id_exists(actor_id):
            return CarlaDataProvider.get_world().get_actor(actor_id)
        log.warning("Non-existing actor id %s", actor_id)
        return None

    @staticmethod
    def get_actor_by_name(role_name: str) -> carla.Actor | None:
        """The first pooled actor whose ``role_name`` is this, or None."""
        for _, actor in CarlaDataProvider.get_actors():
            if actor.attributes.get("role_name") == role_name:
                return actor
        return None

    @staticmethod
    def get_hero_actor() -> carla.Actor | None:
        """The ego vehicle (``role_name == 'hero'``)."""
        return CarlaDataProvider.get_world().get_actor(_bridge.current().ego_id)

    @staticmethod
    def get_velocity(actor: Any) -> float:
        """Horizontal speed (m/s) after the last tick; 0.0 (logged) for an actor the world does not have."""
        try:
            return calculate_velocity(actor)
        except RuntimeError:
            log.warning("%s.get_velocity: %s not found!", __name__, actor)
            return 0.0

    @staticmethod
    def get_location(actor: Any) -> carla.Location | None:
        """World location after the last tick; None (logged) for an actor the world does not have."""
        try:
            return actor.get_location()
        except RuntimeError:
            log.warning("%s.get_location: %s not found!", __name__, actor)
            return None

    @staticmethod
    def get_transform(actor: Any) -> carla.Transform | None:
        """World transform after the last tick; None (logged) for an actor the world does not have."""
        try:
            return actor.get_transform()
        except RuntimeError:
            log.warning("%s.get_transform: %s not found!", __name__, actor)
            return None

    # -- traffic lights ---------------------------------------------------------------------------------------------
    @staticmethod
    def get_trafficlight_trigger_location(traffic_light: Any) -> carla.Location:
        """World location of the centre of a light's trigger volume (at the volume centre's height)."""
        base = traffic_light.get_transform()
        centre = base.transform(traffic_light.trigger_volume.location)
        return carla.Location(centre.x, centre.y, centre.z)

    @staticmethod
    def get_next_traffic_light(actor: Any, use_cached_location: bool = True) -> carla.TrafficLight | None:
        """The light whose trigger volume is nearest the last lane waypoint before the actor's next junction.

        None when the actor already is in a junction (scenario_runner's rule).
        """
        location = actor.get_location()
        wmap = CarlaDataProvider.get_map()
        waypoint = wmap.get_waypoint(location)
        waypoints = []
        while waypoint is not None and not waypoint.is_junction and len(waypoints) < 10000:
            waypoints.append(waypoint)
            following = waypoint.next(2.0)
            waypoint = following[0] if following else None
        if not waypoints:
            return None
        end = waypoints[-1].transform.location
        best, best_distance = None, float("inf")
        for light in CarlaDataProvider.get_world().get_actors().filter("*traffic_light*"):
            distance = CarlaDataProvider.get_trafficlight_trigger_location(light).distance(end)
            if distance < best_distance:
                best, best_distance = light, distance
        return best

    # -- route ------------------------------------------------------------------------------------------------------
    @staticmethod
    def get_ego_vehicle_route() -> list[tuple[carla.Location, Any]] | None:
        """The ego's dense route as (carla.Location, RoadOption) pairs, or None when the route is unknown."""
        route = _bridge.current().route
        if route is None:
            return None
        return [(carla.Location(w.transform.location.x, w.transform.location.y, w.transform.location.z), command)
                for w, command in zip(route.waypoints, route.commands)]  # fmt: skip

    @staticmethod
    def set_ego_vehicle_route(route: Any) -> None:
        """Accepted and ignored (the evaluator sets the route)."""
        return

    @staticmethod
    def get_latlon_ref() -> tuple[float, float]:
        """The town's geo reference (lat_0, lon_0), parsed as the Leaderboard does (default 42.0, 2.0)."""
        from leaderboard.utils.route_manipulation import _get_latlon_ref

        b2d_map = _bridge.current().map
        cache = CarlaDataProvider._latlon_cache
        if cache is None or cache[0] is not b2d_map:
            CarlaDataProvider._latlon_cache = cache = (b2d_map, _get_latlon_ref(CarlaDataProvider.get_world()))
        return cache[1]

    @staticmethod
    def get_global_route_planner() -> GlobalRoutePlanner:
        """A route planner on the running town at 1 m."""
        from agents.navigation.global_route_planner import GlobalRoutePlanner

        return GlobalRoutePlanner(CarlaDataProvider.get_map(), 1.0)

    @staticmethod
    def get_b2d_route() -> _bridge.RouteBridge:
        """b2d-data extension: the running route (simulator, map, ego id, snapshot, dense route, scenario hints)."""
        return _bridge.current()

    # -- refused ----------------------------------------------------------------------------------------------------
    @staticmethod
    def request_new_actor(*args: Any, **kwargs: Any) -> Any:
        """Refused: the evaluator owns the world."""
        raise _refused("request_new_actor")

    @staticmethod
    def request_new_actors(*args: Any, **kwargs: Any) -> Any:
        """Refused: the evaluator owns the world."""
        raise _refused("request_new_actors")

    @staticmethod
    def request_new_batch_actors(*args: Any, **kwargs: Any) -> Any:
        """Refused: the evaluator owns the world."""
        raise _refused("request_new_batch_actors")

    @staticmethod
    def remove_actor_by_id(*args: Any, **kwargs: Any) -> Any:
        """Refused: the evaluator owns the world."""
        raise _refused("remove_actor_by_id")

    @staticmethod
    def remove_actors_in_surrounding(*args: Any, **kwargs: Any) -> Any:
        """Refused: the evaluator owns the world."""
        raise _refused("remove_actors_in_surrounding")

    @staticmethod
    def cleanup() -> None:
        """Forget cached values (nothing is destroyed: the evaluator cleans the world up)."""
        CarlaDataProvider._latlon_cache = None
