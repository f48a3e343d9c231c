"""Read the OpenDRIVE subset this generator writes back into ``model`` records, so its output can be checked
independently of the in-memory town that produced it. Not a general OpenDRIVE parser (that is ``b2d_data.maps``)."""

from __future__ import annotations

from lxml import etree

from b2d_data.maps.towngen.geometry import Arc, Line, ParamPoly3, Pose, Primitive, RefLine, Segment, Spiral
from b2d_data.maps.towngen.model import (
    Connection,
    Controller,
    Junction,
    Lane,
    LaneSection,
    Link,
    Poly3,
    Road,
    RoadMark,
    RoadObject,
    Signal,
    Town,
)


def _f(el: etree._Element, key: str, default: float | None = None) -> float:
    val = el.get(key)
    if val is None:
        if default is None:
            raise ValueError(f"<{el.tag}> line {el.sourceline}: missing attribute {key!r}")
        return default
    return float(val)


def _poly(el: etree._Element, s_key: str) -> Poly3:
    return Poly3(_f(el, s_key), _f(el, "a"), _f(el, "b"), _f(el, "c"), _f(el, "d"))


def _prim(geo: etree._Element) -> Primitive:
    length = _f(geo, "length")
    kind = geo[0]
    if kind.tag == "line":
        return Line(length)
    if kind.tag == "arc":
        return Arc(length, _f(kind, "curvature"))
    if kind.tag == "spiral":
        return Spiral(length, _f(kind, "curvStart"), _f(kind, "curvEnd"))
    if kind.tag == "paramPoly3":
        if kind.get("pRange", "normalized") != "normalized":
            raise ValueError(f"line {kind.sourceline}: only pRange='normalized' is read")
        keys = ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV")
        return ParamPoly3(length, *(_f(kind, k) for k in keys))
    raise ValueError(f"line {kind.sourceline}: unknown geometry <{kind.tag}>")


def _link(el: etree._Element | None) -> Link | None:
    if el is None:
        return None
    return Link(el.get("elementType", ""), int(el.get("elementId", "-1")), el.get("contactPoint"))


def _lane(el: etree._Element) -> Lane:
    link = el.find("link")
    pred = succ = None
    if link is not None:
        if link.find("predecessor") is not None:
            pred = int(link.find("predecessor").get("id"))
        if link.find("successor") is not None:
            succ = int(link.find("successor").get("id"))
    marks = [
        RoadMark(
            _f(m, "sOffset"),
            m.get("type", "none"),
            m.get("color", "white"),
            _f(m, "width", 0.0),
            m.get("laneChange", "both"),
        )
        for m in el.findall("roadMark")
    ]
    return Lane(
        int(el.get("id")), el.get("type", "none"), [_poly(w, "sOffset") for w in el.findall("width")], marks, pred, succ
    )


def written_segments(road: etree._Element) -> list[Segment]:
    """The ``<geometry>`` records of a road element exactly as written (their own s, x, y, hdg)."""
    return [
        Segment(_f(g, "s"), Pose(_f(g, "x"), _f(g, "y"), _f(g, "hdg")), _prim(g))
        for g in road.findall("planView/geometry")
    ]


def _road(el: etree._Element) -> Road:
    segs = written_segments(el)
    if not segs:
        raise ValueError(f"road {el.get('id')}: empty planView")
    line = RefLine(segs[0].start, tuple(seg.prim for seg in segs))
    sections = []
    for sec in el.findall("lanes/laneSection"):
        left = sorted((_lane(x) for x in sec.findall("left/lane")), key=lambda lane: lane.id)
        right = sorted((_lane(x) for x in sec.findall("right/lane")), key=lambda lane: -lane.id)
        center = sec.find("center/lane")
        cmarks = [] if center is None else _lane(center).marks
        sections.append(LaneSection(_f(sec, "s"), left, right, cmarks))
    signals = [
        Signal(
            id=int(s.get("id")),
            name=s.get("name", ""),
            s=_f(s, "s"),
            t=_f(s, "t"),
            type=s.get("type", ""),
            subtype=s.get("subtype", ""),
            dynamic=s.get("dynamic") == "yes",
            orientation=s.get("orientation", "+"),
            valid_from=int(s.find("validity").get("fromLane")) if s.find("validity") is not None else 0,
            valid_to=int(s.find("validity").get("toLane")) if s.find("validity") is not None else 0,
            value=_f(s, "value", -1.0),
            unit=s.get("unit"),
            country=s.get("country", ""),
        )  # fmt: skip
        for s in el.findall("signals/signal")
    ]
    objects = [
        RoadObject(
            int(o.get("id")),
            o.get("name", ""),
            o.get("type", ""),
            _f(o, "s"),
            _f(o, "t"),
            _f(o, "hdg", 0.0),
            _f(o, "length", 0.0),
            _f(o, "width", 0.0),
            tuple((_f(c, "u"), _f(c, "v")) for c in o.findall("outline/cornerLocal")),
        )  # fmt: skip
        for o in el.findall("objects/object")
    ]
    rtype = el.find("type")
    speed = rtype.find("speed") if rtype is not None else None
    link = el.find("link")
    road = Road(
        id=int(el.get("id")),
        name=el.get("name", ""),
        line=line,
        sections=sections,
        junction=int(el.get("junction", "-1")),
        predecessor=_link(link.find("predecessor")) if link is not None else None,
        successor=_link(link.find("successor")) if link is not None else None,
        road_type=rtype.get("type", "") if rtype is not None else "",
        speed_kmh=_f(speed, "max", 0.0) if speed is not None else 0.0,
        lane_offset=[_poly(x, "s") for x in el.findall("lanes/laneOffset")] or [Poly3(0.0, 0.0)],
        elevation=[_poly(x, "s") for x in el.findall("elevationProfile/elevation")] or [Poly3(0.0, 0.0)],
        signals=signals,
        objects=objects,
    )
    declared = _f(el, "length")
    if abs(declared - road.length) > 1e-6:
        raise ValueError(f"road {road.id}: length {declared} differs from its geometry ({road.length})")
    return road


def read_town(text: str) -> Town:
    """Parse OpenDRIVE text written by this generator into a ``Town`` (geometry, lanes, links, signals, objects)."""
    root = etree.fromstring(text.encode("utf-8"))
    header = root.find("header")
    town = Town(header.get("name", "") if header is not None else "", "", 0)
    town.roads = [_road(el) for el in root.findall("road")]
    for el in root.findall("controller"):
        town.controllers.append(
            Controller(
                int(el.get("id")), el.get("name", ""), tuple(int(c.get("signalId")) for c in el.findall("control"))
            )
        )
    for el in root.findall("junction"):
        j = Junction(int(el.get("id")), el.get("name", ""))
        for c in el.findall("connection"):
            links = tuple((int(x.get("from")), int(x.get("to"))) for x in c.findall("laneLink"))
            j.connections.append(
                Connection(
                    int(c.get("id")),
                    int(c.get("incomingRoad")),
                    int(c.get("connectingRoad")),
                    c.get("contactPoint", ""),
                    links,
                )
            )
        j.controllers = [int(x.get("id")) for x in el.findall("controller")]
        town.junctions.append(j)
    return town
