"""ParkingCutIn and StaticCutIn (§2.2 #3, #4): a car pulls into the ego's lane just in front of it.

ParkingCutIn: a blocker car parked 28 m ahead and the cut-in car 35 m ahead, both in the ``direction``-side
lane (a parking lane on generated routes; any lane there, as LB2.0's ``get_right_lane``/``get_left_lane``) pushed
toward its outer edge (hand brake). At the trigger the background clears 45 m ahead; when the
ego's time to arrival at the cut-in car drops below 2.35 s (or within 10 m) it pulls out at 20 km/h into the ego's
lane (stopping for vehicles in its way, ignoring lights) and drives 30 m; then both cars are removed. The
background gets 20 m extra space from the pull-out to the scenario's end.

StaticCutIn: a queue of six stopped cars 11 m apart in the ``direction``-side lane from ``distance`` m ahead, the
third one the cut-in car (hidden until the trigger, when the background clears distance + 66 m ahead). When the
ego's time to arrival at the ego-lane point abreast of the cut-in car drops below 2.7 s (or within 15 m), the
background gets 30 m extra space and leaves the side lane, and the car pulls into the ego's lane in 3 s (within 9
m, so as to clear the queued car ahead of it), drives 2 s more at the ego's speed, then follows the lane for 70 m
at 60 km/h. At the end the extra space goes back to 0 and the side lane opens again.
"""

from __future__ import annotations

import logging

import numpy as np

from b2d_data.maps import Waypoint
from b2d_data.scenarios.catalog.actor_choices import half_extent, random_parked_car
from b2d_data.scenarios.catalog.layout import (
    STRAIGHTISH,
    Layout,
    leftmost_beside_parking,
    multi_lane_left,
    multi_lane_right,
    parking_ahead,
    register_layouts,
    rightmost,
)
from b2d_data.scenarios.catalog.road_geometry import (
    lane_walk,
    lateral_offset,
    move_along,
    neighbour,
    offset_transform,
    same_direction,
)
from b2d_data.scenarios.controllers import ConstantVelocityAgent, PathTrack, park
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import TimeToArrivalTrigger
from b2d_data.sim.api import Snapshot

log = logging.getLogger(__name__)


def merge_track(
    lane: Waypoint, start_lateral: float, merge_length: float, total: float, ease_in: bool = True
) -> PathTrack:
    """A path along ``lane`` starting ``start_lateral`` m to its side and reaching its centre after ``merge_length``
    m, ``total`` m long: smoothstep, or (``ease_in=False``) leaving the side fast, so as to clear a car stopped
    just ahead in the side lane."""
    rows = []
    for k, wp in enumerate(lane_walk(lane, total)):
        u = min(1.0, k / max(merge_length, 1e-6))
        left = 1.0 - (3.0 * u * u - 2.0 * u * u * u) if ease_in else (1.0 - u) ** 2
        offset = start_lateral * left
        t = offset_transform(wp, lateral=offset)
        rows.append((t.location.x, t.location.y, t.location.z))
    return PathTrack(np.array(rows))


def _direction(ctx: ScenarioContext, name: str) -> str:
    direction = ctx.text("direction", "right")
    if direction not in ("left", "right"):
        raise ScenarioSetupError(f"{name}: direction must be 'left' or 'right', got {direction!r}")
    return direction


