"""District planners that add nodes and edges to a ``TownPlan``: a street grid, a highway loop with ramps, and an
interurban road (a ring of its own or a U hung below a grid).

Coordinates are OpenDRIVE metres (x east, y north); grid rows run south from y = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from b2d_data.maps.towngen.cross_sections import CrossSection, TownWidths, highway, ramp, rural, rural_minor
from b2d_data.maps.towngen.geometry import Pose, tangent_lengths, turn_prims
from b2d_data.maps.towngen.network import EdgeSpec, NodeSpec, RampNodeSpec, TownPlan, junction_radius, ramp_port
from b2d_data.maps.towngen.paths import Corner, turn_displacement

GridPoint = tuple[int, int]

_DIRS: tuple[GridPoint, ...] = ((1, 0), (0, 1), (-1, 0), (0, -1))


def grid_name(c: int, r: int) -> str:
    """Node name of grid point (column, row)."""
    return f"g{c}_{r}"


@dataclass(frozen=True)
class GridSpec:
    """A street grid: node coordinates, a cross-section per row and per column, and what happens at each point.

    Points with three or four neighbours are junctions; the four corner points are rounded bends (radius from
    ``corner_radius``, cross-section from ``corner_sections``) unless listed in ``extra_junctions`` because another
    district attaches there. ``column_flow`` gives the direction of each column of one-way streets (+1: south, to
    higher rows; -1: north): its edges are laid so that their lanes (all right of the reference line) run that way.
    """

    xs: tuple[float, ...]
    ys: tuple[float, ...]
    row_sections: tuple[CrossSection, ...]
    col_sections: tuple[CrossSection, ...]
    corner_sections: dict[GridPoint, CrossSection]
    corner_radius: dict[GridPoint, float]
    controls: dict[GridPoint, str]
    extra_junctions: frozenset[GridPoint] = frozenset()
    column_bump: float = 0.0
    column_flow: dict[int, int] = field(default_factory=dict)

    def inside(self, p: GridPoint) -> bool:
        """True when the point is on the grid."""
        return 0 <= p[0] < len(self.xs) and 0 <= p[1] < len(self.ys)

    def neighbours(self, p: GridPoint) -> list[GridPoint]:
        """Grid neighbours of a point."""
        return [q for q in ((p[0] + d[0], p[1] + d[1]) for d in _DIRS) if self.inside(q)]

    def is_junction(self, p: GridPoint) -> bool:
        """True when the point becomes a junction node."""
        return len(self.neighbours(p)) >= 3 or p in self.extra_junctions


def add_grid(plan: TownPlan, g: GridSpec) -> None:
    """Add the grid's junction nodes and the edges between them (bends become filleted corners of an edge)."""
    points = [(c, r) for r in range(len(g.ys)) for c in range(len(g.xs))]
    for p in points:
        if g.is_junction(p):
            # Rows win ties when deciding which approaches of a stop-controlled junction are minor.
            plan.nodes.append(NodeSpec(grid_name(*p), g.xs[p[0]], g.ys[p[1]], g.controls.get(p, "none"), 0.0))
    used: set[frozenset[GridPoint]] = set()
    for p in points:
        if not g.is_junction(p):
            continue
        for q in g.neighbours(p):
            if frozenset((p, q)) in used:
                continue
            used.add(frozenset((p, q)))
            corners: list[GridPoint] = []
            prev, cur = p, q
            while not g.is_junction(cur):
                nxt = next(n for n in g.neighbours(cur) if n != prev)
                corners.append(cur)
                used.add(frozenset((cur, nxt)))
                prev, cur = cur, nxt
            horizontal = p[1] == q[1]
            if corners:
                cs = g.corner_sections[corners[0]]
                name = f"{cs.name} corner {corners[0][0]}.{corners[0][1]}"
            elif horizontal:
                cs = g.row_sections[p[1]]
                name = f"{cs.name} row {p[1]} {min(p[0], cur[0])}-{max(p[0], cur[0])}"
            else:
                cs = g.col_sections[p[0]]
                name = f"{cs.name} column {p[0]} {min(p[1], cur[1])}-{max(p[1], cur[1])}"
            interior_column = not horizontal and not corners and 0 < p[0] < len(g.xs) - 1
            start, end = p, cur
            if cs.driving_count(False) == 0 and not horizontal and not corners:
                if p[0] not in g.column_flow:
                    raise ValueError(f"column {p[0]} is one-way ({cs.name}): give its direction in column_flow")
                if (cur[1] - p[1]) * g.column_flow[p[0]] < 0:
                    start, end = cur, p
            plan.edges.append(
                EdgeSpec(
                    name=name,
                    a=grid_name(*start),
                    b=grid_name(*end),
                    section=cs,
                    corners=tuple(Corner(g.xs[k[0]], g.ys[k[1]], g.corner_radius[k]) for k in corners),
                    bump=g.column_bump if interior_column else 0.0,
                )
            )


