"""Junctions: connecting roads for every allowed movement, traffic lights, stop signs, crosswalks, sidewalk corners.

Every connecting road runs in its driving direction (lanes -1..-k) and its reference line is the inner (left) border
of the lanes it carries, so its start and end coincide with the borders of the lanes it joins; turns are a line-arc-line
fillet, lateral shifts and ramp merges a paramPoly3 (see ``paths.connector``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

from b2d_data.maps.towngen.cross_sections import CrossSection
from b2d_data.maps.towngen.geometry import Pose, RefLine, wrap_angle
from b2d_data.maps.towngen.model import (
    Connection,
    Controller,
    IdAllocator,
    Junction,
    Lane,
    LaneSection,
    Link,
    Poly3,
    Road,
    RoadMark,
    RoadObject,
    Signal,
    smooth_step,
)
from b2d_data.maps.towngen.paths import connector

logger = logging.getLogger(__name__)

#: Junction control kinds a node may ask for.
CONTROLS = ("signal", "stop_minor", "stop_all", "none")

#: Crosswalk band: gap from the junction edge and depth along the approach (metres).
CROSSWALK_GAP = 0.5
CROSSWALK_DEPTH = 3.0

#: Angles (degrees) separating straight movements from turns, and turns from U-turns.
STRAIGHT_LIMIT = 35.0
UTURN_LIMIT = 150.0


@dataclass(frozen=True)
class LaneEnd:
    """A lane at a junction end, in the arm's directional frame (incoming: heading into the junction)."""

    lane_id: int
    type: str
    width: float
    inner: float
    outer: float


@dataclass(frozen=True)
class Arm:
    """One road end touching a junction."""

    road: Road
    contact: str
    cs: CrossSection

    @property
    def end_s(self) -> float:
        """The s of the road end at the junction."""
        return self.road.length if self.contact == "end" else 0.0

    @property
    def in_frame(self) -> Pose:
        """Pose at the road end, heading into the junction."""
        pose = self.road.pose_at(self.end_s)
        return pose if self.contact == "end" else pose.reversed()

    @property
    def out_frame(self) -> Pose:
        """Pose at the road end, heading away from the junction."""
        return self.in_frame.reversed()

    def _side(self, right_side: bool, sign: float) -> list[LaneEnd]:
        sec = self.road.end_section(self.contact)
        if not right_side and not sec.left:
            return self._far_kerb(sign)
        out = []
        for lane in sec.right if right_side else sec.left:
            inner, outer = self.road.lane_borders(self.end_s, lane.id)
            out.append(LaneEnd(lane.id, lane.type, abs(outer - inner), sign * inner, sign * outer))
        return out

    def _far_kerb(self, sign: float) -> list[LaneEnd]:
        """A one-way road's left kerb (the lanes before its first driving lane, all right of the reference line) as the
        side facing the other way: centre outward, its borders swapped so that each lane lies right of its inner one."""
        sec = self.road.end_section(self.contact)
        kerb = []
        for lane in sec.right:
            if lane.type == "driving":
                break
            kerb.append(lane)
        out = []
        for lane in reversed(kerb):
            inner, outer = self.road.lane_borders(self.end_s, lane.id)
            out.append(LaneEnd(lane.id, lane.type, abs(outer - inner), sign * outer, sign * inner))
        return out

    def incoming(self) -> list[LaneEnd]:
        """Lanes whose traffic heads into the junction (driving ones carry traffic), centre outward."""
        return self._side(True, 1.0) if self.contact == "end" else self._side(False, -1.0)

    def outgoing(self) -> list[LaneEnd]:
        """Lanes whose traffic leaves the junction, centre outward."""
        return self._side(True, 1.0) if self.contact == "start" else self._side(False, -1.0)

    def incoming_driving(self) -> list[LaneEnd]:
        """Incoming driving lanes, centre outward."""
        return [lane for lane in self.incoming() if lane.type == "driving"]

    def outgoing_driving(self) -> list[LaneEnd]:
        """Outgoing driving lanes, centre outward."""
        return [lane for lane in self.outgoing() if lane.type == "driving"]

    def to_road_t(self, t_dir: float, incoming: bool) -> float:
        """Convert a t of the directional frame back to the road's own t."""
        same = (self.contact == "end") == incoming
        return t_dir if same else -t_dir