@register
class ParkingCutIn(Scenario):
    """A parked car pulls out in front of the ego."""

    xml_type = "ParkingCutIn"
    scenario_timeout = None
    timeout_test = False
    blocker_distance = 28.0
    cut_in_distance = 35.0
    adversary_speed = 20.0 / 3.6
    drive_distance = 30.0
    merge_length = 10.0
    sync_time = 2.35
    min_trigger_distance = 10.0
    front_clear = 45.0
    extra_space = 20.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.direction = _direction(ctx, self.name)
        self.sign = 1.0 if self.direction == "right" else -1.0
        self.slots: list[tuple[Waypoint, Waypoint]] = []  # (driving lane, parking lane)
        for d in (self.blocker_distance, self.cut_in_distance):
            # LB2.0: ``reference_waypoint.next(d)[0]``, through a junction if one lies there, and whatever lane lies
            # to that side (``get_right_lane``/``get_left_lane``), parking or not
            lane = move_along(self.trigger_waypoint, d)
            parking = neighbour(lane, self.direction) if lane is not None else None
            if parking is None:
                raise ScenarioSetupError(
                    f"{self.name}: layout 'parking_lane' missing: no lane to the {self.direction} "
                    f"{d:.0f} m after the trigger point"
                )
            self.slots.append((lane, parking))
        self.models = [random_parked_car(ctx.rng) for _ in self.slots]
        lane, parking = self.slots[1]
        self.cut_in_lateral = lateral_offset(lane, parking) + self._push(parking, self.models[1])
        self.track = merge_track(lane, self.cut_in_lateral, self.merge_length, self.drive_distance)
        self._tta = TimeToArrivalTrigger(lane.transform.location, self.sync_time, self.min_trigger_distance)
        self.cars: list[int] = []
        self._agent: ConstantVelocityAgent | None = None
        self._finished = False

    def _push(self, parking: Waypoint, model: str) -> float:
        """Lateral push (signed) toward the parking lane's outer edge."""
        return self.sign * (parking.lane_width - half_extent(model)[1]) / 4.0

    def build(self) -> None:
        """The two parked cars."""
        for (lane, parking), model in zip(self.slots, self.models):
            lateral = lateral_offset(lane, parking) + self._push(parking, model)
            transforms = [offset_transform(lane, lateral=lateral, forward=f, z=0.05) for f in (0.0, 1.0, -1.0)]
            car = self.spawn(model, transforms[0], retries=transforms[1:])
            park(self.ctx.sim, car)
            self.cars.append(car)

    def start(self, snapshot: Snapshot) -> None:
        """Clear the road in front of the ego."""
        self.ctx.sim.background.leave_space_in_front(self.front_clear)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """TTA trigger → pull out and drive 30 m → remove both cars → SUCCESS."""
        ego = self.ctx.ego(snapshot)
        if ego is None or len(self.cars) < 2:
            return ScenarioStatus.RUNNING
        if self._agent is None:
            if not self._tta.check(ego):
                return ScenarioStatus.RUNNING
            log.debug("%s: the cut-in car pulls out", self.name)
            # LB2.0 (parking_cut_in.py) gives the road 20 m more room during the cut-in and takes it back at the end
            self.ctx.sim.background.change_road_behavior(extra_space=self.extra_space)
            self._agent = ConstantVelocityAgent(
                self.ctx.sim, self.cars[1], self.track, self.adversary_speed, detect_vehicles=True,
                ignore=[self.cars[0]],
            )  # fmt: skip
        self._agent.run_step(snapshot)
        if self._agent.done or self._agent.travelled >= self.drive_distance:
            for car in self.cars:
                self.destroy(car)
            self.cars = []
            return ScenarioStatus.SUCCESS
        return ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """The road's extra room goes back to 0 (LB2.0's ChangeRoadBehavior(extra_space=0) at the end)."""
        if self._agent is not None:
            self.ctx.sim.background.change_road_behavior(extra_space=0.0)


