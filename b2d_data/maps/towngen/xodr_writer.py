"""Serialise a ``Town`` as OpenDRIVE 1.4 XML laid out like CARLA's towns (header with geoReference, roads,
controllers, junctions)."""

from __future__ import annotations

import math

from lxml import etree

from b2d_data.maps.towngen.geometry import Arc, Line, ParamPoly3, Spiral
from b2d_data.maps.towngen.model import Lane, LaneSection, Poly3, Road, RoadMark, Town

#: PROJ string of the geoReference: CARLA's towns use a transverse Mercator centred on lat 0, lon 0.
GEO_REFERENCE = "+proj=tmerc +lat_0=0 +lon_0=0 +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"

#: Fixed header date so that the output depends on (preset, seed) only.
HEADER_DATE = "2024-01-01T00:00:00"

#: Format version of the generator's output, written into the header's userData.
GENERATOR_VERSION = "1"


def _f(value: float) -> str:
    """Numbers as CARLA writes them (17 significant digits, exponent form); -0 becomes 0."""
    if value == 0.0 or abs(value) < 1e-15:
        value = 0.0
    return f"{value:.16e}"


def _sub(parent: etree._Element, tag: str, **attrs: str) -> etree._Element:
    el = etree.SubElement(parent, tag)
    for key, val in attrs.items():
        el.set(key.rstrip("_"), val)
    return el


def _poly(parent: etree._Element, tag: str, rec: Poly3, s_key: str = "s") -> None:
    _sub(parent, tag, **{s_key: _f(rec.s), "a": _f(rec.a), "b": _f(rec.b), "c": _f(rec.c), "d": _f(rec.d)})


def _marks(parent: etree._Element, marks: list[RoadMark]) -> None:
    for m in marks:
        el = _sub(parent, "roadMark", sOffset=_f(m.s_offset), type=m.type, weight="standard", color=m.color)
        if m.type != "none":
            el.set("width", _f(m.width))
        el.set("material", "standard")
        el.set("laneChange", m.lane_change)


def _lane(parent: etree._Element, lane: Lane) -> None:
    el = _sub(parent, "lane", id=str(lane.id), type=lane.type, level="false")
    if lane.predecessor is not None or lane.successor is not None:
        link = _sub(el, "link")
        if lane.predecessor is not None:
            _sub(link, "predecessor", id=str(lane.predecessor))
        if lane.successor is not None:
            _sub(link, "successor", id=str(lane.successor))
    for w in lane.widths:
        _poly(el, "width", w, "sOffset")
    _marks(el, lane.marks)


def _section(parent: etree._Element, sec: LaneSection) -> None:
    el = _sub(parent, "laneSection", s=_f(sec.s))
    if sec.left:
        left = _sub(el, "left")
        for lane in sorted(sec.left, key=lambda x: -x.id):
            _lane(left, lane)
    center = _sub(_sub(el, "center"), "lane", id="0", type="none", level="false")
    _marks(center, sec.center_marks)
    if sec.right:
        right = _sub(el, "right")
        for lane in sorted(sec.right, key=lambda x: -x.id):
            _lane(right, lane)


def _geometry(parent: etree._Element, road: Road) -> None:
    plan = _sub(parent, "planView")
    for seg in road.line.segments():
        p = seg.prim
        el = _sub(
            plan,
            "geometry",
            s=_f(seg.s),
            x=_f(seg.start.x),
            y=_f(seg.start.y),
            hdg=_f(seg.start.hdg),
            length=_f(p.length),
        )
        if isinstance(p, Line):
            _sub(el, "line")
        elif isinstance(p, Arc):
            _sub(el, "arc", curvature=_f(p.curvature_value))
        elif isinstance(p, Spiral):
            _sub(el, "spiral", curvStart=_f(p.curv_start), curvEnd=_f(p.curv_end))
        elif isinstance(p, ParamPoly3):
            _sub(
                el, "paramPoly3",
                aU=_f(p.au), bU=_f(p.bu), cU=_f(p.cu), dU=_f(p.du),
                aV=_f(p.av), bV=_f(p.bv), cV=_f(p.cv), dV=_f(p.dv), pRange="normalized",
            )  # fmt: skip
        else:
            raise TypeError(f"road {road.id}: cannot write geometry {type(p).__name__}")


