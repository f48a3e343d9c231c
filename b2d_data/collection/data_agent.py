"""The data agent: turns one recorded tick (snapshot, sensors, expert state) into a FrameRecord."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import numpy as np

from b2d_data.collection.annotations import PlannerFields, build_annotation
from b2d_data.collection.expert_assessment import BevRasterizer, assessment_vector
from b2d_data.collection.route_planners import CommandPlanners
from b2d_data.format.record import FrameRecord
from b2d_data.format.road_option import RoadOption
from b2d_data.maps import Map, Waypoint
from b2d_data.sim.api import RigConfig, SensorData, SimulatorError, Snapshot

logger = logging.getLogger(__name__)

#: Route points (1 m apart) checked for the lights/signs that affect the ego.
_ROUTE_LOOKAHEAD = 50


class DataAgent:
    """Builds the per-frame records of one route; keeps the route planners' state between frames.

    With ``expert_assessment`` (the default) every record carries the expert vector of
    :mod:`b2d_data.format.expert_feature` (BEV raster, route progress, nearest Think2Drive action).
    """

    def __init__(
        self,
        world_map: Map,
        route: Sequence[tuple[Waypoint, RoadOption]],
        config: RigConfig,
        expert_assessment: bool = True,
    ) -> None:
        if not route:
            raise ValueError("the data agent needs a non-empty dense route")
        self.map = world_map
        self.config = config
        xy = [(wp.transform.location.x, wp.transform.location.y) for wp, _ in route]
        commands = [RoadOption(c) for _, c in route]
        self.planners = CommandPlanners.from_dense_route(xy, commands)
        self.route_xy = np.asarray(xy, dtype=np.float64)
        self._route_index = 0
        self._bev = BevRasterizer(world_map) if expert_assessment else None

    def _advance_route_index(self, x: float, y: float) -> int:
        """Nearest route point among the next 40 m (never moving backwards)."""
        window = self.route_xy[self._route_index : self._route_index + 40]
        offset = int(np.argmin(np.hypot(window[:, 0] - x, window[:, 1] - y)))
        self._route_index += offset
        return self._route_index

    def make_record(
        self, index: int, snapshot: Snapshot, sensors: SensorData, ego_id: int, expert_state: Any = None
    ) -> FrameRecord:
        """The FrameRecord of frame ``index`` (consecutive from 0)."""
        ego = snapshot.actors.get(ego_id)
        if ego is None:
            raise SimulatorError(f"ego actor {ego_id} is not in snapshot {snapshot.frame}")
        gps = sensors.gnss
        gnss = self.map.geolocation_to_location(gps.latitude, gps.longitude, gps.altitude)
        points = self.planners.run_step(gnss.x, gnss.y)
        plan = PlannerFields(
            x_command_far=points.far.x, y_command_far=points.far.y, command_far=int(points.far.command),
            x_command_near=points.near.x, y_command_near=points.near.y, command_near=int(points.near.command),
            x_target=points.target.x, y_target=points.target.y, next_command=int(points.target.command),
        )  # fmt: skip
        start = self._advance_route_index(ego.location.x, ego.location.y)
        route_ahead = self.route_xy[start : start + _ROUTE_LOOKAHEAD]
        should_brake = bool(getattr(expert_state, "should_brake", False))
        only_ap_brake = bool(getattr(expert_state, "only_ap_brake", False))
        anno = build_annotation(
            self.map,
            snapshot,
            ego,
            sensors,
            self.config,
            plan,
            (gnss.x, gnss.y),
            should_brake,
            only_ap_brake,
            route_ahead,
        )
        expert = None
        if self._bev is not None:
            progress = start / max(len(self.route_xy) - 1, 1)
            expert = assessment_vector(self._bev, snapshot, ego, route_ahead, progress, anno)
        return FrameRecord(
            index=index,
            anno=anno,
            cameras=dict(sensors.cameras),
            lidar=sensors.lidar if self.config.lidar else None,
            radar=dict(sensors.radar) if self.config.radar else None,
            expert_assessment=expert,
        )
