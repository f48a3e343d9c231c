"""RunningRedLightTest and RunningStopTest: the two traffic-rule criteria of the route."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location
from b2d_data.scenarios.criteria.base import (
    FAILURE,
    RUNNING,
    Criterion,
    Infraction,
    planar_speed,
    rotate_2d,
    segments_intersect,
)
from b2d_data.sim.api import ActorState, Snapshot, TrafficLightInfo, TrafficLightState, TrafficSignInfo
from b2d_data.sim.traffic_rules import stop_affects, stop_zone_waypoints

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint


def stop_line_waypoints(light: TrafficLightInfo) -> list[Waypoint]:
    """Waypoints of a light's stop lines: each governed lane's stop waypoint moved to the junction's edge.

    The stop waypoint is advanced in 0.5 m steps to the last point before the junction, as the criterion does
    with the lanes under the trigger volume; one waypoint per (road, lane).
    """
    out: list[Waypoint] = []
    seen: set[tuple[int, int]] = set()
    for wp in light.stop_waypoints:
        while not wp.is_junction:
            nxt = wp.next(0.5)
            if nxt and not nxt[0].is_junction:
                wp = nxt[0]
            else:
                break
        key = (wp.road_id, wp.lane_id)
        if key not in seen:
            seen.add(key)
            out.append(wp)
    return out


class RunningRedLightTest(Criterion):
    """One infraction when the ego's tail segment crosses the stop line of a red light governing its lane.

    Only lights whose trigger-volume centre is within 15 m of the ego are checked; the stop line spans
    ±0.6 × lane width across the lane at the last waypoint before the junction; the tail segment runs from
    0.8 × half-length to half-length + 1 m behind the ego's centre, and counts while the waypoint under its far
    end is on the light's lane and the ego heads along that lane. The same light cannot fire twice in a row.
    """

    name = "RunningRedLightTest"
    DISTANCE_LIGHT = 15.0  # m

    def __init__(self, map: Map) -> None:
        super().__init__()
        self.map = map
        self.actual_value = 0
        self._last_red_light_id: int | None = None
        self._geometry: dict[int, tuple[Location, list[Waypoint]]] = {}

    def _light_geometry(self, light: TrafficLightInfo) -> tuple[Location, list[Waypoint]]:
        cached = self._geometry.get(light.id)
        if cached is None:
            center = light.transform.transform_point(light.trigger_volume.location)
            cached = (center, stop_line_waypoints(light))
            self._geometry[light.id] = cached
        return cached

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Check every nearby red light's stop lines against the ego's tail."""
        if self.test_status != FAILURE:
            self.test_status = RUNNING
        transform = ego.transform
        location = transform.location
        yaw = transform.rotation.yaw
        extent = ego.bounding_box.extent.x
        cx, cy = rotate_2d(-0.8 * extent, 0.0, yaw)
        fx, fy = rotate_2d(-extent - 1.0, 0.0, yaw)
        tail_close = (location.x + cx, location.y + cy)
        tail_far = (location.x + fx, location.y + fy)
        tail_wp: Waypoint | None = None  # looked up only once a nearby red light needs it (same result, cheaper)
        ego_dir = transform.get_forward_vector()
        for light_id in sorted(snapshot.traffic_lights):
            light = snapshot.traffic_lights[light_id]
            if self._last_red_light_id is not None and self._last_red_light_id == light.id:
                continue
            center, waypoints = self._light_geometry(light)
            if center.distance(location) > self.DISTANCE_LIGHT:
                continue
            if light.state != TrafficLightState.RED:
                continue
            if tail_wp is None:
                tail_wp = self.map.get_waypoint(Location(tail_far[0], tail_far[1], location.z))
                if tail_wp is None:
                    return
            for wp in waypoints:
                if tail_wp.road_id != wp.road_id or tail_wp.lane_id != wp.lane_id:
                    continue
                if ego_dir.dot(wp.transform.get_forward_vector()) <= 0:
                    continue
                wp_yaw, half = wp.transform.rotation.yaw, 0.6 * wp.lane_width
                wl = wp.transform.location
                lx, ly = rotate_2d(half, 0.0, wp_yaw + 90)
                rx, ry = rotate_2d(half, 0.0, wp_yaw - 90)
                if segments_intersect(tail_close, tail_far, (wl.x + lx, wl.y + ly), (wl.x + rx, wl.y + ry)):
                    self.test_status = FAILURE
                    self.actual_value += 1
                    at = light.transform.location
                    self.events.append(Infraction(lb.RED_LIGHT, lb.red_light_message(light.id, at), snapshot.frame,
                                                  location=at, actor_id=light.id))
                    self._last_red_light_id = light.id
                    break