def _road(root: etree._Element, road: Road) -> None:
    el = _sub(root, "road", name=road.name, length=_f(road.length), id=str(road.id), junction=str(road.junction))
    if road.predecessor is not None or road.successor is not None:
        link = _sub(el, "link")
        for tag, lk in (("predecessor", road.predecessor), ("successor", road.successor)):
            if lk is None:
                continue
            item = _sub(link, tag, elementType=lk.element_type, elementId=str(lk.element_id))
            if lk.contact is not None:
                item.set("contactPoint", lk.contact)
    rtype = _sub(el, "type", s=_f(0.0), type=road.road_type)
    _sub(rtype, "speed", max=f"{road.speed_kmh:g}", unit="km/h")
    _geometry(el, road)
    elev = _sub(el, "elevationProfile")
    for rec in road.elevation:
        _poly(elev, "elevation", rec)
    lat = _sub(el, "lateralProfile")
    _poly(lat, "superelevation", Poly3(0.0, 0.0))
    lanes = _sub(el, "lanes")
    for rec in road.lane_offset:
        _poly(lanes, "laneOffset", rec)
    for sec in road.sections:
        _section(lanes, sec)
    if road.objects:
        objs = _sub(el, "objects")
        for o in road.objects:
            obj = _sub(
                objs, "object", id=str(o.id), name=o.name, type=o.type, s=_f(o.s), t=_f(o.t), zOffset=_f(0.0),
                hdg=_f(o.hdg), roll=_f(0.0), pitch=_f(0.0), orientation=o.orientation, length=_f(o.length),
                width=_f(o.width), height=_f(0.0),
            )  # fmt: skip
            outline = _sub(obj, "outline")
            for u, v in o.outline:
                _sub(outline, "cornerLocal", u=_f(u), v=_f(v), z=_f(0.0), height=_f(0.0))
    if road.signals:
        sigs = _sub(el, "signals")
        for sg in road.signals:
            item = _sub(
                sigs, "signal", name=sg.name, id=str(sg.id), s=_f(sg.s), t=_f(sg.t), zOffset=_f(sg.z_offset),
                hOffset=_f(sg.h_offset), roll=_f(0.0), pitch=_f(0.0), orientation=sg.orientation,
                dynamic="yes" if sg.dynamic else "no", country=sg.country, type=sg.type, subtype=sg.subtype,
                value=_f(sg.value),
            )  # fmt: skip
            if sg.unit is not None:
                item.set("unit", sg.unit)
            item.set("text", sg.text)
            item.set("height", _f(sg.height))
            item.set("width", _f(sg.width))
            _sub(item, "validity", fromLane=str(sg.valid_from), toLane=str(sg.valid_to))


def _bounds(town: Town) -> tuple[float, float, float, float]:
    xs: list[float] = []
    ys: list[float] = []
    for road in town.roads:
        n = max(2, math.ceil(road.length / 5.0))
        for i in range(n + 1):
            s = road.length * i / n
            pose, sec = road.pose_at(s), road.section_at(s)
            # The outer edges of both sides (the reference line itself when a side has no lanes).
            edges = [road.lane_borders(s, side[-1].id)[1] for side in (sec.left, sec.right) if side] or [0.0]
            for t in edges:
                x, y = pose.offset(t)
                xs.append(x)
                ys.append(y)
    return max(ys), min(ys), max(xs), min(xs)


def to_xml(town: Town) -> str:
    """The town as OpenDRIVE 1.4 text (UTF-8 declaration included)."""
    root = etree.Element("OpenDRIVE")
    north, south, east, west = _bounds(town)
    header = _sub(
        root, "header", revMajor="1", revMinor="4", name=town.name, version="1", date=HEADER_DATE,
        north=_f(north), south=_f(south), east=_f(east), west=_f(west), vendor="b2d_data",
    )  # fmt: skip
    geo = _sub(header, "geoReference")
    geo.text = etree.CDATA(GEO_REFERENCE)
    user = _sub(header, "userData")
    _sub(user, "b2dTownGen", preset=town.preset, seed=str(town.seed), version=GENERATOR_VERSION)
    for road in town.roads:
        _road(root, road)
    for ctrl in town.controllers:
        el = _sub(root, "controller", name=ctrl.name, id=str(ctrl.id), sequence="0")
        for sid in ctrl.signal_ids:
            _sub(el, "control", signalId=str(sid), type="0")
    for junction in town.junctions:
        el = _sub(root, "junction", id=str(junction.id), name=junction.name)
        for con in junction.connections:
            c = _sub(
                el, "connection", id=str(con.id), incomingRoad=str(con.incoming), connectingRoad=str(con.connecting),
                contactPoint=con.contact,
            )  # fmt: skip
            for a, b in con.lane_links:
                _sub(c, "laneLink", from_=str(a), to=str(b))
        for seq, cid in enumerate(junction.controllers):
            _sub(el, "controller", id=str(cid), type="0", sequence=str(seq))
    text = etree.tostring(root, pretty_print=True, xml_declaration=True, encoding="UTF-8")
    return text.decode("utf-8")
