"""carla.Junction: id, axis-aligned bounding box and the (entry, exit) waypoints of its lanes."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from b2d_data.format.transform import BoundingBox, Transform
from b2d_data.maps.lane_types import LaneType

if TYPE_CHECKING:
    from b2d_data.maps.map import Map
    from b2d_data.maps.waypoint import Waypoint


@dataclass(frozen=True, eq=False)
class Junction:
    """A junction. ``bounding_box.location`` is the world centre (rotation 0), extents are half sizes."""

    id: int
    name: str
    bounding_box: BoundingBox
    connecting_roads: tuple[int, ...]
    controller_ids: tuple[str, ...]
    map: Map = field(repr=False)

    @property
    def transform(self) -> Transform:
        """A transform at the bounding-box centre."""
        return Transform(self.bounding_box.location)

    def get_waypoints(self, lane_type: LaneType = LaneType.DRIVING) -> list[tuple[Waypoint, Waypoint]]:
        """(start, end) waypoints, in driving direction, of every lane of the given type inside the junction."""
        return self.map._junction_waypoints(self, lane_type)

    def __hash__(self) -> int:
        return hash(("junction", self.id))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Junction) and other.id == self.id and other.map is self.map
