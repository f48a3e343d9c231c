"""Self-checks of generated OpenDRIVE: references resolve, reference lines are continuous, joined lanes meet.

``validate_xodr(text)`` reads the file back with ``xodr_reader`` (not the in-memory town) and returns a list of
human-readable problems, empty when the file is sound.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

from lxml import etree

from b2d_data.maps.towngen.geometry import Segment, advance, wrap_angle
from b2d_data.maps.towngen.model import LaneSection, Road, Town, poly_at
from b2d_data.maps.towngen.xodr_reader import read_town, written_segments

#: Joined lanes must meet within this distance (metres) and width difference.
JOIN_TOL = 0.01
#: Reference-line geometries must chain within this distance (metres) and heading (radians).
CHAIN_TOL = 1e-3
CHAIN_HDG_TOL = 1e-4
#: Junction lanes must turn no tighter than this (metres, lane centre).
MIN_TURN_RADIUS = 6.0


@dataclass(frozen=True)
class LanePoint:
    """A lane's centre point, width and driving-axis heading at one s."""

    x: float
    y: float
    z: float
    width: float
    hdg: float


def lane_point(road: Road, lane_id: int, s: float, section: LaneSection | None = None) -> LanePoint:
    """Centre point, width and heading of a lane at ``s`` (heading of the reference line, not the driving direction)."""
    inner, outer = road.lane_borders(s, lane_id, section)
    pose = road.pose_at(s)
    x, y = pose.offset(0.5 * (inner + outer))
    return LanePoint(x, y, poly_at(road.elevation, s), abs(outer - inner), pose.hdg)


def _end_s(road: Road, contact: str | None) -> float:
    return road.length if contact == "end" else 0.0


