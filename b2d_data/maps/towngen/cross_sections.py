"""Road cross-sections (lane stacks per side with widths and markings) and their seeded variants."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class MarkStyle:
    """A road-mark style: type, colour, line width, permitted lane change across it."""

    type: str
    color: str = "white"
    width: float = 0.125
    lane_change: str = "none"


NO_MARK = MarkStyle("none", "white", 0.0, "none")
CURB = MarkStyle("curb", "white", 0.15, "none")
SOLID_WHITE = MarkStyle("solid", "white", 0.125, "none")
BROKEN_WHITE = MarkStyle("broken", "white", 0.125, "both")
SOLID_YELLOW = MarkStyle("solid", "yellow", 0.125, "none")
BROKEN_YELLOW = MarkStyle("broken", "yellow", 0.125, "both")


@dataclass(frozen=True)
class LaneSpec:
    """One lane of a cross-section: type, width and the mark on its outer border."""

    type: str
    width: float
    mark: MarkStyle = NO_MARK


@dataclass(frozen=True)
class CrossSection:
    """A road's lanes per side, from the centre line outward; right lanes run along +s, left lanes against it."""

    name: str
    right: tuple[LaneSpec, ...]
    left: tuple[LaneSpec, ...]
    center_mark: MarkStyle
    speed_kmh: float
    road_type: str
    #: Priority when deciding which approaches of a junction are minor (higher wins).
    rank: int
    #: Constant lateral offset of the centre lane from the reference line (positive: left).
    lane_offset: float = 0.0
    #: Crosswalks are painted across this road at the junctions it enters.
    crosswalks: bool = False

    def side(self, right: bool) -> tuple[LaneSpec, ...]:
        """The lanes of one side, centre outward."""
        return self.right if right else self.left

    def driving_count(self, right: bool) -> int:
        """Number of driving lanes on one side."""
        return sum(1 for lane in self.side(right) if lane.type == "driving")

    def half_width(self, right: bool) -> float:
        """Distance from the reference line to the outer edge of one side."""
        total = sum(lane.width for lane in self.side(right))
        return total - self.lane_offset if right else total + self.lane_offset

    @property
    def max_half_width(self) -> float:
        """The wider of the two sides, measured from the reference line."""
        return max(self.half_width(True), self.half_width(False))


def _side(*lanes: LaneSpec) -> tuple[LaneSpec, ...]:
    """Put a curb mark on the lane just inside a sidewalk (CARLA marks the kerb on that border)."""
    out = list(lanes)
    for i in range(1, len(out)):
        if out[i].type == "sidewalk":
            out[i - 1] = replace(out[i - 1], mark=CURB)
    return tuple(out)


@dataclass(frozen=True)
class TownWidths:
    """Lane widths and speeds drawn once per town from the seed, so every road of a class looks the same."""

    street_lane: float
    boulevard_lane: float
    highway_lane: float
    rural_lane: float
    ramp_lane: float
    parking: float
    bike: float
    sidewalk: float
    gutter: float
    shoulder: float
    rural_shoulder: float
    highway_shoulder: float
    median: float
    street_speed: float
    boulevard_speed: float
    highway_speed: float
    rural_speed: float

    @classmethod
    def draw(cls, rng: np.random.Generator) -> TownWidths:
        """Draw a consistent set of widths (metres) and speeds (km/h)."""

        def pick(lo: float, hi: float) -> float:
            return round(float(rng.uniform(lo, hi)), 2)

        return cls(
            # CARLA's town streets are 3.5 m a lane (Town10HD, Town06; Town01 4 m). PDM-Lite's part-way overtake of a
            # parked car (60 % into the opposite lane) keeps 1.2 m from it there but only 0.8 m on a 3.1 m lane.
            street_lane=pick(3.3, 3.6),
            boulevard_lane=pick(3.25, 3.5),
            highway_lane=pick(3.5, 3.75),
            rural_lane=pick(3.4, 3.75),
            ramp_lane=pick(3.75, 4.0),
            parking=pick(2.2, 2.6),
            bike=pick(1.6, 2.0),
            sidewalk=pick(2.5, 3.5),
            gutter=pick(0.3, 0.5),
            shoulder=pick(1.0, 1.5),
            rural_shoulder=pick(1.2, 2.0),
            highway_shoulder=pick(2.5, 3.0),
            median=pick(1.0, 1.6),
            street_speed=float(rng.choice([40.0, 50.0])),
            boulevard_speed=float(rng.choice([50.0, 60.0])),
            highway_speed=float(rng.choice([90.0, 100.0])),
            rural_speed=float(rng.choice([70.0, 80.0, 90.0])),
        )