class JunctionBuilder:
    """Builds the connecting roads and furniture of junctions into a town's road list."""

    def __init__(self, ids: IdAllocator, roads: list[Road], controllers: list[Controller]) -> None:
        self.ids = ids
        self.roads = roads
        self.controllers = controllers

    # -- connecting roads -----------------------------------------------------------------------------------------

    def connect(
        self,
        junction: Junction,
        src: Arm,
        src_lanes: list[LaneEnd],
        dst: Arm,
        dst_lanes: list[LaneEnd],
    ) -> Road:
        """A connecting road carrying ``src_lanes`` (contiguous, centre outward) onto ``dst_lanes``."""
        if len(src_lanes) != len(dst_lanes):
            raise ValueError("a connecting road joins as many lanes as it carries")
        start = src.in_frame.shifted(src_lanes[0].inner)
        end = dst.out_frame.shifted(dst_lanes[0].inner)
        line = RefLine(start, connector(start, end))
        length = line.length
        lanes = []
        for i, (a, b) in enumerate(zip(src_lanes, dst_lanes, strict=True)):
            width = (
                [Poly3(0.0, a.width)] if abs(a.width - b.width) < 1e-9 else [smooth_step(0.0, length, a.width, b.width)]
            )
            lanes.append(
                Lane(-(i + 1), a.type, width, [RoadMark(0.0, "none", "white", 0.0, "none")], a.lane_id, b.lane_id)
            )
        road_id = self.ids()
        road = Road(
            id=road_id,
            name=f"Road {road_id}",
            line=line,
            sections=[LaneSection(0.0, [], lanes, [RoadMark(0.0, "none", "white", 0.0, "none")])],
            junction=junction.id,
            predecessor=Link("road", src.road.id, src.contact),
            successor=Link("road", dst.road.id, dst.contact),
            road_type=src.road.road_type,
            speed_kmh=min(src.road.speed_kmh, dst.road.speed_kmh),
        )
        self.roads.append(road)
        links = tuple((a.lane_id, -(i + 1)) for i, a in enumerate(src_lanes))
        junction.connections.append(Connection(len(junction.connections), src.road.id, road_id, "start", links))
        return road

    # -- ordinary junctions ---------------------------------------------------------------------------------------

    def build(self, junction: Junction, arms: list[Arm], control: str, major_heading: float | None) -> None:
        """Connecting roads, signals, crosswalks and sidewalk corners of a junction of two or more arms."""
        if control not in CONTROLS:
            raise ValueError(f"unknown junction control {control!r}; known: {', '.join(CONTROLS)}")
        self._controls(junction, arms, control, major_heading)
        for src in arms:
            lanes_in = src.incoming_driving()
            if not lanes_in:
                continue
            connected: set[int] = set()
            straight_dst: Arm | None = None
            for dst in arms:
                if dst is src or not dst.outgoing_driving():
                    continue
                turn = math.degrees(wrap_angle(dst.out_frame.hdg - src.in_frame.hdg))
                if abs(turn) > UTURN_LIMIT:
                    continue
                lanes_out = dst.outgoing_driving()
                if abs(turn) < STRAIGHT_LIMIT:
                    straight_dst = dst
                    k = min(len(lanes_in), len(lanes_out))
                    group_in, group_out = lanes_in[-k:], lanes_out[-k:]
                    bike_in, bike_out = (
                        self._bike_after(src.incoming(), group_in[-1]),
                        self._bike_after(dst.outgoing(), group_out[-1]),
                    )
                    carried_in, carried_out = list(group_in), list(group_out)
                    if bike_in is not None and bike_out is not None:
                        carried_in.append(bike_in)
                        carried_out.append(bike_out)
                    self.connect(junction, src, carried_in, dst, carried_out)
                    connected.update(lane.lane_id for lane in group_in)
                elif turn > 0:
                    self.connect(junction, src, [lanes_in[0]], dst, [lanes_out[0]])
                    connected.add(lanes_in[0].lane_id)
                else:
                    self.connect(junction, src, [lanes_in[-1]], dst, [lanes_out[-1]])
                    connected.add(lanes_in[-1].lane_id)
            # Lanes with no movement yet (more lanes in than out straight ahead) merge into the innermost lane ahead.
            for lane in lanes_in:
                if lane.lane_id not in connected and straight_dst is not None:
                    target = straight_dst.outgoing_driving()[0]
                    self.connect(junction, src, [lane], straight_dst, [target])
                elif lane.lane_id not in connected:
                    logger.warning(
                        "junction %d: lane %d of road %d has no exit", junction.id, lane.lane_id, src.road.id
                    )
        self._crosswalks(arms)
        self._verges(junction, arms)

    @staticmethod
    def _bike_after(lanes: list[LaneEnd], last_driving: LaneEnd) -> LaneEnd | None:
        idx = lanes.index(last_driving)
        if idx + 1 < len(lanes) and lanes[idx + 1].type == "biking":
            return lanes[idx + 1]
        return None

    def _controls(self, junction: Junction, arms: list[Arm], control: str, major_heading: float | None) -> None:
        """Place traffic lights or stop signs on the approaches (lights of a junction share one controller)."""
        if control == "none":
            return
        targets = [arm for arm in arms if arm.incoming_driving()]
        if control == "stop_minor":
            major = self._major_pair(arms, major_heading)
            targets = [arm for arm in targets if not any(arm is m for m in major)]
        placed: dict[int, Signal] = {}
        for arm in sorted(targets, key=lambda a: _ccw_angle(a.out_frame.hdg)):
            lanes = arm.incoming_driving()
            side = arm.incoming()
            # On the sidewalk just behind the kerb, else just beyond the paved edge (directional t is negative).
            t_dir = side[-1].inner - 0.5 if side[-1].type == "sidewalk" else side[-1].outer - 0.5
            # Half a metre before the junction, as CARLA places its lights; the trigger box sits ~3 m further back.
            s = arm.end_s - 0.5 if arm.contact == "end" else 0.5
            ids = [lane.lane_id for lane in lanes]
            common = dict(
                id=self.ids(),
                s=s,
                t=arm.to_road_t(t_dir, incoming=True),
                orientation="+" if arm.contact == "end" else "-",
                valid_from=min(ids),
                valid_to=max(ids),
            )
            if control == "signal":
                sig = Signal(
                    name="Signal_3Light_Post01", type="1000001", subtype="-1", dynamic=True,
                    height=1.16, width=0.52, z_offset=0.0, **common,
                )  # fmt: skip
            else:
                sig = Signal(
                    name="Sign_Stop", type="206", subtype="-1", dynamic=False,
                    height=0.97, width=0.97, z_offset=1.8, **common,
                )  # fmt: skip
            arm.road.signals.append(sig)
            placed[arm.road.id] = sig
        if control == "signal" and placed:
            ctrl_id = self.ids()
            self.controllers.append(Controller(ctrl_id, f"ctrl{ctrl_id}", tuple(sig.id for sig in placed.values())))
            junction.controllers.append(ctrl_id)

    @staticmethod
    def _major_pair(arms: list[Arm], major_heading: float | None) -> tuple[Arm, ...]:
        """The two roughly opposite arms of the main road (highest rank; ``major_heading`` breaks ties)."""
        best: tuple[Arm, ...] = ()
        best_key: tuple[float, float] = (-math.inf, -math.inf)
        for i, a in enumerate(arms):
            for b in arms[i + 1 :]:
                if abs(wrap_angle(a.out_frame.hdg - b.out_frame.hdg - math.pi)) > math.radians(30.0):
                    continue
                align = 0.0
                if major_heading is not None:
                    align = abs(math.cos(a.out_frame.hdg - major_heading))
                key = (min(a.cs.rank, b.cs.rank), align)
                if key > best_key:
                    best, best_key = (a, b), key
        return best

    def _crosswalks(self, arms: list[Arm]) -> None:
        for arm in arms:
            if not arm.cs.crosswalks:
                continue
            sec = arm.road.end_section(arm.contact)
            right_sw = [lane for lane in sec.right if lane.type == "sidewalk"]
            left_sw = [lane for lane in sec.left if lane.type == "sidewalk"]
            if not sec.left and len(right_sw) >= 2:
                # a one-way street: both sidewalks lie right of the reference line; the band spans between them
                t_left = arm.road.lane_borders(arm.end_s, right_sw[0].id)[1]
                t_right = arm.road.lane_borders(arm.end_s, right_sw[-1].id)[0]
            elif not right_sw or not left_sw:
                continue
            else:
                t_right = arm.road.lane_borders(arm.end_s, right_sw[0].id)[0]
                t_left = arm.road.lane_borders(arm.end_s, left_sw[0].id)[0]
            span = t_left - t_right
            # Object frame: hdg = pi/2 puts u across the road (+t) and v along -s; the band lies inside the junction.
            v_near, v_far = (-CROSSWALK_GAP, -CROSSWALK_GAP - CROSSWALK_DEPTH)
            if arm.contact == "start":
                v_near, v_far = -v_near, -v_far
            half = span / 2.0
            outline = ((half, v_near), (half, v_far), (-half, v_far), (-half, v_near), (half, v_near))
            arm.road.objects.append(
                RoadObject(self.ids(), "Crosswalk", "crosswalk", arm.end_s, 0.5 * (t_left + t_right), math.pi / 2.0,
                           span, CROSSWALK_DEPTH, outline)
            )  # fmt: skip

    def _verges(self, junction: Junction, arms: list[Arm]) -> None:
        """Non-driving edge lanes inside the junction: sidewalks round each corner, and along the open side of a T
        the whole verge (shoulder, parking, sidewalk...) when both arms carry the same lane types there."""
        order = sorted(arms, key=lambda a: _ccw_angle(a.out_frame.hdg))
        for i, a in enumerate(order):
            b = order[(i + 1) % len(order)]
            if a is b:
                continue
            gap = math.degrees((b.out_frame.hdg - a.out_frame.hdg) % (2.0 * math.pi))
            src, dst = _verge(a.incoming()), _verge(b.outgoing())
            if 160.0 < gap < 200.0 and src and [x.type for x in src] == [x.type for x in dst]:
                # No parking inside a junction: that strip is paved shoulder there.
                carried = [replace(x, type="shoulder") if x.type == "parking" else x for x in src]
                self.connect(junction, a, carried, b, dst)
            elif 60.0 < gap < 200.0 and src and dst and src[-1].type == dst[-1].type == "sidewalk":
                self.connect(junction, a, [src[-1]], b, [dst[-1]])

    # -- highway ramps --------------------------------------------------------------------------------------------

    def build_ramp(self, junction: Junction, kind: str, up: Arm, down: Arm, ramp: Arm, through: int) -> None:
        """A diverge (exit lane -> ramp) or merge (ramp -> acceleration lane) junction on a divided highway.

        ``through`` is the number of leading lanes (median and through driving lanes) that continue straight.
        """
        up_in, down_out = up.incoming(), down.outgoing()
        self.connect(junction, up, up_in[:through], down, down_out[:through])
        self.connect(junction, down, down.incoming(), up, up.outgoing())
        if kind == "diverge":
            self.connect(junction, up, [up_in[through]], ramp, [ramp.outgoing_driving()[0]])
        elif kind == "merge":
            self.connect(junction, ramp, [ramp.incoming_driving()[0]], down, [down_out[through]])
        else:
            raise ValueError(f"unknown ramp junction kind {kind!r}; known: diverge, merge")


def _ccw_angle(hdg: float) -> float:
    return hdg % (2.0 * math.pi)


def _verge(lanes: list[LaneEnd]) -> list[LaneEnd]:
    """The lanes outside the last driving or biking lane (the ones straight connecting roads do not carry)."""
    last = max((i for i, lane in enumerate(lanes) if lane.type in ("driving", "biking")), default=-1)
    return lanes[last + 1 :]