@register
class StaticCutIn(Scenario):
    """A car of a stopped queue in the next lane cuts into the ego's lane."""

    xml_type = "StaticCutIn"
    # LB2.0's 30 s is the class's legacy timeout, not a ScenarioTimeout behaviour with its test
    scenario_timeout = None
    timeout_test = False
    queue_gap = 11.0
    queue_before = 2
    queue_after = 3
    change_time = 3.0
    #: The car pulls out of the queue within this many metres: the next queued car stands 11 m ahead of it.
    merge_length = 9.0
    keep_time = 2.0
    final_speed = 60.0 / 3.6
    final_distance = 70.0
    sync_time = 2.7
    min_trigger_distance = 15.0
    clear_extra = 66.0
    extra_space = 30.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.direction = _direction(ctx, self.name)
        self.distance = ctx.value("distance", 100.0)
        # LB2.0 (cut_in_with_static_vehicle.py ``_initialize_actors``): from ``next(distance)[0]`` on the ego's lane,
        # each car stands on the lane to the side of the ego lane's point, the next point ``next(11)[0]`` on,
        # through junctions; the cut-in car is the third, and its lane point (``_collision_wp``) needs 70 m of lane
        # ahead (the plan after the cut-in).
        self.ego_points: list[Waypoint] = []
        self.spots: list[Waypoint] = []
        count = self.queue_before + 1 + self.queue_after
        point = move_along(self.trigger_waypoint, self.distance)
        for k in range(count):
            side = neighbour(point, self.direction) if point is not None else None
            # LB2.0 takes any lane there; an opposite one would hold the queue facing the ego (refused here)
            if point is None or side is None or not same_direction(point, side):
                raise ScenarioSetupError(
                    f"{self.name}: layout 'multi_lane' missing: no same-direction lane to the {self.direction} of the "
                    f"ego's lane {self.distance + k * self.queue_gap:.0f} m after the trigger point"
                )
            self.ego_points.append(point)
            self.spots.append(side)
            point = move_along(point, self.queue_gap)
        ego_lane = self.ego_points[self.queue_before]
        if move_along(ego_lane, self.final_distance) is None:
            raise ScenarioSetupError(f"{self.name}: the ego's lane ends within {self.final_distance:.0f} m of the cut-in")
        cut_in_spot = self.spots[self.queue_before]
        self.ego_lane = ego_lane
        self.cut_in_lateral = lateral_offset(ego_lane, cut_in_spot)
        self.models = [random_parked_car(ctx.rng) for _ in self.spots]
        # LB2.0 (cut_in_with_static_vehicle.py) times the cut-in to _collision_wp: the ego lane's point abreast of
        # the cut-in car
        self._tta = TimeToArrivalTrigger(ego_lane.transform.location, self.sync_time, self.min_trigger_distance)
        self.cars: list[int] = []
        self._agent: ConstantVelocityAgent | None = None
        self._t0: float | None = None
        self._phase = 0
        self._ego_speed = 0.0

    @property
    def cut_in(self) -> int | None:
        """The cut-in car's actor id."""
        return self.cars[self.queue_before] if len(self.cars) > self.queue_before else None

    def start(self, snapshot: Snapshot) -> None:
        """Clear the road ahead, show the queue."""
        bg = self.ctx.sim.background
        bg.leave_space_in_front(self.distance + self.clear_extra)
        for wp, model in zip(self.spots, self.models):
            transforms = [offset_transform(wp, forward=f, z=0.05) for f in (0.0, 1.0, -1.0)]
            car = self.spawn(model, transforms[0], retries=transforms[1:])
            park(self.ctx.sim, car)
            self.cars.append(car)

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """TTA trigger → 3 s lane change + 2 s at the ego's speed → 70 m at 60 km/h → SUCCESS."""
        ego = self.ctx.ego(snapshot)
        if ego is None or self.cut_in is None:
            return ScenarioStatus.RUNNING
        if self._agent is None:
            if not self._tta.check(ego):
                return ScenarioStatus.RUNNING
            # LB2.0 at the trigger: 30 m extra space, the side lane (at the second queued car) taken from the road
            bg = self.ctx.sim.background
            bg.change_road_behavior(extra_space=self.extra_space)
            bg.remove_road_lane(self.spots[1])
            self._ego_speed = max(ego.speed(), 3.0)
            total = self.merge_length + self._ego_speed * self.keep_time + self.final_distance
            track = merge_track(self.ego_lane, self.cut_in_lateral, self.merge_length, total, ease_in=False)
            others = [c for c in self.cars if c != self.cut_in]
            self._agent = ConstantVelocityAgent(
                self.ctx.sim, self.cut_in, track, self.merge_length / self.change_time, ignore=others
            )
            self._t0 = snapshot.timestamp
            log.debug("%s: the cut-in car changes lane (ego at %.1f m/s)", self.name, self._ego_speed)
        elapsed = snapshot.timestamp - (self._t0 if self._t0 is not None else snapshot.timestamp)
        if self._phase == 0 and elapsed >= self.change_time:
            self._phase, self._agent.speed = 1, self._ego_speed
        if self._phase == 1 and elapsed >= self.change_time + self.keep_time:
            self._phase, self._agent.speed = 2, self.final_speed
        self._agent.run_step(snapshot)
        return ScenarioStatus.SUCCESS if self._agent.done else ScenarioStatus.RUNNING

    def on_end(self) -> None:
        """The road's extra space back to 0 and the side lane open again (LB2.0's ChangeRoadBehavior(extra_space=0)
        and ReAddRoadLane at the end)."""
        if self._agent is not None:
            bg = self.ctx.sim.background
            bg.change_road_behavior(extra_space=0.0)
            bg.readd_road_lane(1 if self.direction == "right" else -1)


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "ParkingCutIn": Layout("parking_lane", "rightmost lane with a parking lane on the right 24–40 m ahead (or "
                           "leftmost with one on the left), 100 m junction-free", rightmost, clear_after=100.0,
                           pre=(12.0, 14.0),
                           extra=parking_ahead((24.0, 28.0, 32.0, 36.0, 40.0)), max_turn=STRAIGHTISH,
                           directions={"right": rightmost, "left": leftmost_beside_parking}, extra_sides=("right",)),
    "StaticCutIn": Layout("multi_lane", "two same-direction lanes (ego on the left one), 130 m junction-free",
                          multi_lane_right, clear_after=130.0, max_turn=STRAIGHTISH,
                          directions={"right": multi_lane_right, "left": multi_lane_left}, reach_param="distance"),
})  # fmt: skip
