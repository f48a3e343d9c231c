"""carla.Waypoint: a point on a lane centre line, frozen and hashable.

Two waypoints are equal when they lie on the same (road, section, lane) at the same ``s`` of the same map; the
other fields are derived from those four. Navigation methods (``next``, ``previous``, neighbours) delegate to the
:class:`~b2d_data.maps.map.Map` that made the waypoint and follow CARLA 0.9.15's ``carla::road::Map`` rules.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from b2d_data.format.transform import Transform
from b2d_data.maps.lane_types import LaneChange, LaneMarking, LaneType

if TYPE_CHECKING:
    from b2d_data.maps.junction import Junction
    from b2d_data.maps.map import Map


@dataclass(frozen=True, slots=True, eq=False)
class Waypoint:
    """A lane-centre pose with CARLA's attributes (CARLA frame; ``transform.rotation.yaw`` follows traffic).

    ``left_lane_marking`` / ``right_lane_marking`` are ``None`` where the file gives no road mark, as in CARLA.
    """

    road_id: int
    section_id: int
    lane_id: int
    s: float
    transform: Transform
    lane_width: float
    lane_type: LaneType
    is_junction: bool
    junction_id: int
    lane_change: LaneChange
    left_lane_marking: LaneMarking | None
    right_lane_marking: LaneMarking | None
    map: Map = field(repr=False)
    segment: int = field(repr=False)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Waypoint):
            return NotImplemented
        return (
            self.s == other.s
            and self.segment == other.segment
            and self.lane_id == other.lane_id
            and self.map is other.map
        )

    def __hash__(self) -> int:
        return hash((self.road_id, self.section_id, self.lane_id, self.s))

    def __reduce__(self):
        # Pickle as (map, segment, s) so that worker processes rebuild the waypoint from their own map copy.
        return (_rebuild, (self.map, self.segment, self.s))

    @property
    def id(self) -> int:
        """A stable integer identifying (road, section, lane, s), like ``carla.Waypoint.id``."""
        return hash((self.road_id, self.section_id, self.lane_id, self.s)) & 0xFFFFFFFFFFFFFFFF

    @property
    def is_intersection(self) -> bool:
        """CARLA's deprecated alias of :attr:`is_junction` (gen_hdmap.py still uses it)."""
        return self.is_junction

    @property
    def location(self):
        """Shortcut for ``transform.location``."""
        return self.transform.location

    def next(self, distance: float) -> list[Waypoint]:
        """Waypoints ``distance`` metres ahead along the lane; several after a branching lane end."""
        return self.map._step(self, distance, forward=True)

    def previous(self, distance: float) -> list[Waypoint]:
        """Waypoints ``distance`` metres behind; several where lanes merge into this one."""
        return self.map._step(self, distance, forward=False)

    def next_until_lane_end(self, distance: float) -> list[Waypoint]:
        """Waypoints every ``distance`` metres up to the end of this road's lane (last one at the end)."""
        return self.map._until_road_end(self, distance, forward=True)

    def previous_until_lane_start(self, distance: float) -> list[Waypoint]:
        """Waypoints every ``distance`` metres back to the start of this road's lane (last one at the start)."""
        return self.map._until_road_end(self, distance, forward=False)

    def get_left_lane(self) -> Waypoint | None:
        """The lane to the left of the driving direction (across the centre line for lanes ±1), or ``None``."""
        lane = -self.lane_id if abs(self.lane_id) == 1 else (self.lane_id - 1 if self.lane_id > 0 else self.lane_id + 1)
        return self.map._neighbour(self, lane)

    def get_right_lane(self) -> Waypoint | None:
        """The lane to the right of the driving direction, or ``None``."""
        lane = self.lane_id + 1 if self.lane_id > 0 else self.lane_id - 1
        return self.map._neighbour(self, lane)

    def get_junction(self) -> Junction | None:
        """The junction this waypoint lies in, or ``None``."""
        return self.map.junctions.get(self.junction_id) if self.is_junction else None


def _rebuild(map_: Map, segment: int, s: float) -> Waypoint:
    return map_._waypoint_at(segment, s)
