"""Road-network plans (junction nodes, ramp nodes, edges) and the builder that turns a plan into OpenDRIVE records.

A plan places junction nodes, highway diverge/merge nodes and edges between them. Building it:
1. gives every junction node a radius from the widest road meeting there (plus room for crosswalks);
2. lays each edge's reference line from arm end to arm end (filleted polyline or solved line-turn-line) and cuts it
   into roads at its turns, linking the pieces road-to-road;
3. builds every junction's connecting roads, signals and furniture, and puts speed-limit signs on the roads.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

from b2d_data.maps.towngen.cross_sections import CrossSection
from b2d_data.maps.towngen.geometry import Pose, RefLine
from b2d_data.maps.towngen.junction_builder import Arm, JunctionBuilder
from b2d_data.maps.towngen.lanes import ExtraLaneSpan, build_sections, link_through
from b2d_data.maps.towngen.model import IdAllocator, Junction, Link, Poly3, Road, Signal, Town, smooth_step
from b2d_data.maps.towngen.paths import Corner, Path, line_turn_line, polyline_path

logger = logging.getLogger(__name__)

#: Roads shorter than this are not cut off a longer edge (tiny roads trouble parsers and samplers).
MIN_PIECE = 12.0

#: Only roads at least this long get a crest (keeps grades gentle: 3 m over 75 m is 6 % at most).
HILL_MIN_LENGTH = 150.0


@dataclass(frozen=True)
class NodeSpec:
    """A junction at (x, y) with its control; ``major_heading`` picks the main road when ranks tie."""

    name: str
    x: float
    y: float
    control: str = "none"
    major_heading: float | None = None


@dataclass(frozen=True)
class RampNodeSpec:
    """A diverge (off-ramp) or merge (on-ramp) junction centred at (x, y) on a highway running along ``hdg``.

    The junction spans ``length`` metres of highway. The ramp lane leaves (or joins) ``shift`` metres outside the
    right carriageway at an angle ``angle``. The exit/acceleration lane is full width for ``lane_full`` metres and
    tapers over ``lane_taper`` metres.
    """

    name: str
    kind: str
    x: float
    y: float
    hdg: float
    length: float = 40.0
    angle: float = math.radians(5.0)
    shift: float = 2.0
    lane_full: float = 80.0
    lane_taper: float = 60.0

    @property
    def center(self) -> Pose:
        """Centre pose on the highway reference line."""
        return Pose(self.x, self.y, self.hdg)


@dataclass(frozen=True)
class EdgeSpec:
    """A road between two nodes: its cross-section and shape.

    Shape: ``corners`` (a filleted polyline), or ``turn`` = (radius, spiral) for a line-turn-line solved between the
    two arm poses. ``heading_a``/``heading_b`` give the arm directions (pointing away from the node) where the shape
    does not imply them. ``port_a``/``port_b`` name the port at a ramp node (``up``, ``down``, ``ramp``). ``bump`` adds
    gentle S-bends (radians) on long straights, ``hill`` a gentle crest (metres) on long straight roads.
    """

    name: str
    a: str
    b: str
    section: CrossSection
    corners: tuple[Corner, ...] = ()
    turn: tuple[float, float] | None = None
    heading_a: float | None = None
    heading_b: float | None = None
    port_a: str = ""
    port_b: str = ""
    bump: float = 0.0
    hill: float = 0.0


@dataclass
class TownPlan:
    """Everything a town is built from."""

    name: str
    preset: str
    seed: int
    nodes: list[NodeSpec] = field(default_factory=list)
    ramps: list[RampNodeSpec] = field(default_factory=list)
    edges: list[EdgeSpec] = field(default_factory=list)

    def node(self, name: str) -> NodeSpec | RampNodeSpec:
        """The node or ramp node of that name."""
        for n in (*self.nodes, *self.ramps):
            if n.name == name:
                return n
        raise KeyError(f"plan has no node {name!r}")


def junction_radius(sections: list[CrossSection]) -> float:
    """Distance from a junction centre to where its roads end."""
    widest = max(cs.max_half_width for cs in sections)
    crosswalk = any(cs.crosswalks for cs in sections)
    # Room for the crosswalk band (urban) or for right turns of at least ~8 m lane radius (rural, ramps).
    return widest + (5.0 if crosswalk else 4.5)


def ramp_port(node: RampNodeSpec, port: str, highway: CrossSection, ramp: CrossSection) -> Pose:
    """Pose of a ramp node's port: where the upstream/downstream highway road or the ramp road meets the junction.

    Ramp poses are those of the ramp's reference line; they are placed so that the ramp lane's inner border lies
    ``shift`` metres outside the outermost through lane, which is where the exit/acceleration lane starts.
    """
    c = node.center
    half = node.length / 2.0
    if port == "up":
        return c.forward(-half)
    if port == "down":
        return c.forward(half)
    if port != "ramp":
        raise ValueError(f"unknown ramp port {port!r}; known: up, down, ramp")
    through = 0.0
    for lane in highway.right:
        if lane.type not in ("median", "driving"):
            break
        through += lane.width
    t_inner = highway.lane_offset - through - node.shift
    if node.kind == "diverge":
        base, hdg = c.forward(half), node.hdg - node.angle
    else:
        base, hdg = c.forward(-half), node.hdg + node.angle
    qx, qy = base.offset(t_inner)
    return Pose(qx, qy, hdg).shifted(-ramp.lane_offset)


class NetworkBuilder:
    """Builds a ``Town`` from a ``TownPlan``."""

    def __init__(self, plan: TownPlan) -> None:
        self.plan = plan
        self.ids = IdAllocator(0)
        self.town = Town(plan.name, plan.preset, plan.seed)
        self.junction_of: dict[str, Junction] = {}
        self.radius: dict[str, float] = {}
        self.arms: dict[str, list[Arm]] = {}
        self.ports: dict[str, dict[str, Arm]] = {}
        self.highway_cs: dict[str, CrossSection] = {}
        self.ramp_cs: dict[str, CrossSection] = {}

    def build(self) -> Town:
        """Lay out every edge and junction."""
        for node in (*self.plan.nodes, *self.plan.ramps):
            jid = self.ids()
            self.junction_of[node.name] = Junction(jid, f"junction{jid}")
        self._sizes()
        for edge in self.plan.edges:
            self._edge(edge)
        jb = JunctionBuilder(self.ids, self.town.roads, self.town.controllers)
        for node in self.plan.nodes:
            arms = self.arms.get(node.name, [])
            if len(arms) < 2:
                raise ValueError(f"node {node.name!r} has {len(arms)} road(s); a junction needs two or more")
            jb.build(self.junction_of[node.name], arms, node.control, node.major_heading)
        for rnode in self.plan.ramps:
            ports = self.ports.get(rnode.name, {})
            if set(ports) != {"up", "down", "ramp"}:
                raise ValueError(
                    f"ramp node {rnode.name!r} needs roads on ports up, down and ramp; has {sorted(ports)}"
                )
            through = sum(1 for lane in self.highway_cs[rnode.name].right if lane.type in ("median", "driving"))
            jb.build_ramp(self.junction_of[rnode.name], rnode.kind, ports["up"], ports["down"], ports["ramp"], through)
        self.town.junctions = [self.junction_of[n.name] for n in (*self.plan.nodes, *self.plan.ramps)]
        return self.town

    # -- sizes and arm poses --------------------------------------------------------------------------------------

    def _sizes(self) -> None:
        touching: dict[str, list[CrossSection]] = {}
        for e in self.plan.edges:
            touching.setdefault(e.a, []).append(e.section)
            touching.setdefault(e.b, []).append(e.section)
            for end, port in ((e.a, e.port_a), (e.b, e.port_b)):
                if port in ("up", "down"):
                    self.highway_cs[end] = e.section
                elif port == "ramp":
                    self.ramp_cs[end] = e.section
        for node in self.plan.nodes:
            self.radius[node.name] = junction_radius(touching.get(node.name, []))

    def _arm_heading(self, e: EdgeSpec, at_a: bool) -> float:
        given = e.heading_a if at_a else e.heading_b
        if given is not None:
            return given
        here = self.plan.node(e.a if at_a else e.b)
        if e.corners:
            c = e.corners[0] if at_a else e.corners[-1]
            return math.atan2(c.y - here.y, c.x - here.x)
        there = self.plan.node(e.b if at_a else e.a)
        if isinstance(there, RampNodeSpec):
            raise ValueError(f"edge {e.name!r}: give the arm heading at {here.name!r}")
        return math.atan2(there.y - here.y, there.x - here.x)

    def _end_pose(self, e: EdgeSpec, at_a: bool) -> Pose:
        """Reference-line pose where the edge meets node a (heading along the edge) or node b (heading into b)."""
        name, port = (e.a, e.port_a) if at_a else (e.b, e.port_b)
        node = self.plan.node(name)
        if isinstance(node, RampNodeSpec):
            pose = ramp_port(node, port, self.highway_cs[name], self.ramp_cs.get(name, e.section))
            return pose
        hdg = self._arm_heading(e, at_a)
        r = self.radius[name]
        pose = Pose(node.x + r * math.cos(hdg), node.y + r * math.sin(hdg), hdg)
        return pose if at_a else pose.reversed()

    # -- edges ----------------------------------------------------------------------------------------------------

    def _edge(self, e: EdgeSpec) -> None:
        start, end = self._end_pose(e, True), self._end_pose(e, False)
        if e.turn is not None:
            path = line_turn_line(start, end, *e.turn)
        else:
            path = polyline_path(start, e.corners, end, e.bump)
        pieces = _pieces(path)
        node_a, node_b = self.plan.node(e.a), self.plan.node(e.b)
        roads: list[Road] = []
        for k, line in enumerate(pieces):
            first, last = k == 0, k == len(pieces) - 1
            extra = []
            if last and isinstance(node_b, RampNodeSpec) and e.port_b == "up" and node_b.kind == "diverge":
                length = line.length
                s_taper = length - node_b.lane_full - node_b.lane_taper
                extra.append(ExtraLaneSpan(s_taper, length - node_b.lane_full, 0.0, _extra_width(e.section)))
                extra.append(
                    ExtraLaneSpan(length - node_b.lane_full, length, _extra_width(e.section), _extra_width(e.section))
                )
            if first and isinstance(node_a, RampNodeSpec) and e.port_a == "down" and node_a.kind == "merge":
                w = _extra_width(e.section)
                extra.append(ExtraLaneSpan(0.0, node_a.lane_full, w, w))
                extra.append(ExtraLaneSpan(node_a.lane_full, node_a.lane_full + node_a.lane_taper, w, 0.0))
            sections = build_sections(
                e.section,
                line.length,
                solid_start=first and isinstance(node_a, NodeSpec),
                solid_end=last and isinstance(node_b, NodeSpec),
                extra=tuple(extra),
                extra_width=_extra_width(e.section),
            )
            road_id = self.ids()
            road = Road(
                id=road_id,
                name=f"{e.name} {k}" if len(pieces) > 1 else e.name,
                line=line,
                sections=sections,
                road_type=e.section.road_type,
                speed_kmh=e.section.speed_kmh,
                lane_offset=[Poly3(0.0, e.section.lane_offset)],
                elevation=_hill(line, e.hill),
            )
            if roads:
                prev = roads[-1]
                prev.successor = Link("road", road_id, "start")
                road.predecessor = Link("road", prev.id, "end")
                link_through(prev.sections, road.sections)
            roads.append(road)
            self.town.roads.append(road)
        roads[0].predecessor = Link("junction", self.junction_of[e.a].id)
        roads[-1].successor = Link("junction", self.junction_of[e.b].id)
        self._attach(e.a, e.port_a, Arm(roads[0], "start", e.section))
        self._attach(e.b, e.port_b, Arm(roads[-1], "end", e.section))
        _speed_signs(self.ids, roads, e.section)

    def _attach(self, name: str, port: str, arm: Arm) -> None:
        node = self.plan.node(name)
        if isinstance(node, RampNodeSpec):
            if port in self.ports.setdefault(name, {}):
                raise ValueError(f"ramp node {name!r} port {port!r} is used twice")
            self.ports[name][port] = arm
        else:
            self.arms.setdefault(name, []).append(arm)


def _extra_width(cs: CrossSection) -> float:
    return max(lane.width for lane in cs.right if lane.type == "driving")


def _pieces(path: Path) -> list[RefLine]:
    """Cut a path at its turns, dropping cuts that would leave a road shorter than ``MIN_PIECE``."""
    line = RefLine(path.start, path.prims)
    starts = [seg.s for seg in line.segments()]
    total = line.length
    cuts: list[int] = []
    last_s = 0.0
    for idx in path.turn_bounds:
        if idx <= 0 or idx >= len(path.prims):
            continue
        s = starts[idx]
        if s - last_s >= MIN_PIECE and total - s >= MIN_PIECE:
            cuts.append(idx)
            last_s = s
    return line.split(cuts)


def _hill(line: RefLine, height: float) -> list[Poly3]:
    """A gentle crest on a long road (zero height and slope at both ends, so joins stay level), else flat."""
    if height == 0.0 or line.length < HILL_MIN_LENGTH:
        return [Poly3(0.0, 0.0)]
    half = line.length / 2.0
    return [smooth_step(0.0, half, 0.0, height), smooth_step(half, half, height, 0.0)]


def _speed_signs(ids: IdAllocator, roads: list[Road], cs: CrossSection) -> None:
    """A speed-limit sign (type 274) at the start of each carriageway of an edge, CARLA-style on the right verge."""
    speed = int(round(cs.speed_kmh))

    def sign(road: Road, s: float, right: bool) -> Signal | None:
        sec = road.section_at(s)
        lanes = sec.right if right else sec.left
        driving = [lane.id for lane in lanes if lane.type == "driving"]
        if not driving:
            return None
        outer = road.lane_borders(s, lanes[-1].id)[1]
        t = outer - 0.5 if right else outer + 0.5
        return Signal(
            id=ids(), name=f"Speed_{speed}", s=s, t=t, type="274", subtype=str(speed), dynamic=False,
            orientation="+" if right else "-", valid_from=min(driving), valid_to=max(driving),
            value=float(speed), unit="km/h", country="DE", z_offset=1.8, height=0.7, width=0.7,
        )  # fmt: skip

    first, last = roads[0], roads[-1]
    s_first = min(15.0, first.length / 2.0)
    s_last = last.length - min(15.0, last.length / 2.0)
    for road, s, right in ((first, s_first, True), (last, s_last, False)):
        sig = sign(road, s, right)
        if sig is not None:
            road.signals.append(sig)
