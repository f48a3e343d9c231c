"""OutsideRouteLanesTest: route metres driven outside driving/parking lanes or in a wrong-direction lane."""

from __future__ import annotations

from typing import TYPE_CHECKING

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import Location
from b2d_data.maps import LaneType
from b2d_data.scenarios.criteria.base import FAILURE, RUNNING, Criterion, Infraction
from b2d_data.scenarios.route import DenseRoute
from b2d_data.sim.api import ActorState, Snapshot

if TYPE_CHECKING:
    from b2d_data.maps import Map, Waypoint


class OutsideRouteLanesTest(Criterion):
    """Accumulates the route distance passed while outside the lanes or in a lane of the wrong direction.

    Outside: the ego is farther than half the lane width + 0.5 m from the nearest driving or parking lane centre.
    Wrong lane: on changing lane outside a junction, the lane direction jumps by more than 150° (the state
    toggles, so coming back clears it); right after a junction, the new lane differs from the ego's yaw by 120°
    or more. Scenarios may switch the wrong-direction part off (:meth:`switch_wrong_direction`). The single
    event's message and percentage are refreshed whenever the wrong distance grows.
    """

    name = "OutsideRouteLanesTest"
    ALLOWED_OUT_DISTANCE = 0.5  # m: the mini shoulder between lanes and sidewalks
    MAX_VEHICLE_ANGLE = 120.0  # deg: ego yaw vs lane right after a junction
    MAX_WAYPOINT_ANGLE = 150.0  # deg: lane direction change between ticks
    WINDOW = 3

    def __init__(self, map: Map, route: DenseRoute) -> None:
        super().__init__()
        self.map = map
        self.route = route
        self.index = 0
        self.outside_lane_active = False
        self.wrong_lane_active = False
        self.wrong_direction_active = True
        self.total_distance = 0.0
        self.wrong_distance = 0.0
        self._last_ego_waypoint: Waypoint | None = None
        self._last_road_id: int | None = None
        self._last_lane_id: int | None = None
        self._event_position: int | None = None
        self._pending_switch: bool | None = None

    @property
    def percentage(self) -> float:
        """Wrong distance as a percentage of the passed route distance (0 before any progress)."""
        return self.wrong_distance / self.total_distance * 100 if self.total_distance > 0 else 0.0

    def switch_wrong_direction(self, active: bool) -> None:
        """(De)activate the wrong-direction check from the next update (``AC_SwitchWrongDirectionTest``)."""
        self._pending_switch = active

    def update(self, snapshot: Snapshot, ego: ActorState) -> None:
        """Classify the ego's position, then add the newly passed route distance."""
        location = ego.location
        if self._last_ego_waypoint is None:
            # The leaderboard takes it when the criterion is built, right after the ego is spawned.
            self._last_ego_waypoint = self.map.get_waypoint(location)
        if self._pending_switch is not None:
            self.wrong_direction_active = self._pending_switch
            self._pending_switch = None
        driving = self.map.get_waypoint(location, lane_type=LaneType.DRIVING)
        self._check_outside_driving_lanes(location, driving)
        self._check_wrong_lane(driving, ego)
        out = self.outside_lane_active or (self.wrong_direction_active and self.wrong_lane_active)
        if out:
            self.test_status = FAILURE
        elif self.test_status != FAILURE:
            self.test_status = RUNNING

        n = len(self.route)
        for index in range(self.index + 1, min(self.index + self.WINDOW + 1, n)):
            point = self.route.locations[index]
            forward = self.route.forward_vectors[index]
            ahead = ((location.x - point[0]) * forward[0] + (location.y - point[1]) * forward[1]
                     + (location.z - point[2]) * forward[2])  # fmt: skip
            if ahead > 0:
                previous = self.route.locations[self.index]
                new_dist = float(((point - previous) ** 2).sum() ** 0.5)
                self.total_distance += new_dist
                if out:
                    self.wrong_distance += new_dist
                if self.wrong_distance:
                    self._set_event(snapshot.frame)
                self.index = index

    def _set_event(self, frame: int) -> None:
        percentage = self.wrong_distance / self.total_distance * 100
        event = Infraction(lb.OUTSIDE_ROUTE_LANES, lb.outside_lanes_message(self.wrong_distance, percentage), frame,
                           percentage=percentage)
        if self._event_position is None:
            self._event_position = len(self.events)
            self.events.append(event)
        else:
            self.events[self._event_position] = event

    def _check_outside_driving_lanes(self, location: Location, driving: Waypoint | None) -> None:
        parking = self.map.get_waypoint(location, lane_type=LaneType.PARKING)
        driving_distance = location.distance(driving.transform.location) if driving is not None else float("inf")
        parking_distance = location.distance(parking.transform.location) if parking is not None else float("inf")
        if parking is not None and driving_distance >= parking_distance:
            distance, lane_width = parking_distance, parking.lane_width
        elif driving is not None:
            distance, lane_width = driving_distance, driving.lane_width
        else:
            self.outside_lane_active = True  # a map without driving lanes near here
            return
        self.outside_lane_active = distance > lane_width / 2 + self.ALLOWED_OUT_DISTANCE

    def _check_wrong_lane(self, waypoint: Waypoint | None, ego: ActorState) -> None:
        if waypoint is None:
            return
        lane_id, road_id = waypoint.lane_id, waypoint.road_id
        if waypoint.is_junction:
            # Lanes and roads are too chaotic at junctions.
            self.wrong_lane_active = False
        elif self._last_road_id != road_id or self._last_lane_id != lane_id:
            last = self._last_ego_waypoint
            if last is not None and last.is_junction:
                # Just left a junction: compare the new lane with the ego's heading.
                angle = (waypoint.transform.rotation.yaw % 360 - ego.transform.rotation.yaw % 360) % 360
                self.wrong_lane_active = not (angle < self.MAX_VEHICLE_ANGLE or angle > 360 - self.MAX_VEHICLE_ANGLE)
            elif last is not None:
                # Lane directions are continuous along a road: a big jump means crossing into (or back out of)
                # a lane of the other direction.
                angle = (last.transform.rotation.yaw % 360 - waypoint.transform.rotation.yaw % 360) % 360
                if self.MAX_WAYPOINT_ANGLE < angle < 360 - self.MAX_WAYPOINT_ANGLE:
                    self.wrong_lane_active = not self.wrong_lane_active
        self._last_lane_id = lane_id
        self._last_road_id = road_id
        self._last_ego_waypoint = waypoint
