"""CARLA's GlobalRoutePlanner (PythonAPI agents, 0.9.15) and the leaderboard's ``interpolate_trajectory``.

The graph has one node per lane-segment end point (locations rounded to whole metres, so touching segments share
nodes) and one LANEFOLLOW edge per topology segment, weighted by its number of waypoints at the hop resolution,
plus zero-cost CHANGELANELEFT/RIGHT edges where a marking allows the change outside junctions. A* with the
Euclidean heuristic finds the node path. Turn decisions: at each junction entry the turn angle between the exit
tangent of the incoming edge and of the last junction edge decides STRAIGHT (< 35°) or LEFT/RIGHT (by the cross
product, compared with the other branches leaving the same node); edges inside the junction repeat that decision.
The graph attributes behave like networkx's: re-adding an edge updates its attributes.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location
from b2d_data.maps.lane_types import LaneChange, LaneType
from b2d_data.maps.waypoint import Waypoint

if TYPE_CHECKING:
    from b2d_data.maps.map import Map

logger = logging.getLogger(__name__)

#: Decision threshold between STRAIGHT and a turn (radians), as in CARLA 0.9.15.
TURN_THRESHOLD = math.radians(35)
_MAX_PATH_STEPS = 1_000_000


class RouteNotFoundError(ValueError):
    """No lane path joins the two locations (or one of them cannot be placed on a driving lane)."""


@dataclass
class _Segment:
    entry: Waypoint
    exit: Waypoint
    entry_xyz: tuple[float, float, float]
    exit_xyz: tuple[float, float, float]
    path: list[Waypoint] = field(default_factory=list)


def _vector(a: Location, b: Location) -> np.ndarray:
    """Unit vector from a to b (agents.tools.misc.vector)."""
    v = np.array([b.x - a.x, b.y - a.y, b.z - a.z])
    return v / (np.linalg.norm(v) + np.finfo(float).eps)


def _forward(waypoint: Waypoint) -> np.ndarray:
    f = waypoint.transform.rotation.forward_vector()
    return np.array([f.x, f.y, f.z])


def _xyz(location: Location) -> tuple[float, float, float]:
    r = np.round([location.x, location.y, location.z], 0)
    return (float(r[0]), float(r[1]), float(r[2]))


class RouteGraph:
    """The planner's graph for one map and hop resolution (immutable once built; share it between planners)."""

    def __init__(self, map_: Map, resolution: float = 1.0) -> None:
        self.map = map_
        self.resolution = resolution
        self.nodes: dict[int, tuple[float, float, float]] = {}
        self.succ: dict[int, dict[int, dict[str, Any]]] = {}
        self.id_map: dict[tuple[float, float, float], int] = {}
        self.road_id_to_edge: dict[int, dict[int, dict[int, tuple[int, int]]]] = {}
        self.topology = self._build_topology()
        self._build_graph()
        self._find_loose_ends()
        self._lane_change_link()

    # -- construction (same steps as CARLA's planner) ------------------------------------------------

    def _build_topology(self) -> list[_Segment]:
        res = self.resolution
        topology = []
        for wp1, wp2 in self.map.get_topology():
            l1, l2 = wp1.transform.location, wp2.transform.location
            seg = _Segment(wp1, wp2, _xyz(l1), _xyz(l2))
            if l1.distance(l2) > res:
                first = wp1.next(res)
                if not first:
                    continue
                w = first[0]
                steps = 0
                while w.transform.location.distance(l2) > res and steps < _MAX_PATH_STEPS:
                    seg.path.append(w)
                    nxt = w.next(res)
                    if not nxt:
                        break
                    w = nxt[0]
                    steps += 1
            else:
                nxt = wp1.next(res)
                if not nxt:
                    continue
                seg.path.append(nxt[0])
            topology.append(seg)
        return topology

    def _add_node(self, node: int, vertex: tuple[float, float, float]) -> None:
        if node not in self.nodes:
            self.nodes[node] = vertex
            self.succ[node] = {}
        else:
            self.nodes[node] = vertex

    def add_edge(self, n1: int, n2: int, **attrs: Any) -> None:
        """networkx ``DiGraph.add_edge``: create the edge or update the attributes of an existing one."""
        for n in (n1, n2):
            if n not in self.succ:
                self.succ[n] = {}
        self.succ[n1].setdefault(n2, {}).update(attrs)

    def edge(self, n1: int, n2: int) -> dict[str, Any]:
        """Attributes of edge n1 → n2."""
        return self.succ[n1][n2]

    def _build_graph(self) -> None:
        for seg in self.topology:
            for vertex in (seg.entry_xyz, seg.exit_xyz):
                if vertex not in self.id_map:
                    new_id = len(self.id_map)
                    self.id_map[vertex] = new_id
                    self._add_node(new_id, vertex)
            n1, n2 = self.id_map[seg.entry_xyz], self.id_map[seg.exit_xyz]
            entry, exit_ = seg.entry, seg.exit
            sections = self.road_id_to_edge.setdefault(entry.road_id, {})
            sections.setdefault(entry.section_id, {})[entry.lane_id] = (n1, n2)
            self.add_edge(
                n1, n2, length=len(seg.path) + 1, path=seg.path, entry_waypoint=entry, exit_waypoint=exit_,
                entry_vector=_forward(entry), exit_vector=_forward(exit_),
                net_vector=_vector(entry.transform.location, exit_.transform.location),
                intersection=entry.is_junction, type=RoadOption.LANEFOLLOW,
            )  # fmt: skip

    def _find_loose_ends(self) -> None:
        count = 0
        res = self.resolution
        for seg in self.topology:
            end = seg.exit
            road, section, lane = end.road_id, end.section_id, end.lane_id
            if lane in self.road_id_to_edge.get(road, {}).get(section, {}):
                continue
            count += 1
            n1, n2 = self.id_map[seg.exit_xyz], -count
            self.road_id_to_edge.setdefault(road, {}).setdefault(section, {})[lane] = (n1, n2)
            path: list[Waypoint] = []
            nxt = end.next(res)
            while nxt and nxt[0].road_id == road and nxt[0].section_id == section and nxt[0].lane_id == lane:
                path.append(nxt[0])
                nxt = nxt[0].next(res)
            if path:
                loc = path[-1].transform.location
                self._add_node(n2, (loc.x, loc.y, loc.z))
                self.add_edge(
                    n1, n2, length=len(path) + 1, path=path, entry_waypoint=end, exit_waypoint=path[-1],
                    entry_vector=None, exit_vector=None, net_vector=None, intersection=end.is_junction,
                    type=RoadOption.LANEFOLLOW,
                )  # fmt: skip

    def localize(self, location: Location) -> tuple[int, int] | None:
        """The graph edge of the driving lane closest to ``location``."""
        waypoint = self.map.get_waypoint(location)
        if waypoint is None:
            return None
        return self.road_id_to_edge.get(waypoint.road_id, {}).get(waypoint.section_id, {}).get(waypoint.lane_id)

    def _lane_change_link(self) -> None:
        for seg in self.topology:
            left_found = right_found = False
            for waypoint in seg.path:
                if not seg.entry.is_junction:
                    right = waypoint.right_lane_marking
                    if right is not None and right.lane_change & LaneChange.RIGHT and not right_found:
                        target = waypoint.get_right_lane()
                        right_found = self._link_change(seg, waypoint, target, RoadOption.CHANGELANERIGHT)
                    left = waypoint.left_lane_marking
                    if left is not None and left.lane_change & LaneChange.LEFT and not left_found:
                        target = waypoint.get_left_lane()
                        left_found = self._link_change(seg, waypoint, target, RoadOption.CHANGELANELEFT)
                if left_found and right_found:
                    break

    def _link_change(self, seg: _Segment, waypoint: Waypoint, target: Waypoint | None, option: RoadOption) -> bool:
        if target is None or target.lane_type != LaneType.DRIVING or target.road_id != waypoint.road_id:
            return False
        # CARLA's planner does not check this, but a broken centre line must not turn a route into a
        # wrong-way drive: only change into lanes that run the same way (same sign of lane id).
        if (target.lane_id > 0) != (waypoint.lane_id > 0):
            return False
        next_segment = self.localize(target.transform.location)
        if next_segment is None:
            return False
        self.add_edge(
            self.id_map[seg.entry_xyz], next_segment[0], entry_waypoint=waypoint, exit_waypoint=target,
            intersection=False, exit_vector=None, path=[], length=0, type=option, change_waypoint=target,
        )  # fmt: skip
        return True

    # -- search --------------------------------------------------------------------------------------

    def _heuristic(self, n1: int, n2: int) -> float:
        a, b = self.nodes[n1], self.nodes[n2]
        return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)

    def astar(self, source: int, target: int) -> list[int]:
        """Node path by A* on edge ``length`` (ties resolved in insertion order, like networkx)."""
        counter = itertools.count()
        queue: list[tuple[float, int, int, float, int | None]] = [(0.0, next(counter), source, 0.0, None)]
        enqueued: dict[int, tuple[float, float]] = {}
        explored: dict[int, int | None] = {}
        while queue:
            _, _, node, dist, parent = heapq.heappop(queue)
            if node == target:
                path = [node]
                back = parent
                while back is not None:
                    path.append(back)
                    back = explored[back]
                path.reverse()
                return path
            if node in explored:
                if explored[node] is None:
                    continue
                queued_cost, _ = enqueued[node]
                if queued_cost < dist:
                    continue
            explored[node] = parent
            for neighbour, attrs in self.succ.get(node, {}).items():
                cost = dist + attrs["length"]
                if neighbour in enqueued:
                    queued_cost, h = enqueued[neighbour]
                    if queued_cost <= cost:
                        continue
                else:
                    h = self._heuristic(neighbour, target)
                enqueued[neighbour] = (cost, h)
                heapq.heappush(queue, (cost + h, next(counter), neighbour, cost, node))
        raise RouteNotFoundError(f"{self.map.name}: no lane path from node {source} to node {target}")


