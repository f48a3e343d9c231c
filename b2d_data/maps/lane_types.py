"""CARLA's lane enums (LaneType, LaneChange, LaneMarkingType/Color) and the LaneMarking record.

Values are CARLA 0.9.15's (``carla.LaneType`` is a bit set, so masks like ``DRIVING | SIDEWALK`` work). Member
names are upper case; ``carla_name`` gives CARLA's own spelling, which is what ``str()`` of a CARLA enum prints and
what the Bench2Drive HD map stores (``'Broken'``, ``'SolidSolid'``, ``'NONE'``, ``'White'``...).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum, IntFlag


class LaneType(IntFlag):
    """carla.LaneType (OpenDRIVE lane ``type``)."""

    NONE = 0x1
    DRIVING = 0x1 << 1
    STOP = 0x1 << 2
    SHOULDER = 0x1 << 3
    BIKING = 0x1 << 4
    SIDEWALK = 0x1 << 5
    BORDER = 0x1 << 6
    RESTRICTED = 0x1 << 7
    PARKING = 0x1 << 8
    BIDIRECTIONAL = 0x1 << 9
    MEDIAN = 0x1 << 10
    SPECIAL1 = 0x1 << 11
    SPECIAL2 = 0x1 << 12
    SPECIAL3 = 0x1 << 13
    ROADWORKS = 0x1 << 14
    TRAM = 0x1 << 15
    RAIL = 0x1 << 16
    ENTRY = 0x1 << 17
    EXIT = 0x1 << 18
    OFFRAMP = 0x1 << 19
    ONRAMP = 0x1 << 20
    # carla.LaneType.Any is 0xFFFFFFFE: every type except NONE.
    ANY = 0xFFFFFFFE

    @property
    def carla_name(self) -> str:
        """CARLA's spelling (``Driving``, ``Sidewalk``, ``NONE``...)."""
        return _LANE_TYPE_CARLA_NAMES.get(self, self.name or str(int(self)))


_LANE_TYPE_CARLA_NAMES = {
    LaneType.NONE: "NONE", LaneType.DRIVING: "Driving", LaneType.STOP: "Stop", LaneType.SHOULDER: "Shoulder",
    LaneType.BIKING: "Biking", LaneType.SIDEWALK: "Sidewalk", LaneType.BORDER: "Border",
    LaneType.RESTRICTED: "Restricted", LaneType.PARKING: "Parking", LaneType.BIDIRECTIONAL: "Bidirectional",
    LaneType.MEDIAN: "Median", LaneType.SPECIAL1: "Special1", LaneType.SPECIAL2: "Special2",
    LaneType.SPECIAL3: "Special3", LaneType.ROADWORKS: "RoadWorks", LaneType.TRAM: "Tram", LaneType.RAIL: "Rail",
    LaneType.ENTRY: "Entry", LaneType.EXIT: "Exit", LaneType.OFFRAMP: "OffRamp", LaneType.ONRAMP: "OnRamp",
    LaneType.ANY: "Any",
}  # fmt: skip

#: OpenDRIVE lane ``type`` strings (lower-cased) → LaneType; CARLA maps anything unknown to NONE.
_LANE_TYPE_BY_XODR = {
    "none": LaneType.NONE, "driving": LaneType.DRIVING, "stop": LaneType.STOP, "shoulder": LaneType.SHOULDER,
    "biking": LaneType.BIKING, "sidewalk": LaneType.SIDEWALK, "walking": LaneType.SIDEWALK,
    "border": LaneType.BORDER, "restricted": LaneType.RESTRICTED, "parking": LaneType.PARKING,
    "bidirectional": LaneType.BIDIRECTIONAL, "median": LaneType.MEDIAN, "special1": LaneType.SPECIAL1,
    "special2": LaneType.SPECIAL2, "special3": LaneType.SPECIAL3, "roadworks": LaneType.ROADWORKS,
    "tram": LaneType.TRAM, "rail": LaneType.RAIL, "entry": LaneType.ENTRY, "exit": LaneType.EXIT,
    "offramp": LaneType.OFFRAMP, "onramp": LaneType.ONRAMP,
}  # fmt: skip


def lane_type_from_xodr(text: str) -> LaneType:
    """Map an OpenDRIVE lane ``type`` attribute to :class:`LaneType` (unknown → NONE, as CARLA does)."""
    return _LANE_TYPE_BY_XODR.get(text.strip().lower(), LaneType.NONE)


