"""OpenDRIVE 1.4–1.6 XML → plain dataclasses (no geometry evaluation here).

Everything is kept in OpenDRIVE's own frame and units except speeds, which are converted to km/h. Road and
junction ids become ``int`` (CARLA's ids are integers); a file whose ids are not numeric gets fresh integer ids
(logged). Signal, object and controller ids stay strings, as in CARLA (``get_opendrive_id``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from b2d_data.format.errors import B2DFormatError
from b2d_data.maps.lane_types import (
    LaneChange,
    LaneMarkingColor,
    LaneMarkingType,
    LaneType,
    lane_change_from_xodr,
    lane_type_from_xodr,
    marking_color_from_xodr,
    marking_type_from_xodr,
)

logger = logging.getLogger(__name__)

_MPH_TO_KMH = 1.609344


class OpenDriveError(B2DFormatError):
    """An OpenDRIVE file that cannot be read; the message names the file and the offending element."""


@dataclass(frozen=True, slots=True)
class Poly3:
    """A cubic ``a + b·ds + c·ds² + d·ds³`` valid from ``s`` (road s, or sOffset inside a lane section)."""

    s: float
    a: float
    b: float
    c: float
    d: float


@dataclass(frozen=True, slots=True)
class GeometryRecord:
    """One ``<planView><geometry>``: start pose, length and the curve kind with its parameters.

    ``kind`` is ``line``, ``arc`` (params: curvature), ``spiral`` (curvStart, curvEnd), ``poly3`` (a, b, c, d)
    or ``paramPoly3`` (aU, bU, cU, dU, aV, bV, cV, dV; ``normalized`` when pRange is ``normalized``).
    """

    s: float
    x: float
    y: float
    hdg: float
    length: float
    kind: str
    params: tuple[float, ...] = ()
    normalized: bool = False


@dataclass(frozen=True, slots=True)
class RoadLink:
    """A road's predecessor or successor: another road (with its contact point) or a junction."""

    element_type: str
    element_id: int
    contact_point: str | None


@dataclass(frozen=True, slots=True)
class RoadMarkRecord:
    """A ``<roadMark>`` on a lane's outer border, valid from ``s_offset`` inside its lane section."""

    s_offset: float
    type: LaneMarkingType
    color: LaneMarkingColor
    width: float
    lane_change: LaneChange


@dataclass
class LaneRecord:
    """A ``<lane>`` of one lane section. Width and border cubics use ``s`` = sOffset inside the section."""

    id: int
    type: LaneType
    level: bool = False
    predecessor: int | None = None
    successor: int | None = None
    widths: list[Poly3] = field(default_factory=list)
    borders: list[Poly3] = field(default_factory=list)
    road_marks: list[RoadMarkRecord] = field(default_factory=list)
    speeds: list[tuple[float, float]] = field(default_factory=list)  # (sOffset, km/h)


@dataclass
class LaneSectionRecord:
    """A ``<laneSection>``: its start s and its lanes by id (0 is the centre lane)."""

    s: float
    lanes: dict[int, LaneRecord] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class Validity:
    """A ``<validity fromLane toLane>`` range (inclusive)."""

    from_lane: int
    to_lane: int

    def lanes(self) -> list[int]:
        """Lane ids in the range, in CARLA's order (from → to), without the centre lane 0."""
        step = 1 if self.to_lane >= self.from_lane else -1
        return [lane for lane in range(self.from_lane, self.to_lane + step, step) if lane != 0]


@dataclass
class SignalRecord:
    """A ``<signal>`` as written (value converted to km/h for speed signs given in mph)."""

    id: str
    road_id: int
    name: str
    s: float
    t: float
    z_offset: float
    h_offset: float
    pitch: float
    roll: float
    orientation: str
    dynamic: bool
    country: str
    type: str
    subtype: str
    value: float | None
    unit: str
    text: str
    height: float
    width: float
    validities: list[Validity] = field(default_factory=list)