def street(w: TownWidths, parking: bool = False, shoulder: bool = False) -> CrossSection:
    """Two-way urban street, one lane each way, sidewalks; optional parking lanes or a wide shoulder on each side."""
    edge = SOLID_WHITE if (parking or shoulder) else NO_MARK
    lanes = [LaneSpec("driving", w.street_lane, edge)]
    if parking:
        lanes.append(LaneSpec("parking", w.parking, NO_MARK))
    elif shoulder:
        lanes.append(LaneSpec("shoulder", w.shoulder, NO_MARK))
    else:
        lanes.append(LaneSpec("shoulder", w.gutter, NO_MARK))
    lanes.append(LaneSpec("sidewalk", w.sidewalk, NO_MARK))
    side = _side(*lanes)
    name = "street_parking" if parking else "street_shoulder" if shoulder else "street"
    return CrossSection(name, side, side, BROKEN_YELLOW, w.street_speed, "town", rank=1, crosswalks=True)


def boulevard(w: TownWidths) -> CrossSection:
    """Divided urban road: median, two lanes each way, a bike lane and a sidewalk on each side."""
    side = _side(
        LaneSpec("median", w.median / 2.0, SOLID_YELLOW),
        LaneSpec("driving", w.boulevard_lane, BROKEN_WHITE),
        LaneSpec("driving", w.boulevard_lane, SOLID_WHITE),
        LaneSpec("biking", w.bike, NO_MARK),
        LaneSpec("sidewalk", w.sidewalk, NO_MARK),
    )
    return CrossSection("boulevard", side, side, NO_MARK, w.boulevard_speed, "town", rank=3, crosswalks=True)


def highway(w: TownWidths, lanes: int) -> CrossSection:
    """Divided motorway: median, ``lanes`` lanes each way, hard shoulders."""
    driving = [LaneSpec("driving", w.highway_lane, BROKEN_WHITE) for _ in range(lanes - 1)]
    driving.append(LaneSpec("driving", w.highway_lane, SOLID_WHITE))
    side = (
        LaneSpec("median", w.median / 2.0, SOLID_YELLOW),
        *driving,
        LaneSpec("shoulder", w.highway_shoulder, NO_MARK),
    )
    return CrossSection("highway", side, side, NO_MARK, w.highway_speed, "motorway", rank=4)


def ramp(w: TownWidths) -> CrossSection:
    """One-way single-lane ramp; the reference line runs down the lane's middle (a lane offset of half a lane)."""
    right = (
        LaneSpec("driving", w.ramp_lane, SOLID_WHITE),
        LaneSpec("shoulder", w.shoulder, NO_MARK),
    )
    left = (LaneSpec("shoulder", 0.5, NO_MARK),)
    return CrossSection("ramp", right, left, SOLID_YELLOW, 60.0, "motorway", rank=2, lane_offset=w.ramp_lane / 2.0)


def rural(w: TownWidths) -> CrossSection:
    """Interurban two-way road: one lane each way, paved shoulders, no sidewalks."""
    side = (
        LaneSpec("driving", w.rural_lane, SOLID_WHITE),
        LaneSpec("shoulder", w.rural_shoulder, NO_MARK),
    )
    return CrossSection("rural", side, side, BROKEN_YELLOW, w.rural_speed, "rural", rank=2)


def rural_minor(w: TownWidths) -> CrossSection:
    """A side road meeting the interurban road: narrower shoulders, lower speed."""
    side = (
        LaneSpec("driving", w.rural_lane, SOLID_WHITE),
        LaneSpec("shoulder", 0.5, NO_MARK),
    )
    return CrossSection("rural_minor", side, side, BROKEN_YELLOW, 50.0, "rural", rank=1)


def one_way(w: TownWidths, lanes: int = 2) -> CrossSection:
    """One-way urban street: ``lanes`` driving lanes along +s with a parking lane and a sidewalk on both kerbs.

    Every lane lies right of the reference line (ids -1..-n from the left kerb: sidewalk, parking, driving lanes,
    parking, sidewalk), as on CARLA Town12's one-way streets: walking left from the leftmost driving lane reaches
    the left parking lane and sidewalk without crossing the centre line (LB2.0's ``direction="left"``). The
    reference line runs along the left kerb's outer edge, the lane offset centres the road on it.
    """
    driving = [LaneSpec("driving", w.street_lane, BROKEN_WHITE) for _ in range(lanes - 1)]
    driving.append(LaneSpec("driving", w.street_lane, SOLID_WHITE))
    right = (
        LaneSpec("sidewalk", w.sidewalk, CURB),
        # the left edge line of the leftmost driving lane is this lane's outer border
        LaneSpec("parking", w.parking, SOLID_WHITE),
        *driving,
        LaneSpec("parking", w.parking, CURB),
        LaneSpec("sidewalk", w.sidewalk, NO_MARK),
    )
    total = sum(lane.width for lane in right)
    return CrossSection(
        "one_way", right, (), NO_MARK, w.street_speed, "town", rank=2, lane_offset=total / 2.0, crosswalks=True
    )