class LaneChange(IntFlag):
    """carla.LaneChange: which lane changes a marking allows, relative to the driving direction."""

    NONE = 0x0
    RIGHT = 0x1
    LEFT = 0x2
    BOTH = 0x3

    @property
    def carla_name(self) -> str:
        """CARLA's spelling."""
        return {0: "NONE", 1: "Right", 2: "Left", 3: "Both"}[int(self)]


def lane_change_from_xodr(text: str | None) -> LaneChange:
    """Map a roadMark ``laneChange`` attribute the way CARLA does.

    CARLA stores OpenDRIVE's increase/decrease as 0x1/0x2 and reinterprets them as Right/Left; a missing or
    unknown value means "both" (OpenDRIVE's default).
    """
    value = (text or "both").strip().lower()
    return {"none": LaneChange.NONE, "increase": LaneChange.RIGHT, "decrease": LaneChange.LEFT}.get(
        value, LaneChange.BOTH
    )


class LaneMarkingType(IntEnum):
    """carla.LaneMarkingType."""

    OTHER = 0
    BROKEN = 1
    SOLID = 2
    SOLIDSOLID = 3
    SOLIDBROKEN = 4
    BROKENSOLID = 5
    BROKENBROKEN = 6
    BOTTSDOTS = 7
    GRASS = 8
    CURB = 9
    NONE = 10

    @property
    def carla_name(self) -> str:
        """CARLA's spelling, as stored in the HD map's ``Type`` field."""
        return _MARKING_TYPE_CARLA_NAMES[self]


_MARKING_TYPE_CARLA_NAMES = {
    LaneMarkingType.OTHER: "Other", LaneMarkingType.BROKEN: "Broken", LaneMarkingType.SOLID: "Solid",
    LaneMarkingType.SOLIDSOLID: "SolidSolid", LaneMarkingType.SOLIDBROKEN: "SolidBroken",
    LaneMarkingType.BROKENSOLID: "BrokenSolid", LaneMarkingType.BROKENBROKEN: "BrokenBroken",
    LaneMarkingType.BOTTSDOTS: "BottsDots", LaneMarkingType.GRASS: "Grass", LaneMarkingType.CURB: "Curb",
    LaneMarkingType.NONE: "NONE",
}  # fmt: skip

_MARKING_TYPE_BY_XODR = {
    "broken": LaneMarkingType.BROKEN, "solid": LaneMarkingType.SOLID, "solid solid": LaneMarkingType.SOLIDSOLID,
    "solid broken": LaneMarkingType.SOLIDBROKEN, "broken solid": LaneMarkingType.BROKENSOLID,
    "broken broken": LaneMarkingType.BROKENBROKEN, "botts dots": LaneMarkingType.BOTTSDOTS,
    "grass": LaneMarkingType.GRASS, "curb": LaneMarkingType.CURB, "none": LaneMarkingType.NONE,
}  # fmt: skip


def marking_type_from_xodr(text: str | None) -> LaneMarkingType:
    """Map a roadMark ``type`` attribute (unknown → OTHER, as CARLA does)."""
    return _MARKING_TYPE_BY_XODR.get((text or "none").strip().lower(), LaneMarkingType.OTHER)


class LaneMarkingColor(IntEnum):
    """carla.LaneMarkingColor (``Standard`` is the same value as ``White``)."""

    WHITE = 0
    BLUE = 1
    GREEN = 2
    RED = 3
    YELLOW = 4
    OTHER = 5
    STANDARD = 0

    @property
    def carla_name(self) -> str:
        """CARLA's spelling (``White`` for standard/white)."""
        return {0: "White", 1: "Blue", 2: "Green", 3: "Red", 4: "Yellow", 5: "Other"}[int(self)]


def marking_color_from_xodr(text: str | None) -> LaneMarkingColor:
    """Map a roadMark ``color`` attribute (standard/white → WHITE; unknown → OTHER)."""
    value = (text or "standard").strip().lower()
    return {
        "standard": LaneMarkingColor.WHITE, "white": LaneMarkingColor.WHITE, "blue": LaneMarkingColor.BLUE,
        "green": LaneMarkingColor.GREEN, "red": LaneMarkingColor.RED, "yellow": LaneMarkingColor.YELLOW,
    }.get(value, LaneMarkingColor.OTHER)  # fmt: skip


@dataclass(frozen=True, slots=True)
class LaneMarking:
    """carla.LaneMarking: the marking on one side of a lane.

    ``lane_change`` is the raw OpenDRIVE permission of the marking (CARLA does not turn it to the driving
    direction here; ``Waypoint.lane_change`` does).
    """

    type: LaneMarkingType
    color: LaneMarkingColor
    width: float
    lane_change: LaneChange