@dataclass
class SignalReferenceRecord:
    """A ``<signalReference>``: a signal that also governs lanes of this road at ``s``."""

    id: str
    road_id: int
    s: float
    t: float
    orientation: str
    validities: list[Validity] = field(default_factory=list)


@dataclass
class ObjectRecord:
    """A road ``<object>`` (crosswalks, stop lines, props); ``outline`` holds cornerLocal (u, v, z) tuples."""

    id: str
    road_id: int
    name: str
    type: str
    s: float
    t: float
    z_offset: float
    hdg: float
    pitch: float
    roll: float
    orientation: str
    length: float
    width: float
    height: float
    radius: float
    outline: list[tuple[float, float, float]] = field(default_factory=list)
    outline_road: list[tuple[float, float, float]] = field(default_factory=list)  # cornerRoad (s, t, dz)


@dataclass
class RoadTypeRecord:
    """A ``<type>`` entry of a road: its class and speed limit (km/h, ``None`` when absent or unlimited)."""

    s: float
    type: str
    speed_kmh: float | None


@dataclass
class RoadRecord:
    """A ``<road>`` with everything our lane model needs."""

    id: int
    name: str
    length: float
    junction: int
    predecessor: RoadLink | None
    successor: RoadLink | None
    types: list[RoadTypeRecord]
    geometries: list[GeometryRecord]
    elevations: list[Poly3]
    superelevations: list[Poly3]
    lane_offsets: list[Poly3]
    sections: list[LaneSectionRecord]
    signals: list[SignalRecord] = field(default_factory=list)
    signal_references: list[SignalReferenceRecord] = field(default_factory=list)
    objects: list[ObjectRecord] = field(default_factory=list)


@dataclass
class ConnectionRecord:
    """A junction ``<connection>``: lanes of ``incoming_road`` continue on ``connecting_road``."""

    id: str
    incoming_road: int
    connecting_road: int
    contact_point: str
    lane_links: list[tuple[int, int]]


@dataclass
class JunctionRecord:
    """A ``<junction>``: its connections and the controllers (traffic-light phases) it uses."""

    id: int
    name: str
    connections: list[ConnectionRecord]
    controllers: list[tuple[str, int | None]]  # (controller id, sequence)


@dataclass
class ControllerRecord:
    """A top-level ``<controller>``: the signals switched together (one traffic-light phase)."""

    id: str
    name: str
    sequence: int | None
    signal_ids: list[str]


@dataclass
class OpenDriveData:
    """The parsed file."""

    path: Path | None
    name: str
    geo_reference: str
    rev_major: int
    rev_minor: int
    roads: list[RoadRecord]
    junctions: dict[int, JunctionRecord]
    controllers: list[ControllerRecord]

    _road_index: dict[int, RoadRecord] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        self._road_index = {r.id: r for r in self.roads}

    def road(self, road_id: int) -> RoadRecord:
        """The road with this id (``KeyError`` when absent)."""
        return self._road_index[road_id]

    def has_road(self, road_id: int) -> bool:
        """Whether a road with this id exists."""
        return road_id in self._road_index