class RunningStopTest(Criterion):
    """A stop sign affecting the ego must see it below 0.1 m/s before it leaves the sign's zone.

    The ego is affected when the stop's trigger centre is within 4 m of its lane waypoint and any of the 9 lane
    waypoints from it (0.5 m steps, 4 m ahead) lies in the trigger box enlarged 1.2×; no stop is picked up while
    the ego moves backwards or faces against its lane (> ~100°).
    """

    name = "RunningStopTest"
    SPEED_THRESHOLD = 0.1  # m/s
    #: Without a target, stops farther than this from the ego cannot be picked up (the ego's lane waypoint is
    #: within a lane width of it, and a stop must be within 4 m of that waypoint): skip the waypoint walk.
    SCAN_RADIUS = 50.0  # m

    def __init__(self, map: Map) -> None:
        super().__init__()
        self.map = map
        self.actual_value = 0
        self.target_stop_sign: TrafficSignInfo | None = None
        self.stop_completed = False
        self._last_failed_stop: int | None = None

    def _waypoints(self, location: Location) -> list[Waypoint]:
        return stop_zone_waypoints(self.map, location)

    def is_affected(self, waypoints: Sequence[Waypoint], stop: TrafficSignInfo) -> bool:
        """Whether the lane waypoints ahead of the ego reach into the stop's trigger volume."""
        return stop_affects(waypoints, stop)

    def _scan(self, snapshot: Snapshot, ego: ActorState, waypoints: Sequence[Waypoint]) -> TrafficSignInfo | None:
        if not waypoints:
            return None
        direction = ego.transform.get_forward_vector()
        if ego.velocity.dot(direction) < -0.17:  # going backwards (~100°, "just in case")
            return None
        if direction.dot(waypoints[0].transform.get_forward_vector()) < -0.17:  # against the lane
            return None
        for sign_id in sorted(snapshot.traffic_signs):
            sign = snapshot.traffic_signs[sign_id]
            if "traffic.stop" in sign.type_id and self.is_affected(waypoints, sign):
                return sign
        return None

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Pick up a stop, watch for the full stop, and judge when the ego leaves the stop's zone."""
        if self.test_status != FAILURE:
            self.test_status = RUNNING
        if self.target_stop_sign is None and not any(
            "traffic.stop" in sign.type_id and sign.transform.location.distance(ego.location) < self.SCAN_RADIUS
            for sign in snapshot.traffic_signs.values()
        ):
            return
        waypoints = self._waypoints(ego.location)
        if self.target_stop_sign is None:
            self.target_stop_sign = self._scan(snapshot, ego, waypoints)
            return
        if not self.stop_completed and planar_speed(ego) < self.SPEED_THRESHOLD:
            self.stop_completed = True
        if not self.is_affected(waypoints, self.target_stop_sign):
            stop = self.target_stop_sign
            if not self.stop_completed and self._last_failed_stop != stop.id:
                self.actual_value += 1
                self.test_status = FAILURE
                at = stop.transform.location
                self.events.append(Infraction(lb.STOP_INFRACTION, lb.stop_message(stop.id, at), snapshot.frame,
                                              location=at, actor_id=stop.id))
                self._last_failed_stop = stop.id
            self.target_stop_sign = None
            self.stop_completed = False
