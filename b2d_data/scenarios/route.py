"""The leaderboard's dense route: the route XML keypoints densified to 1 m, as arrays the criteria can scan.

``DenseRoute.from_route(map, route)`` runs ``Map.interpolate_trajectory(keypoints, hop_resolution=1.0)`` (the
leaderboard's ``interpolate_trajectory``) and keeps, per route point, the waypoint, its RoadOption, its location,
its forward vector (``transform.get_forward_vector()``, pitch included, as the criteria's dot-product tests use)
and the cumulative 3-D length (``statistics_manager.compute_route_length``). It also stores the speed limit of
each point's lane (km/h, ``Map.speed_limit``), which the route timeout needs.

A ``DenseRoute`` is also a sequence of ``(Waypoint, RoadOption)`` pairs, so it can be handed to the expert as is.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, overload

import numpy as np

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location, Transform

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint
    from b2d_data.scenarios.route_xml import Route

log = logging.getLogger(__name__)

#: Spacing of the leaderboard's dense route (m).
HOP_RESOLUTION = 1.0


class EmptyRouteError(ValueError):
    """A route whose keypoints densify to no route point at all."""


def _as_xyz(location: Location | Sequence[float] | np.ndarray) -> np.ndarray:
    if isinstance(location, Location):
        return np.array([location.x, location.y, location.z], dtype=np.float64)
    a = np.asarray(location, dtype=np.float64)
    return np.array([a[0], a[1], a[2] if a.shape[0] > 2 else 0.0])


@dataclass(frozen=True, eq=False)
class DenseRoute:
    """The 1 m leaderboard route: per-point waypoint, command, location, forward vector, lengths and speed limit."""

    waypoints: tuple[Waypoint, ...]
    commands: tuple[RoadOption, ...]
    #: (N, 3) route point locations (CARLA frame).
    locations: np.ndarray
    #: (N, 3) unit forward vectors of the route points' transforms.
    forward_vectors: np.ndarray
    #: (N,) 3-D length from the first point to each point (0 at the first point).
    cumulative_length: np.ndarray
    #: (N,) speed limit of each point's lane in km/h.
    speed_limits: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.waypoints)
        if n == 0:
            raise EmptyRouteError("a dense route needs at least one route point")
        shapes = {
            "commands": (len(self.commands),),
            "locations": self.locations.shape,
            "forward_vectors": self.forward_vectors.shape,
            "cumulative_length": self.cumulative_length.shape,
            "speed_limits": self.speed_limits.shape,
        }
        expected = {"commands": (n,), "locations": (n, 3), "forward_vectors": (n, 3),
                    "cumulative_length": (n,), "speed_limits": (n,)}  # fmt: skip
        for name, shape in shapes.items():
            if tuple(shape) != expected[name]:
                raise ValueError(f"DenseRoute.{name} has shape {tuple(shape)}, expected {expected[name]}")

    # ----------------------------------------------------------------------------------------------- building

    @classmethod
    def from_pairs(cls, pairs: Sequence[tuple[Waypoint, RoadOption]], map: Map | None = None) -> DenseRoute:
        """Build from ``[(waypoint, RoadOption)]`` (e.g. ``Map.trace_route``); speed limits from the map (else 50)."""
        if not pairs:
            raise EmptyRouteError("no (waypoint, RoadOption) pair to build a dense route from")
        waypoints = tuple(wp for wp, _ in pairs)
        commands = tuple(RoadOption(int(option)) for _, option in pairs)
        locations = np.array([_as_xyz(wp.transform.location) for wp in waypoints])
        forward = np.array([_as_xyz(wp.transform.get_forward_vector()) for wp in waypoints])
        steps = np.linalg.norm(np.diff(locations, axis=0), axis=1)
        cumulative = np.concatenate([[0.0], np.cumsum(steps)])
        source = map if map is not None else getattr(waypoints[0], "map", None)
        if source is not None:
            limits = np.array([float(source.speed_limit(wp)) for wp in waypoints])
        else:
            limits = np.full(len(waypoints), 50.0)
        return cls(waypoints, commands, locations, forward, cumulative, limits)

    @classmethod
    def from_keypoints(
        cls, map: Map, keypoints: Sequence[Location], hop_resolution: float = HOP_RESOLUTION
    ) -> DenseRoute:
        """Densify route keypoints with ``Map.interpolate_trajectory`` (the leaderboard's route)."""
        pairs = map.interpolate_trajectory(list(keypoints), hop_resolution=hop_resolution)
        if not pairs:
            raise EmptyRouteError(
                f"{getattr(map, 'name', 'map')}: the {len(keypoints)} keypoints give no dense route "
                "(all keypoints at the same place?)"
            )
        return cls.from_pairs(pairs, map)

    @classmethod
    def from_route(cls, map: Map, route: Route) -> DenseRoute:
        """The dense route of a route XML ``<route>``."""
        dense = cls.from_keypoints(map, route.waypoints)
        log.debug("route %s: %d keypoints -> %d route points, %.3f m", route.id, len(route.waypoints),
                  len(dense), dense.total_length)
        return dense

    # ----------------------------------------------------------------------------------------------- sequence

    def __len__(self) -> int:
        return len(self.waypoints)

    @overload
    def __getitem__(self, index: int) -> tuple[Waypoint, RoadOption]: ...

    @overload
    def __getitem__(self, index: slice) -> list[tuple[Waypoint, RoadOption]]: ...

    def __getitem__(self, index: int | slice) -> tuple[Waypoint, RoadOption] | list[tuple[Waypoint, RoadOption]]:
        if isinstance(index, slice):
            return list(zip(self.waypoints[index], self.commands[index]))
        return self.waypoints[index], self.commands[index]

    def __iter__(self) -> Iterator[tuple[Waypoint, RoadOption]]:
        return iter(zip(self.waypoints, self.commands))

    # ----------------------------------------------------------------------------------------------- queries

    @property
    def total_length(self) -> float:
        """Route length in metres (the record's ``meta.route_length`` before rounding)."""
        return float(self.cumulative_length[-1])

    @property
    def transforms(self) -> list[Transform]:
        """The route points' transforms (what the leaderboard keeps of each waypoint)."""
        return [wp.transform for wp in self.waypoints]

    def location(self, index: int) -> Location:
        """Location of route point ``index``."""
        x, y, z = self.locations[index]
        return Location(float(x), float(y), float(z))

    def speed_limit_ms(self, index: int) -> float:
        """Speed limit of route point ``index`` in m/s."""
        return float(self.speed_limits[index]) / 3.6

    def percentage(self, index: int) -> float:
        """Cumulative length at ``index`` as a percentage of the route length (100 for a one-point route)."""
        total = self.total_length
        return 100.0 if total <= 0.0 else float(self.cumulative_length[index]) / total * 100.0

    def closest_index(
        self,
        location: Location | Sequence[float] | np.ndarray,
        start: int = 0,
        window: int | None = None,
        planar: bool = True,
    ) -> int:
        """Index of the route point nearest to ``location`` among ``start .. start + window``.

        ``window=None`` searches the whole route from ``start``. Distances are horizontal unless ``planar`` is
        False (the scenario triggerer measures in 3-D, the deviation test horizontally). Ties go to the later
        point, as the leaderboard's window scans (``distance <= shortest``) do.
        """
        n = len(self.waypoints)
        start = min(max(int(start), 0), n - 1)
        stop = n if window is None else min(start + int(window) + 1, n)
        delta = self.locations[start:stop] - _as_xyz(location)
        d = np.hypot(delta[:, 0], delta[:, 1]) if planar else np.linalg.norm(delta, axis=1)
        # argmin returns the first minimum; the leaderboard keeps the last one of equal distance.
        best = int(len(d) - 1 - np.argmin(d[::-1]))
        return start + best

    def passed_index(self, location: Location | Sequence[float] | np.ndarray, start: int, window: int) -> int:
        """Furthest index in ``start .. start + window`` whose point the location has passed (else ``start``).

        "Passed" is the criteria's test: the point's forward vector · (location − point) > 0.
        """
        n = len(self.waypoints)
        stop = min(start + window + 1, n)
        p = _as_xyz(location)
        ahead = np.einsum("ij,ij->i", p - self.locations[start:stop], self.forward_vectors[start:stop]) > 0.0
        hits = np.nonzero(ahead)[0]
        return start + int(hits[-1]) if hits.size else start