class _Checker:
    def __init__(self, town: Town, segments: dict[int, list[Segment]] | None = None) -> None:
        self.town = town
        self.segments = segments or {}
        self.roads = {r.id: r for r in town.roads}
        self.junctions = {j.id: j for j in town.junctions}
        self.problems: list[str] = []

    def fail(self, msg: str) -> None:
        """Record a problem."""
        self.problems.append(msg)

    def run(self) -> list[str]:
        """Run every check; the problems found."""
        self.unique_ids()
        for road in self.town.roads:
            self.chain(road)
            self.sections(road)
            self.road_links(road)
        self.junction_links()
        self.signals()
        self.dead_ends()
        return self.problems

    def unique_ids(self) -> None:
        """Roads and junctions share one id space."""
        counts = Counter(r.id for r in self.town.roads)
        counts.update(j.id for j in self.town.junctions)
        for dup, n in counts.items():
            if n > 1:
                self.fail(f"id {dup} is used by {n} roads/junctions")

    def chain(self, road: Road) -> None:
        """Each geometry starts where the previous one ends (s, position, heading)."""
        segs = self.segments.get(road.id) or road.line.segments()
        s = 0.0
        for seg in segs:
            if abs(seg.s - s) > CHAIN_TOL:
                self.fail(f"road {road.id}: geometry starts at s={seg.s:.4f}, the previous ones end at {s:.4f}")
            s += seg.prim.length
        for a, b in zip(segs[:-1], segs[1:], strict=True):
            end = advance(a.start, a.prim, a.prim.length)
            if (
                math.hypot(end.x - b.start.x, end.y - b.start.y) > CHAIN_TOL
                or abs(wrap_angle(end.hdg - b.start.hdg)) > CHAIN_HDG_TOL
            ):
                self.fail(f"road {road.id}: geometry at s={b.s:.3f} does not continue the previous one")
        for seg in segs:
            if seg.prim.length <= 0:
                self.fail(f"road {road.id}: geometry at s={seg.s:.3f} has length {seg.prim.length}")

    def sections(self, road: Road) -> None:
        """Lane sections start at 0, number their lanes 1..n / -1..-n, and linked lanes meet across boundaries."""
        if not road.sections or abs(road.sections[0].s) > 1e-9:
            self.fail(f"road {road.id}: first lane section must start at s=0")
            return
        for a, b in zip(road.sections[:-1], road.sections[1:], strict=True):
            for lane in (*a.left, *a.right):
                if lane.successor is not None and not b.has_lane(lane.successor):
                    self.fail(f"road {road.id}: lane {lane.id} at s={a.s:.1f} links to missing lane {lane.successor}")
                elif lane.successor is not None:
                    where = f"road {road.id} section s={b.s:.1f}"
                    self.meet(road, lane.id, b.s, road, lane.successor, b.s, where, a, b)
        for sec in road.sections:
            ids = [lane.id for lane in sec.left] + [lane.id for lane in sec.right]
            left = sorted(lane.id for lane in sec.left)
            right = sorted((lane.id for lane in sec.right), reverse=True)
            if (
                left != list(range(1, len(left) + 1))
                or right != list(range(-1, -len(right) - 1, -1))
                or len(set(ids)) != len(ids)
            ):
                self.fail(f"road {road.id}: lane ids of section s={sec.s:.1f} are not 1..n / -1..-n")

    def meet(
        self,
        ra: Road,
        la: int,
        sa: float,
        rb: Road,
        lb: int,
        sb: float,
        where: str,
        sec_a: LaneSection | None = None,
        sec_b: LaneSection | None = None,
    ) -> None:
        """Two lane ends that should join: same centre point, width and height, parallel."""
        try:
            a, b = lane_point(ra, la, sa, sec_a), lane_point(rb, lb, sb, sec_b)
        except KeyError as err:
            self.fail(f"{where}: {err}")
            return
        gap = math.hypot(a.x - b.x, a.y - b.y)
        if gap > JOIN_TOL:
            self.fail(f"{where}: lane {ra.id}/{la} and lane {rb.id}/{lb} are {gap:.3f} m apart")
        if abs(a.width - b.width) > JOIN_TOL:
            self.fail(f"{where}: lane {ra.id}/{la} width {a.width:.3f} m meets {rb.id}/{lb} width {b.width:.3f} m")
        if abs(a.z - b.z) > JOIN_TOL:
            self.fail(f"{where}: lane {ra.id}/{la} and {rb.id}/{lb} differ in height by {abs(a.z - b.z):.3f} m")
        if abs(math.sin(a.hdg - b.hdg)) > math.sin(math.radians(1.0)):
            self.fail(f"{where}: lane {ra.id}/{la} and {rb.id}/{lb} meet at an angle")

    def road_links(self, road: Road) -> None:
        """Road links resolve and the linked lanes meet."""
        for which, link in (("predecessor", road.predecessor), ("successor", road.successor)):
            if link is None:
                continue
            if link.element_type == "junction":
                if link.element_id not in self.junctions:
                    self.fail(f"road {road.id}: {which} junction {link.element_id} does not exist")
                continue
            other = self.roads.get(link.element_id)
            if other is None or link.element_type != "road":
                self.fail(f"road {road.id}: {which} {link.element_type} {link.element_id} does not exist")
                continue
            if link.contact not in ("start", "end"):
                self.fail(f"road {road.id}: {which} road link without a contact point")
                continue
            s_here = 0.0 if which == "predecessor" else road.length
            sec = road.section_at(s_here) if which == "successor" else road.sections[0]
            s_there = _end_s(other, link.contact)
            other_sec = other.end_section(link.contact)
            for lane in (*sec.left, *sec.right):
                target = lane.predecessor if which == "predecessor" else lane.successor
                if target is None:
                    continue
                if not other_sec.has_lane(target):
                    self.fail(f"road {road.id}: lane {lane.id} {which} {target} missing on road {other.id}")
                    continue
                self.meet(road, lane.id, s_here, other, target, s_there, f"road {road.id} {which} road {other.id}")

    def junction_links(self) -> None:
        """Connections name existing roads and lanes, agree with the lane links, and turn smoothly."""
        for j in self.town.junctions:
            for con in j.connections:
                inc, conn = self.roads.get(con.incoming), self.roads.get(con.connecting)
                if inc is None or conn is None:
                    self.fail(f"junction {j.id} connection {con.id}: road {con.incoming} or {con.connecting} missing")
                    continue
                if conn.junction != j.id:
                    self.fail(f"junction {j.id}: connecting road {conn.id} has junction={conn.junction}")
                if conn.predecessor is None or conn.predecessor.element_id != inc.id:
                    self.fail(f"junction {j.id}: connecting road {conn.id} does not start at incoming road {inc.id}")
                    continue
                for a, b in con.lane_links:
                    sec = inc.end_section(conn.predecessor.contact or "start")
                    if not sec.has_lane(a) or not conn.sections[0].has_lane(b):
                        self.fail(f"junction {j.id} connection {con.id}: lane link {a}->{b} names a missing lane")
                        continue
                    if conn.sections[0].lane(b).predecessor != a:
                        where = f"junction {j.id} connection {con.id}"
                        self.fail(f"{where}: lane link {a}->{b} disagrees with the lane's predecessor")
                self.turn_radius(conn)

    def turn_radius(self, road: Road) -> None:
        """Driving lanes of a connecting road turn no tighter than ``MIN_TURN_RADIUS`` (three-point circles)."""
        for lane in road.sections[0].right:
            if lane.type != "driving":
                continue
            n = max(4, math.ceil(road.length / 0.5))
            pts = [lane_point(road, lane.id, road.length * i / n) for i in range(n + 1)]
            for p, q, r in zip(pts, pts[1:], pts[2:], strict=False):
                a, b, c = (
                    math.dist((p.x, p.y), (q.x, q.y)),
                    math.dist((q.x, q.y), (r.x, r.y)),
                    math.dist((p.x, p.y), (r.x, r.y)),
                )
                area2 = abs((q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x))
                if area2 > 1e-12 and a * b * c / (2.0 * area2) < MIN_TURN_RADIUS:
                    self.fail(f"connecting road {road.id} lane {lane.id}: turns tighter than {MIN_TURN_RADIUS} m")
                    return

    def signals(self) -> None:
        """Signals sit on their road and lanes; controllers and junctions name existing signals/controllers."""
        signals = {s.id for r in self.town.roads for s in r.signals}
        for r in self.town.roads:
            for sig in r.signals:
                if not 0.0 <= sig.s <= r.length:
                    self.fail(f"road {r.id}: signal {sig.id} at s={sig.s:.2f} is off the road")
                sec = r.section_at(sig.s)
                for lane_id in range(sig.valid_from, sig.valid_to + 1):
                    if lane_id != 0 and not sec.has_lane(lane_id):
                        self.fail(f"road {r.id}: signal {sig.id} is valid for missing lane {lane_id}")
        controllers = {c.id for c in self.town.controllers}
        for c in self.town.controllers:
            for sid in c.signal_ids:
                if sid not in signals:
                    self.fail(f"controller {c.id}: missing signal {sid}")
        for j in self.town.junctions:
            for cid in j.controllers:
                if cid not in controllers:
                    self.fail(f"junction {j.id}: missing controller {cid}")

    def dead_ends(self) -> None:
        """Every driving lane that carries traffic to a road end must continue (a link or a junction connection)."""
        from_junction: set[tuple[int, int]] = set()
        for j in self.town.junctions:
            for con in j.connections:
                for a, _ in con.lane_links:
                    from_junction.add((con.incoming, a))
        for road in self.town.roads:
            if road.junction != -1:
                continue
            checks = (
                (road.successor, road.sections[-1].right, road.length),
                (road.predecessor, road.sections[0].left, 0.0),
            )
            for link, lanes, s in checks:
                for lane in lanes:
                    if lane.type != "driving" or lane_point(road, lane.id, s).width < 0.5:
                        continue
                    ok = (
                        link is not None
                        and link.element_type == "road"
                        and (lane.successor if s else lane.predecessor) is not None
                    ) or (link is not None and link.element_type == "junction" and (road.id, lane.id) in from_junction)
                    if not ok:
                        self.fail(f"road {road.id}: driving lane {lane.id} dead-ends at s={s:.1f}")


def validate_town(town: Town, segments: dict[int, list[Segment]] | None = None) -> list[str]:
    """Problems found in a town read back from OpenDRIVE (empty list: sound).

    ``segments`` (road id -> geometries as written) lets the chain check use the file's own start poses.
    """
    return _Checker(town, segments).run()


def validate_xodr(text: str) -> list[str]:
    """Problems found in OpenDRIVE text written by this generator (empty list: sound)."""
    root = etree.fromstring(text.encode("utf-8"))
    segments = {int(el.get("id")): written_segments(el) for el in root.findall("road")}
    return validate_town(read_town(text), segments)
