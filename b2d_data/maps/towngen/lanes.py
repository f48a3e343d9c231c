"""Lane sections of ordinary roads: lanes from a cross-section, extra tapered lanes, road marks near junctions."""

from __future__ import annotations

from dataclasses import dataclass

from b2d_data.maps.towngen.cross_sections import BROKEN_WHITE, SOLID_WHITE, CrossSection, LaneSpec, MarkStyle
from b2d_data.maps.towngen.model import Lane, LaneSection, Poly3, RoadMark, smooth_step

#: Broken lines turn solid over this many metres before a junction (no lane changes on the approach).
JUNCTION_ZONE = 12.0


@dataclass(frozen=True)
class ExtraLaneSpan:
    """An extra outer driving lane on the right side over [s0, s1], its width easing from ``w0`` to ``w1``."""

    s0: float
    s1: float
    w0: float
    w1: float


def marks_for(style: MarkStyle, length: float, solid_start: bool, solid_end: bool) -> list[RoadMark]:
    """Road marks of one border over a section; broken lines become solid within the junction zones."""

    def mark(s: float, st: MarkStyle) -> RoadMark:
        return RoadMark(s, st.type, st.color, st.width, st.lane_change)

    if style.type != "broken" or not (solid_start or solid_end):
        return [mark(0.0, style)]
    solid = MarkStyle("solid", style.color, style.width, "none")
    lo = JUNCTION_ZONE if solid_start else 0.0
    hi = length - JUNCTION_ZONE if solid_end else length
    if hi - lo < JUNCTION_ZONE:
        return [mark(0.0, solid)]
    out = []
    if solid_start:
        out.append(mark(0.0, solid))
    out.append(mark(lo, style))
    if solid_end:
        out.append(mark(hi, solid))
    return out


def _width(span: ExtraLaneSpan | None, spec: LaneSpec) -> list[Poly3]:
    if span is None or span.w0 == span.w1:
        return [Poly3(0.0, span.w0 if span is not None else spec.width)]
    return [smooth_step(0.0, span.s1 - span.s0, span.w0, span.w1)]


def build_sections(
    cs: CrossSection,
    length: float,
    solid_start: bool = False,
    solid_end: bool = False,
    extra: tuple[ExtraLaneSpan, ...] = (),
    extra_width: float = 0.0,
) -> list[LaneSection]:
    """Lane sections of a road of ``length`` metres with cross-section ``cs``.

    ``extra`` spans add a driving lane outside the last right driving lane (deceleration lanes before a diverge,
    acceleration lanes after a merge); a new lane section starts at every span boundary. Lanes are linked across
    section boundaries by identity, so the lanes outside an extra lane change id but keep their links.
    """
    cuts = sorted({0.0, length, *(x for sp in extra for x in (sp.s0, sp.s1) if 0.0 < x < length)})
    for sp in extra:
        if sp.s0 < -1e-6 or sp.s1 > length + 1e-6 or sp.s1 - sp.s0 < 1.0:
            raise ValueError(f"extra lane span [{sp.s0:.1f}, {sp.s1:.1f}] does not fit a road of {length:.1f} m")
    last_driving = max(i for i, lane in enumerate(cs.right) if lane.type == "driving") if cs.driving_count(True) else -1
    sections: list[LaneSection] = []
    keyed: list[dict[object, int]] = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        span = next((sp for sp in extra if sp.s0 <= a + 1e-9 and b <= sp.s1 + 1e-9), None)
        first, last = a == cuts[0], b == cuts[-1]
        seclen = b - a
        right_specs: list[tuple[object, LaneSpec, list[Poly3]]] = []
        for i, spec in enumerate(cs.right):
            style = spec.mark
            if span is not None and i == last_driving:
                style = BROKEN_WHITE
            right_specs.append((i, LaneSpec(spec.type, spec.width, style), [Poly3(0.0, spec.width)]))
            if span is not None and i == last_driving:
                right_specs.append(("extra", LaneSpec("driving", extra_width, SOLID_WHITE), _width(span, spec)))
        left_specs = [(i, spec, [Poly3(0.0, spec.width)]) for i, spec in enumerate(cs.left)]
        keys: dict[object, int] = {}
        right: list[Lane] = []
        for n, (key, spec, widths) in enumerate(right_specs):
            lane_id = -(n + 1)
            keys[("r", key)] = lane_id
            right.append(
                Lane(
                    lane_id, spec.type, widths, marks_for(spec.mark, seclen, solid_start and first, solid_end and last)
                )
            )
        left: list[Lane] = []
        for n, (key, spec, widths) in enumerate(left_specs):
            lane_id = n + 1
            keys[("l", key)] = lane_id
            left.append(
                Lane(
                    lane_id, spec.type, widths, marks_for(spec.mark, seclen, solid_start and first, solid_end and last)
                )
            )
        center = marks_for(cs.center_mark, seclen, solid_start and first, solid_end and last)
        sections.append(LaneSection(a, left, right, center))
        keyed.append(keys)
    for k in range(len(sections) - 1):
        this, nxt = keyed[k], keyed[k + 1]
        for key, lane_id in this.items():
            if key in nxt:
                sections[k].lane(lane_id).successor = nxt[key]
                sections[k + 1].lane(nxt[key]).predecessor = lane_id
    return sections


def link_through(sections_a: list[LaneSection], sections_b: list[LaneSection]) -> None:
    """Link the lanes of two roads joined end-to-start (same lanes, same ids) across the road boundary."""
    end, start = sections_a[-1], sections_b[0]
    for lane in (*end.left, *end.right):
        if start.has_lane(lane.id) and start.lane(lane.id).type == lane.type:
            lane.successor = lane.id
            start.lane(lane.id).predecessor = lane.id