class RoutePlanner:
    """One planner session: the graph plus the turn-decision state CARLA keeps between ``trace_route`` calls."""

    def __init__(self, graph: RouteGraph) -> None:
        self.graph = graph
        self._intersection_end_node = -1
        self._previous_decision = RoadOption.VOID

    def path_search(self, origin: Location, destination: Location) -> list[int]:
        """Node path from the edge at ``origin`` to the edge at ``destination`` (both edge ends included)."""
        start, end = self.graph.localize(origin), self.graph.localize(destination)
        if start is None or end is None:
            bad = origin if start is None else destination
            raise RouteNotFoundError(f"{self.graph.map.name}: cannot place {bad} on a driving lane of the route graph")
        route = self.graph.astar(start[0], end[0])
        route.append(end[1])
        return route

    def _successive_last_intersection_edge(self, index: int, route: list[int]):
        last_edge = None
        last_node = None
        for node1, node2 in zip(route[index:-1], route[index + 1 :]):
            candidate = self.graph.edge(node1, node2)
            if node1 == route[index]:
                last_edge = candidate
            if candidate["type"] == RoadOption.LANEFOLLOW and candidate["intersection"]:
                last_edge = candidate
                last_node = node2
            else:
                break
        return last_node, last_edge

    def turn_decision(self, index: int, route: list[int], threshold: float = TURN_THRESHOLD) -> RoadOption:
        """RoadOption for the route edge ``route[index] → route[index + 1]``."""
        decision = None
        previous_node = route[index - 1]
        current_node = route[index]
        next_node = route[index + 1]
        next_edge = self.graph.edge(current_node, next_node)
        if index > 0:
            if (
                self._previous_decision != RoadOption.VOID
                and self._intersection_end_node > 0
                and self._intersection_end_node != previous_node
                and next_edge["type"] == RoadOption.LANEFOLLOW
                and next_edge["intersection"]
            ):
                decision = self._previous_decision
            else:
                self._intersection_end_node = -1
                current_edge = self.graph.edge(previous_node, current_node)
                calculate_turn = (
                    current_edge["type"] == RoadOption.LANEFOLLOW
                    and not current_edge["intersection"]
                    and next_edge["type"] == RoadOption.LANEFOLLOW
                    and next_edge["intersection"]
                )
                if calculate_turn:
                    last_node, tail_edge = self._successive_last_intersection_edge(index, route)
                    self._intersection_end_node = last_node
                    if tail_edge is not None:
                        next_edge = tail_edge
                    cv, nv = current_edge.get("exit_vector"), next_edge.get("exit_vector")
                    if cv is None or nv is None:
                        return next_edge["type"]
                    cross_list = []
                    for neighbour, select_edge in self.graph.succ[current_node].items():
                        if select_edge["type"] == RoadOption.LANEFOLLOW and neighbour != route[index + 1]:
                            sv = select_edge.get("net_vector")
                            if sv is not None:
                                cross_list.append(float(np.cross(cv, sv)[2]))
                    next_cross = float(np.cross(cv, nv)[2])
                    cosine = float(np.dot(cv, nv) / (np.linalg.norm(cv) * np.linalg.norm(nv)))
                    deviation = math.acos(min(1.0, max(-1.0, cosine)))
                    if not cross_list:
                        cross_list.append(0.0)
                    if deviation < threshold:
                        decision = RoadOption.STRAIGHT
                    elif next_cross < min(cross_list):
                        decision = RoadOption.LEFT
                    elif next_cross > max(cross_list):
                        decision = RoadOption.RIGHT
                    elif next_cross < 0:
                        decision = RoadOption.LEFT
                    elif next_cross > 0:
                        decision = RoadOption.RIGHT
                else:
                    decision = next_edge["type"]
        else:
            decision = next_edge["type"]
        self._previous_decision = decision
        return decision

    def trace_route(self, origin: Location, destination: Location) -> list[tuple[Waypoint, RoadOption]]:
        """``[(waypoint, RoadOption)]`` at the graph's resolution from ``origin`` to ``destination``."""
        graph = self.graph
        trace: list[tuple[Waypoint, RoadOption]] = []
        route = self.path_search(origin, destination)
        current = graph.map.get_waypoint(origin)
        destination_wp = graph.map.get_waypoint(destination)
        for i in range(len(route) - 1):
            option = self.turn_decision(i, route)
            edge = graph.edge(route[i], route[i + 1])
            if edge["type"] not in (RoadOption.LANEFOLLOW, RoadOption.VOID):
                trace.append((current, option))
                exit_wp = edge["exit_waypoint"]
                n1, n2 = graph.road_id_to_edge[exit_wp.road_id][exit_wp.section_id][exit_wp.lane_id]
                next_edge = graph.edge(n1, n2)
                if next_edge["path"]:
                    closest = _closest(current, next_edge["path"])
                    closest = min(len(next_edge["path"]) - 1, closest + 5)
                    current = next_edge["path"][closest]
                else:
                    current = next_edge["exit_waypoint"]
                trace.append((current, option))
            else:
                path = [edge["entry_waypoint"]] + edge["path"] + [edge["exit_waypoint"]]
                closest = _closest(current, path)
                for waypoint in path[closest:]:
                    current = waypoint
                    trace.append((current, option))
                    if len(route) - i <= 2:
                        if waypoint.transform.location.distance(destination) < 2 * graph.resolution:
                            break
                        if (
                            current.road_id == destination_wp.road_id
                            and current.section_id == destination_wp.section_id
                            and current.lane_id == destination_wp.lane_id
                            and closest > _closest(destination_wp, path)
                        ):
                            break
        return trace


def _closest(waypoint: Waypoint, candidates: list[Waypoint]) -> int:
    loc = waypoint.transform.location
    best, best_i = math.inf, -1
    for i, candidate in enumerate(candidates):
        d = candidate.transform.location.distance(loc)
        if d < best:
            best, best_i = d, i
    return best_i


def interpolate_trajectory(map_: Map, keypoints: list[Location], hop_resolution: float = 1.0):
    """The leaderboard's ``interpolate_trajectory``: one planner session over consecutive distinct keypoints.

    Returns ``[(waypoint, RoadOption)]``; the leaderboard keeps ``waypoint.transform`` of each entry.
    """
    planner = RoutePlanner(map_.route_graph(hop_resolution))
    route: list[tuple[Waypoint, RoadOption]] = []
    for a, b in zip(keypoints[:-1], keypoints[1:]):
        if a.x != b.x or a.y != b.y:
            route.extend(planner.trace_route(a, b))
    return route