def sections_at(plan: TownPlan, node: str) -> list[CrossSection]:
    """Cross-sections of the edges planned so far that touch a node."""
    return [e.section for e in plan.edges if node in (e.a, e.b)]


@dataclass(frozen=True)
class HighwayLayout:
    """Where the highway loop went (for tests and reports)."""

    top_y: float
    diverge_x: float
    merge_x: float
    west_x: float
    east_x: float


def add_highway_loop(
    plan: TownPlan,
    w: TownWidths,
    rng: np.random.Generator,
    west: NodeSpec,
    east: NodeSpec,
    off_target: NodeSpec,
    on_source: NodeSpec,
    lanes: int,
) -> HighwayLayout:
    """A divided highway leaving ``west`` westward, running north then east above the grid and back down to ``east``.

    On its eastbound top straight an off-ramp (diverge) leads down into ``off_target`` from the north and an on-ramp
    from ``on_source`` merges back in. The highway's corners and the ramps use clothoid transitions; the ramp
    junctions use paramPoly3 connecting roads. Positions are solved so that every straight keeps a minimum length.
    """
    hw, rp = highway(w, lanes), ramp(w)
    delta = math.radians(float(rng.uniform(4.0, 6.0)))
    r_ramp, ls_ramp = float(rng.uniform(45.0, 60.0)), float(rng.uniform(20.0, 30.0))
    r_hw, ls_hw = float(rng.uniform(100.0, 125.0)), float(rng.uniform(30.0, 45.0))
    full_div, full_mrg, taper = float(rng.uniform(70.0, 90.0)), float(rng.uniform(90.0, 120.0)), 60.0
    junction_len, lead, min_straight = 40.0, 10.0, 15.0
    # The ramp leaves beyond the highway's hard shoulder (plus its own left shoulder): a clean gore, no overlap.
    gore = hw.right[-1].width + rp.left[0].width + 0.3

    probe_div = RampNodeSpec("probe", "diverge", 0.0, 0.0, 0.0, junction_len, delta, gore)
    probe_mrg = RampNodeSpec("probe", "merge", 0.0, 0.0, 0.0, junction_len, delta, gore)
    a0 = ramp_port(probe_div, "ramp", hw, rp)
    e0 = ramp_port(probe_mrg, "ramp", hw, rp)

    r_off = junction_radius([*sections_at(plan, off_target.name), rp])
    r_on = junction_radius([*sections_at(plan, on_source.name), rp])
    b = Pose(off_target.x, off_target.y + r_off, -math.pi / 2.0)
    _, tx, ty = turn_displacement(-delta, -math.pi / 2.0, r_ramp, ls_ramp)
    s = Pose(on_source.x, on_source.y + r_on, math.pi / 2.0)
    _, tx2, ty2 = turn_displacement(math.pi / 2.0, delta, r_ramp, ls_ramp)

    # Off-ramp: A + lead*dir(-delta) + turn + L1*(0, -1) = B; on-ramp: S + L1*(0, 1) + turn + lead*dir(delta) = E.
    top_y = max(
        b.y + min_straight - a0.y + lead * math.sin(delta) - ty,
        s.y + min_straight - e0.y + ty2 + lead * math.sin(delta),
    ) + float(rng.uniform(0.0, 10.0))
    diverge_x = b.x - a0.x - lead * math.cos(delta) - tx
    merge_x = s.x + tx2 + lead * math.cos(delta) - e0.x

    # Highway corners must fit the vertical legs with a straight of at least 20 m between them.
    leg = top_y - west.y
    while True:
        t_hw = tangent_lengths(turn_prims(math.pi / 2.0, r_hw, ls_hw))[0]
        if leg - 2.0 * t_hw >= 20.0 or r_hw <= 60.0:
            break
        r_hw -= 5.0
    r_w = junction_radius([*sections_at(plan, west.name), hw])
    r_e = junction_radius([*sections_at(plan, east.name), hw])
    west_x = min(
        west.x - r_w - t_hw - 20.0,
        diverge_x - junction_len / 2.0 - full_div - taper - 20.0 - t_hw,
    )
    east_x = max(
        east.x + r_e + t_hw + 20.0,
        merge_x + junction_len / 2.0 + full_mrg + taper + 20.0 + t_hw,
    )
    div = RampNodeSpec("diverge", "diverge", diverge_x, top_y, 0.0, junction_len, delta, gore, full_div, taper)
    mrg = RampNodeSpec("merge", "merge", merge_x, top_y, 0.0, junction_len, delta, gore, full_mrg, taper)
    plan.ramps.extend([div, mrg])
    plan.edges.extend(
        [
            EdgeSpec(
                "highway west", west.name, div.name, hw,
                corners=(Corner(west_x, west.y, r_hw, ls_hw), Corner(west_x, top_y, r_hw, ls_hw)),
                heading_a=math.pi, port_b="up",
            ),
            EdgeSpec("highway middle", div.name, mrg.name, hw, port_a="down", port_b="up"),
            EdgeSpec(
                "highway east", mrg.name, east.name, hw,
                corners=(Corner(east_x, top_y, r_hw, ls_hw), Corner(east_x, east.y, r_hw, ls_hw)),
                port_a="down", heading_b=0.0,
            ),
            EdgeSpec(
                "off-ramp", div.name, off_target.name, rp,
                turn=(r_ramp, ls_ramp), port_a="ramp", heading_b=math.pi / 2.0,
            ),
            EdgeSpec(
                "on-ramp", on_source.name, mrg.name, rp,
                turn=(r_ramp, ls_ramp), heading_a=math.pi / 2.0, port_b="ramp",
            ),
        ]
    )  # fmt: skip
    return HighwayLayout(top_y, diverge_x, merge_x, west_x, east_x)


