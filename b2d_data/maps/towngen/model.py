"""In-memory OpenDRIVE records of a generated town, one dataclass per element the writer emits."""

from __future__ import annotations

from dataclasses import dataclass, field

from b2d_data.maps.towngen.geometry import Pose, RefLine


@dataclass(frozen=True)
class Poly3:
    """A cubic ``a + b ds + c ds^2 + d ds^3`` starting at ``s`` (relative to its parent's start)."""

    s: float
    a: float
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0

    def value(self, ds: float) -> float:
        """Value ``ds`` metres after the record's start."""
        return self.a + ds * (self.b + ds * (self.c + ds * self.d))

    def slope(self, ds: float) -> float:
        """First derivative ``ds`` metres after the record's start."""
        return self.b + ds * (2.0 * self.c + 3.0 * ds * self.d)


def smooth_step(s: float, length: float, start: float, end: float) -> Poly3:
    """A cubic going from ``start`` to ``end`` over ``length`` metres with zero slope at both ends."""
    delta = end - start
    return Poly3(s, start, 0.0, 3.0 * delta / length**2, -2.0 * delta / length**3)


def poly_at(records: list[Poly3] | tuple[Poly3, ...], s: float) -> float:
    """Evaluate a piecewise cubic (records sorted by ``s``) at ``s``."""
    current = records[0]
    for rec in records:
        if rec.s <= s + 1e-9:
            current = rec
    return current.value(s - current.s)


@dataclass(frozen=True)
class RoadMark:
    """A ``<roadMark>`` on a lane's outer border, from ``s_offset`` within its lane section."""

    s_offset: float
    type: str
    color: str = "white"
    width: float = 0.125
    lane_change: str = "none"


@dataclass
class Lane:
    """A ``<lane>``: id, type, width records and road marks, links to lanes of adjacent sections or roads."""

    id: int
    type: str
    widths: list[Poly3]
    marks: list[RoadMark] = field(default_factory=list)
    predecessor: int | None = None
    successor: int | None = None

    def width_at(self, ds: float) -> float:
        """Width ``ds`` metres into the lane section."""
        return poly_at(self.widths, ds)


@dataclass
class LaneSection:
    """A ``<laneSection>``; ``left`` holds ids 1..n and ``right`` ids -1..-n, both ordered from the centre out."""

    s: float
    left: list[Lane]
    right: list[Lane]
    center_marks: list[RoadMark]

    def lane(self, lane_id: int) -> Lane:
        """The lane with this id (KeyError when absent)."""
        for lane in (*self.left, *self.right):
            if lane.id == lane_id:
                return lane
        raise KeyError(lane_id)

    def has_lane(self, lane_id: int) -> bool:
        """True when the section holds a lane with this id."""
        return any(lane.id == lane_id for lane in (*self.left, *self.right))


@dataclass(frozen=True)
class Link:
    """A road's ``<predecessor>`` or ``<successor>``."""

    element_type: str
    element_id: int
    contact: str | None = None


@dataclass(frozen=True)
class Signal:
    """A ``<signal>`` (traffic light, stop sign, speed limit)."""

    id: int
    name: str
    s: float
    t: float
    type: str
    subtype: str
    dynamic: bool
    orientation: str
    valid_from: int
    valid_to: int
    value: float = -1.0
    unit: str | None = None
    country: str = "OpenDRIVE"
    z_offset: float = 0.0
    h_offset: float = 0.0
    height: float = 1.0
    width: float = 1.0
    text: str = ""


@dataclass(frozen=True)
class RoadObject:
    """An ``<object>`` with a local outline (crosswalks)."""

    id: int
    name: str
    type: str
    s: float
    t: float
    hdg: float
    length: float
    width: float
    outline: tuple[tuple[float, float], ...]
    orientation: str = "none"


@dataclass
class Road:
    """A ``<road>`` with its reference line, lanes, links, signals and objects."""

    id: int
    name: str
    line: RefLine
    sections: list[LaneSection]
    junction: int = -1
    predecessor: Link | None = None
    successor: Link | None = None
    road_type: str = "town"
    speed_kmh: float = 50.0
    lane_offset: list[Poly3] = field(default_factory=lambda: [Poly3(0.0, 0.0)])
    elevation: list[Poly3] = field(default_factory=lambda: [Poly3(0.0, 0.0)])
    signals: list[Signal] = field(default_factory=list)
    objects: list[RoadObject] = field(default_factory=list)

    @property
    def length(self) -> float:
        """Reference-line length."""
        return self.line.length

    def section_at(self, s: float) -> LaneSection:
        """The lane section holding ``s``."""
        current = self.sections[0]
        for sec in self.sections:
            if sec.s <= s + 1e-9:
                current = sec
        return current

    def end_section(self, contact: str) -> LaneSection:
        """The first (``start``) or last (``end``) lane section."""
        return self.sections[0] if contact == "start" else self.sections[-1]

    def pose_at(self, s: float) -> Pose:
        """Reference-line pose at ``s``."""
        return self.line.pose_at(s)

    def lane_borders(self, s: float, lane_id: int, section: LaneSection | None = None) -> tuple[float, float]:
        """(inner, outer) t of a lane's borders at ``s``, lane offset included (inner is nearer the centre).

        ``section`` picks the lane section explicitly (needed exactly at a section boundary, where ``s`` alone
        selects the later section).
        """
        sec = section if section is not None else self.section_at(s)
        ds = s - sec.s
        t = poly_at(self.lane_offset, s)
        side = sec.left if lane_id > 0 else sec.right
        sign = 1.0 if lane_id > 0 else -1.0
        for lane in side:
            w = lane.width_at(ds)
            if lane.id == lane_id:
                return t, t + sign * w
            t += sign * w
        raise KeyError(f"road {self.id} has no lane {lane_id} at s={s:.2f}")


@dataclass(frozen=True)
class Connection:
    """A junction ``<connection>`` with its lane links."""

    id: int
    incoming: int
    connecting: int
    contact: str
    lane_links: tuple[tuple[int, int], ...]


@dataclass
class Junction:
    """A ``<junction>``: its connections and the controllers of its traffic lights."""

    id: int
    name: str
    connections: list[Connection] = field(default_factory=list)
    controllers: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class Controller:
    """A top-level ``<controller>`` grouping the traffic lights that cycle together."""

    id: int
    name: str
    signal_ids: tuple[int, ...]


@dataclass
class Town:
    """Everything the writer needs for one OpenDRIVE file."""

    name: str
    preset: str
    seed: int
    roads: list[Road] = field(default_factory=list)
    junctions: list[Junction] = field(default_factory=list)
    controllers: list[Controller] = field(default_factory=list)


class IdAllocator:
    """One id space shared by roads, junctions, signals, objects and controllers (as in CARLA's towns)."""

    def __init__(self, start: int = 0) -> None:
        self._next = start

    def __call__(self) -> int:
        """The next free id."""
        value = self._next
        self._next += 1
        return value