class _Reader:
    """Attribute access that reports the file and the element on failure."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, element: etree._Element, problem: str) -> OpenDriveError:
        line = getattr(element, "sourceline", None)
        where = f"<{element.tag}> (line {line})" if line else f"<{element.tag}>"
        return OpenDriveError(self.source, f"{where}: {problem}")

    def float(self, element: etree._Element, name: str, default: float | None = None) -> float:
        text = element.get(name)
        if text is None or text.strip() == "":
            if default is None:
                raise self.fail(element, f"missing attribute '{name}'")
            return default
        try:
            value = float(text)
        except ValueError:
            raise self.fail(element, f"attribute '{name}'={text!r} is not a number") from None
        if not math.isfinite(value):
            if default is None:
                raise self.fail(element, f"attribute '{name}'={text!r} is not finite")
            return default
        return value

    def int(self, element: etree._Element, name: str, default: int | None = None) -> int:
        text = element.get(name)
        if text is None or text.strip() == "":
            if default is None:
                raise self.fail(element, f"missing attribute '{name}'")
            return default
        try:
            return int(float(text))
        except ValueError:
            raise self.fail(element, f"attribute '{name}'={text!r} is not an integer") from None

    def poly(self, element: etree._Element, s_name: str) -> Poly3:
        return Poly3(
            self.float(element, s_name, 0.0),
            self.float(element, "a", 0.0),
            self.float(element, "b", 0.0),
            self.float(element, "c", 0.0),
            self.float(element, "d", 0.0),
        )


def _speed_kmh(value: float | None, unit: str | None, default_unit: str) -> float | None:
    if value is None:
        return None
    unit = (unit or default_unit).strip().lower()
    if unit == "mph":
        return value * _MPH_TO_KMH
    if unit == "m/s":
        return value * 3.6
    return value


def _parse_float_or_none(text: str | None) -> float | None:
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        return None  # "no limit" / "undefined"
    return value if math.isfinite(value) else None


class _IdMap:
    """Road/junction ids → int; non-numeric ids get fresh integers above the numeric ones."""

    def __init__(self, raw_ids: list[str], what: str, source: str) -> None:
        self.map: dict[str, int] = {}
        numeric: list[int] = []
        others: list[str] = []
        for raw in raw_ids:
            try:
                numeric.append(int(raw))
                self.map[raw] = int(raw)
            except ValueError:
                others.append(raw)
        next_id = max(numeric, default=-1) + 1
        for raw in others:
            if raw not in self.map:
                self.map[raw] = next_id
                next_id += 1
        if others:
            logger.warning("%s: %d non-numeric %s ids were given integer ids", source, len(others), what)

    def __call__(self, raw: str | None, reader: _Reader, element: etree._Element) -> int:
        if raw is None:
            raise reader.fail(element, "missing id")
        if raw in self.map:
            return self.map[raw]
        try:
            return int(raw)
        except ValueError:
            raise reader.fail(element, f"refers to unknown id {raw!r}") from None


def parse_opendrive(source: str | Path) -> OpenDriveData:
    """Parse an OpenDRIVE file (a path) or XML text (a string starting with ``<``)."""
    path: Path | None
    if isinstance(source, str) and source.lstrip().startswith("<"):
        path, label = None, "<OpenDRIVE text>"
        try:
            root = etree.fromstring(source.encode("utf-8"), parser=etree.XMLParser(huge_tree=True))
        except etree.XMLSyntaxError as exc:
            raise OpenDriveError(label, f"not well-formed XML: {exc}") from None
    else:
        path = Path(source)
        label = str(path)
        if not path.is_file():
            raise OpenDriveError(path, "no such OpenDRIVE file")
        try:
            root = etree.parse(str(path), parser=etree.XMLParser(huge_tree=True)).getroot()
        except etree.XMLSyntaxError as exc:
            raise OpenDriveError(path, f"not well-formed XML: {exc}") from None
    _strip_namespaces(root)
    if root.tag != "OpenDRIVE":
        raise OpenDriveError(label, f"root element is <{root.tag}>, expected <OpenDRIVE>")
    reader = _Reader(label)

    road_elements = root.findall("road")
    junction_elements = root.findall("junction")
    road_ids = _IdMap([e.get("id", "") for e in road_elements], "road", label)
    junction_ids = _IdMap([e.get("id", "") for e in junction_elements], "junction", label)

    header = root.find("header")
    name, geo, rev_major, rev_minor = "", "", 1, 4
    if header is not None:
        name = header.get("name", "") or ""
        rev_major = reader.int(header, "revMajor", 1)
        rev_minor = reader.int(header, "revMinor", 4)
        geo_el = header.find("geoReference")
        if geo_el is not None and geo_el.text:
            geo = geo_el.text.strip()

    roads = [_parse_road(e, reader, road_ids, junction_ids) for e in road_elements]
    seen: set[int] = set()
    for road in roads:
        if road.id in seen:
            raise OpenDriveError(label, f"road id {road.id} appears twice")
        seen.add(road.id)
    junctions = {}
    for e in junction_elements:
        junction = _parse_junction(e, reader, road_ids, junction_ids)
        junctions[junction.id] = junction
    controllers = [_parse_controller(e, reader) for e in root.findall("controller")]
    return OpenDriveData(path, name, geo, rev_major, rev_minor, roads, junctions, controllers)


def _strip_namespaces(root: etree._Element) -> None:
    if not isinstance(root.tag, str) or "{" not in root.tag:
        return
    for element in root.iter():
        if isinstance(element.tag, str) and "{" in element.tag:
            element.tag = etree.QName(element).localname


def _parse_link(element: etree._Element | None, reader: _Reader, road_ids: _IdMap, junction_ids: _IdMap):
    if element is None:
        return None
    kind = (element.get("elementType") or "road").strip().lower()
    raw = element.get("elementId")
    element_id = junction_ids(raw, reader, element) if kind == "junction" else road_ids(raw, reader, element)
    contact = element.get("contactPoint")
    return RoadLink(kind, element_id, contact.strip().lower() if contact else None)


def _parse_road(e: etree._Element, r: _Reader, road_ids: _IdMap, junction_ids: _IdMap) -> RoadRecord:
    road_id = road_ids(e.get("id"), r, e)
    length = r.float(e, "length")
    junction_raw = e.get("junction", "-1").strip()
    junction = -1 if junction_raw in ("", "-1") else junction_ids(junction_raw, r, e)
    link = e.find("link")
    predecessor = successor = None
    if link is not None:
        predecessor = _parse_link(link.find("predecessor"), r, road_ids, junction_ids)
        successor = _parse_link(link.find("successor"), r, road_ids, junction_ids)

    types = []
    for t in e.findall("type"):
        speed_el = t.find("speed")
        speed = None
        if speed_el is not None:
            speed = _speed_kmh(_parse_float_or_none(speed_el.get("max")), speed_el.get("unit"), "m/s")
        types.append(RoadTypeRecord(r.float(t, "s", 0.0), t.get("type", ""), speed))

    geometries = []
    plan = e.find("planView")
    for g in plan.findall("geometry") if plan is not None else []:
        geometries.append(_parse_geometry(g, r))
    if not geometries:
        raise r.fail(e, f"road {road_id} has no <planView><geometry>")
    geometries.sort(key=lambda g: g.s)

    elevations = [r.poly(x, "s") for x in e.findall("elevationProfile/elevation")]
    superelevations = [r.poly(x, "s") for x in e.findall("lateralProfile/superelevation")]
    lanes_el = e.find("lanes")
    if lanes_el is None:
        raise r.fail(e, f"road {road_id} has no <lanes>")
    lane_offsets = [r.poly(x, "s") for x in lanes_el.findall("laneOffset")]
    sections = [_parse_section(x, r) for x in lanes_el.findall("laneSection")]
    if not sections:
        raise r.fail(lanes_el, f"road {road_id} has no <laneSection>")
    sections.sort(key=lambda sec: sec.s)
    for poly_list in (elevations, superelevations, lane_offsets):
        poly_list.sort(key=lambda p: p.s)

    road = RoadRecord(
        road_id, e.get("name", "") or "", length, junction, predecessor, successor, types, geometries,
        elevations, superelevations, lane_offsets, sections,
    )  # fmt: skip
    signals_el = e.find("signals")
    if signals_el is not None:
        for s in signals_el.findall("signal"):
            road.signals.append(_parse_signal(s, r, road_id))
        for s in signals_el.findall("signalReference"):
            road.signal_references.append(
                SignalReferenceRecord(
                    (s.get("id") or "").strip(), road_id, r.float(s, "s", 0.0), r.float(s, "t", 0.0),
                    (s.get("orientation") or "none").strip(), _validities(s, r),
                )  # fmt: skip
            )
    objects_el = e.find("objects")
    if objects_el is not None:
        for o in objects_el.findall("object"):
            road.objects.append(_parse_object(o, r, road_id))
    return road


def _parse_geometry(g: etree._Element, r: _Reader) -> GeometryRecord:
    s, x, y = r.float(g, "s"), r.float(g, "x"), r.float(g, "y")
    hdg, length = r.float(g, "hdg"), r.float(g, "length")
    if length < 0:
        raise r.fail(g, f"negative length {length}")
    for child in g:
        if not isinstance(child.tag, str):
            continue
        tag = child.tag
        if tag == "line":
            return GeometryRecord(s, x, y, hdg, length, "line")
        if tag == "arc":
            return GeometryRecord(s, x, y, hdg, length, "arc", (r.float(child, "curvature"),))
        if tag == "spiral":
            params = (r.float(child, "curvStart"), r.float(child, "curvEnd"))
            return GeometryRecord(s, x, y, hdg, length, "spiral", params)
        if tag == "poly3":
            params = tuple(r.float(child, k, 0.0) for k in ("a", "b", "c", "d"))
            return GeometryRecord(s, x, y, hdg, length, "poly3", params)
        if tag == "paramPoly3":
            keys = ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV")
            params = tuple(r.float(child, k, 0.0) for k in keys)
            p_range = (child.get("pRange") or "normalized").strip()
            return GeometryRecord(s, x, y, hdg, length, "paramPoly3", params, p_range != "arcLength")
    raise r.fail(g, "has no line/arc/spiral/poly3/paramPoly3 child")


def _parse_section(e: etree._Element, r: _Reader) -> LaneSectionRecord:
    section = LaneSectionRecord(r.float(e, "s", 0.0))
    for side in ("left", "center", "right"):
        side_el = e.find(side)
        if side_el is None:
            continue
        for lane_el in side_el.findall("lane"):
            lane = _parse_lane(lane_el, r)
            section.lanes[lane.id] = lane
    if 0 not in section.lanes:
        section.lanes[0] = LaneRecord(0, LaneType.NONE)
    return section


def _parse_lane(e: etree._Element, r: _Reader) -> LaneRecord:
    lane = LaneRecord(
        r.int(e, "id"), lane_type_from_xodr(e.get("type", "none")), (e.get("level") or "").lower() in ("true", "1")
    )
    link = e.find("link")
    if link is not None:
        pred, succ = link.find("predecessor"), link.find("successor")
        if pred is not None:
            lane.predecessor = r.int(pred, "id")
        if succ is not None:
            lane.successor = r.int(succ, "id")
    lane.widths = sorted((r.poly(w, "sOffset") for w in e.findall("width")), key=lambda p: p.s)
    lane.borders = sorted((r.poly(w, "sOffset") for w in e.findall("border")), key=lambda p: p.s)
    for m in e.findall("roadMark"):
        lane.road_marks.append(
            RoadMarkRecord(
                r.float(m, "sOffset", 0.0),
                marking_type_from_xodr(m.get("type")),
                marking_color_from_xodr(m.get("color")),
                r.float(m, "width", 0.15),
                lane_change_from_xodr(m.get("laneChange")),
            )
        )
    lane.road_marks.sort(key=lambda m: m.s_offset)
    for sp in e.findall("speed"):
        kmh = _speed_kmh(_parse_float_or_none(sp.get("max")), sp.get("unit"), "m/s")
        if kmh is not None:
            lane.speeds.append((r.float(sp, "sOffset", 0.0), kmh))
    lane.speeds.sort()
    return lane


def _validities(e: etree._Element, r: _Reader) -> list[Validity]:
    return [Validity(r.int(v, "fromLane", 0), r.int(v, "toLane", 0)) for v in e.findall("validity")]


def _parse_signal(e: etree._Element, r: _Reader, road_id: int) -> SignalRecord:
    value = _parse_float_or_none(e.get("value"))
    unit = (e.get("unit") or "").strip()
    if value is not None and unit.lower() == "mph":
        value *= _MPH_TO_KMH
        unit = "km/h"
    dynamic = (e.get("dynamic") or "no").strip().lower() in ("yes", "true")
    return SignalRecord(
        (e.get("id") or "").strip(), road_id, e.get("name", "") or "", r.float(e, "s", 0.0), r.float(e, "t", 0.0),
        r.float(e, "zOffset", 0.0), r.float(e, "hOffset", 0.0), r.float(e, "pitch", 0.0), r.float(e, "roll", 0.0),
        (e.get("orientation") or "none").strip(), dynamic, e.get("country", "") or "", (e.get("type") or "").strip(),
        (e.get("subtype") or "").strip(), value, unit, e.get("text", "") or "", r.float(e, "height", 0.0),
        r.float(e, "width", 0.0), _validities(e, r),
    )  # fmt: skip


def _parse_object(e: etree._Element, r: _Reader, road_id: int) -> ObjectRecord:
    obj = ObjectRecord(
        (e.get("id") or "").strip(), road_id, e.get("name", "") or "", (e.get("type") or "").strip(),
        r.float(e, "s", 0.0), r.float(e, "t", 0.0), r.float(e, "zOffset", 0.0), r.float(e, "hdg", 0.0),
        r.float(e, "pitch", 0.0), r.float(e, "roll", 0.0), (e.get("orientation") or "none").strip(),
        r.float(e, "length", 0.0), r.float(e, "width", 0.0), r.float(e, "height", 0.0), r.float(e, "radius", 0.0),
    )  # fmt: skip
    # OpenDRIVE 1.4 has a single <outline>, 1.5+ wraps several in <outlines>; we keep the first one.
    outline = e.find("outline")
    if outline is None:
        outline = e.find("outlines/outline")
    if outline is not None:
        for c in outline.findall("cornerLocal"):
            obj.outline.append((r.float(c, "u", 0.0), r.float(c, "v", 0.0), r.float(c, "z", 0.0)))
        for c in outline.findall("cornerRoad"):
            obj.outline_road.append((r.float(c, "s", 0.0), r.float(c, "t", 0.0), r.float(c, "dz", 0.0)))
    return obj


def _parse_junction(e: etree._Element, r: _Reader, road_ids: _IdMap, junction_ids: _IdMap) -> JunctionRecord:
    junction_id = junction_ids(e.get("id"), r, e)
    connections = []
    for c in e.findall("connection"):
        links = [(r.int(link, "from"), r.int(link, "to")) for link in c.findall("laneLink")]
        connections.append(
            ConnectionRecord(
                (c.get("id") or "").strip(),
                road_ids(c.get("incomingRoad"), r, c),
                road_ids(c.get("connectingRoad"), r, c),
                (c.get("contactPoint") or "start").strip().lower(),
                links,
            )
        )
    controllers = []
    for c in e.findall("controller"):
        sequence = c.get("sequence")
        controllers.append(((c.get("id") or "").strip(), int(sequence) if sequence not in (None, "") else None))
    return JunctionRecord(junction_id, e.get("name", "") or "", connections, controllers)


def _parse_controller(e: etree._Element, r: _Reader) -> ControllerRecord:
    ids: list[str] = []
    for c in e.findall("control"):
        signal_id = (c.get("signalId") or "").strip()
        if signal_id and signal_id not in ids:
            ids.append(signal_id)
    sequence = e.get("sequence")
    seq = r.int(e, "sequence") if sequence not in (None, "") else None
    return ControllerRecord((e.get("id") or "").strip(), e.get("name", "") or "", seq, ids)