def _interurban_edges(
    plan: TownPlan,
    w: TownWidths,
    rng: np.random.Generator,
    west_t: NodeSpec,
    east_t: NodeSpec,
    bottom_y: float,
    top: tuple[str, str] | float,
) -> None:
    road, minor = rural(w), rural_minor(w)
    radius, spiral = float(rng.uniform(50.0, 75.0)), float(rng.uniform(20.0, 30.0))
    hill = float(rng.uniform(1.0, 3.0))
    bump = math.radians(float(rng.uniform(2.0, 4.0))) * float(rng.choice([-1.0, 1.0]))
    plan.edges.append(
        EdgeSpec(
            "interurban south", west_t.name, east_t.name, road,
            corners=(Corner(west_t.x, bottom_y, radius, spiral), Corner(east_t.x, bottom_y, radius, spiral)),
            hill=hill,
        )
    )  # fmt: skip
    if isinstance(top, tuple):
        north_w, north_e = top
        plan.edges.append(EdgeSpec("interurban west", north_w, west_t.name, road, hill=hill))
        plan.edges.append(EdgeSpec("interurban east", east_t.name, north_e, road, hill=hill))
    else:
        plan.edges.append(
            EdgeSpec(
                "interurban north", east_t.name, west_t.name, road,
                corners=(Corner(east_t.x, top, radius, spiral), Corner(west_t.x, top, radius, spiral)),
                hill=hill,
            )
        )  # fmt: skip
    plan.edges.append(EdgeSpec("side road", west_t.name, east_t.name, minor, bump=bump, hill=hill))


def add_interurban_u(plan: TownPlan, w: TownWidths, rng: np.random.Generator, left: NodeSpec, right: NodeSpec) -> None:
    """An interurban road hung below two grid nodes: down from ``left``, around, back up to ``right``.

    A side road joins its two legs half way down, making two T junctions on the interurban road (one with a stop
    sign on the side road, one uncontrolled: the interurban road has priority).
    """
    depth = float(rng.uniform(360.0, 420.0))
    controls = ["stop_minor", "none"]
    rng.shuffle(controls)
    west_t = NodeSpec("interurban T west", left.x, left.y - depth / 2.0, controls[0])
    east_t = NodeSpec("interurban T east", right.x, right.y - depth / 2.0, controls[1])
    plan.nodes.extend([west_t, east_t])
    _interurban_edges(plan, w, rng, west_t, east_t, left.y - depth, (left.name, right.name))


def add_interurban_ring(plan: TownPlan, w: TownWidths, rng: np.random.Generator) -> None:
    """A stand-alone interurban ring with a side road across it (two T junctions on the ring)."""
    width, height = float(rng.uniform(300.0, 360.0)), float(rng.uniform(360.0, 420.0))
    controls = ["stop_minor", "none"]
    rng.shuffle(controls)
    west_t = NodeSpec("interurban T west", 0.0, -height / 2.0, controls[0])
    east_t = NodeSpec("interurban T east", width, -height / 2.0, controls[1])
    plan.nodes.extend([west_t, east_t])
    _interurban_edges(plan, w, rng, west_t, east_t, -height, 0.0)
