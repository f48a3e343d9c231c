"""Leaderboard 2.0 route XML files: read and write (format.md §7.1).

A route file is ``<routes>`` holding ``<route id town [road_id]>`` elements, each with ``<waypoints>``
(sparse ``<position x y z/>`` keypoints), ``<scenarios>`` (``<scenario name type>`` with a
``<trigger_point x y z yaw/>`` and type-specific parameter elements) and optionally ``<weathers>``.
Weathers are parsed as the leaderboard's RouteParser does: every ``<weather>`` starts from
``WeatherParameters(sun_altitude_angle=70, cloudiness=50)``, overrides the attributes it lists, and the
list is sorted by ``route_percentage``; a route without ``<weathers>`` gets that base weather at 0 %.
This module only depends on ``b2d_data.format``.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import UnsafeNameError, check_safe_name
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import ROUTE_DEFAULT, XML_ATTRIBUTES, WeatherParameters, weather_id_of

log = logging.getLogger(__name__)

_WEATHER_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(WeatherParameters))
_INDENT = "   "


class RouteFileError(B2DFormatError):
    """A route XML file that cannot be parsed; the message names the file and, where known, the line."""


@dataclass(frozen=True)
class ScenarioConfig:
    """One ``<scenario>``: its name (``<Type>_<n>``), type, trigger point and other parameter elements."""

    name: str
    type: str
    trigger_point: Transform
    #: Every other child element: tag → its attributes (strings, as written), in file order.
    other_parameters: dict[str, dict[str, str]] = field(default_factory=dict)

    def parameter(self, tag: str, attribute: str = "value") -> str | None:
        """One attribute of a parameter element (e.g. ``parameter("direction")``), or None when absent."""
        return self.other_parameters.get(tag, {}).get(attribute)


@dataclass(frozen=True)
class Route:
    """One ``<route>``: id, town, optional road id, keypoints, scenarios and weathers (sorted by percentage)."""

    id: str
    town: str
    waypoints: tuple[Location, ...]
    scenarios: tuple[ScenarioConfig, ...] = ()
    weathers: tuple[tuple[float, WeatherParameters], ...] = ((0.0, ROUTE_DEFAULT),)
    road_id: int | None = None

    @property
    def scenario_type(self) -> str | None:
        """Type of the first scenario (what Bench2Drive's tools classify a route by), None without scenarios."""
        return self.scenarios[0].type if self.scenarios else None

    @property
    def weather_id(self) -> int | None:
        """The weather.xml preset id matching the first weather (the leaderboard's rule), or None."""
        return weather_id_of(self.weathers[0][1]) if self.weathers else None

    def weather_at(self, route_percentage: float) -> WeatherParameters:
        """Weather at a point of the route: linear interpolation between the surrounding entries, clamped."""
        if not self.weathers:
            return ROUTE_DEFAULT
        if route_percentage <= self.weathers[0][0]:
            return self.weathers[0][1]
        for (p0, w0), (p1, w1) in zip(self.weathers, self.weathers[1:]):
            if route_percentage <= p1:
                t = 0.0 if p1 == p0 else (route_percentage - p0) / (p1 - p0)
                return WeatherParameters(
                    **{k: getattr(w0, k) + t * (getattr(w1, k) - getattr(w0, k)) for k in _WEATHER_FIELDS}
                )
        return self.weathers[-1][1]


# ---------------------------------------------------------------------------------------------------------------
# reading


def _float(elem: etree._Element, name: str, path: Path) -> float:
    raw = elem.get(name)
    if raw is None:
        raise RouteFileError(path, f"line {elem.sourceline}: <{elem.tag}> lacks the '{name}' attribute")
    try:
        return float(raw)
    except ValueError:
        raise RouteFileError(path, f"line {elem.sourceline}: <{elem.tag} {name}={raw!r}> is not a number") from None


def _parse_weathers(route: etree._Element, path: Path) -> tuple[tuple[float, WeatherParameters], ...]:
    weathers_elem = route.find("weathers")
    if weathers_elem is None:
        return ((0.0, ROUTE_DEFAULT),)
    out: list[tuple[float, WeatherParameters]] = []
    for elem in weathers_elem.iter("weather"):
        percentage = _float(elem, "route_percentage", path)
        values: dict[str, float] = {}
        for name in elem.attrib:
            if name in _WEATHER_FIELDS:
                values[name] = _float(elem, name, path)
            elif name != "route_percentage":
                log.warning("%s: line %s: ignoring '%s', not a weather parameter", path, elem.sourceline, name)
        out.append((percentage, ROUTE_DEFAULT.replace(**values)))
    out.sort(key=lambda item: item[0])
    return tuple(out)


def _plain(value: str, what: str, elem: etree._Element, path: Path) -> str:
    # Route ids, towns and scenario names and types end up in clip, record and map file names.
    try:
        return check_safe_name(value, what)
    except UnsafeNameError as exc:
        raise RouteFileError(path, f"line {elem.sourceline}: {exc}") from None


def _parse_scenario(elem: etree._Element, path: Path) -> ScenarioConfig:
    name, type_ = elem.get("name"), elem.get("type")
    if not name or not type_:
        raise RouteFileError(path, f"line {elem.sourceline}: <scenario> needs both 'name' and 'type'")
    _plain(name, "scenario name", elem, path)
    _plain(type_, "scenario type", elem, path)
    trigger: Transform | None = None
    params: dict[str, dict[str, str]] = {}
    for child in elem:
        if not isinstance(child.tag, str):
            continue  # comments and processing instructions
        if child.tag == "trigger_point":
            if trigger is not None:
                raise RouteFileError(path, f"line {child.sourceline}: scenario {name!r} has a second <trigger_point>")
            trigger = Transform(
                Location(_float(child, "x", path), _float(child, "y", path), _float(child, "z", path)),
                Rotation(yaw=_float(child, "yaw", path)),
            )
        else:
            # Like the leaderboard, a repeated tag keeps its last attributes.
            params[child.tag] = {str(k): str(v) for k, v in child.attrib.items()}
    if trigger is None:
        raise RouteFileError(path, f"line {elem.sourceline}: scenario {name!r} has no <trigger_point>")
    return ScenarioConfig(name=name, type=type_, trigger_point=trigger, other_parameters=params)


def _parse_route(elem: etree._Element, path: Path) -> Route:
    route_id, town = elem.get("id"), elem.get("town")
    if not route_id or not town:
        raise RouteFileError(path, f"line {elem.sourceline}: <route> needs both 'id' and 'town'")
    _plain(route_id, "route id", elem, path)
    _plain(town, "route town", elem, path)
    road_raw = elem.get("road_id")
    try:
        road_id = int(road_raw) if road_raw is not None else None
    except ValueError:
        raise RouteFileError(path, f"line {elem.sourceline}: route {route_id} has road_id={road_raw!r}") from None
    waypoints_elem = elem.find("waypoints")
    if waypoints_elem is None:
        raise RouteFileError(path, f"line {elem.sourceline}: route {route_id} has no <waypoints>")
    waypoints = tuple(
        Location(_float(p, "x", path), _float(p, "y", path), _float(p, "z", path))
        for p in waypoints_elem.iter("position")
    )
    if not waypoints:
        raise RouteFileError(path, f"line {waypoints_elem.sourceline}: route {route_id} has no <position> keypoint")
    scenarios_elem = elem.find("scenarios")
    scenarios = (
        tuple(_parse_scenario(s, path) for s in scenarios_elem.iter("scenario")) if scenarios_elem is not None else ()
    )
    return Route(
        id=route_id,
        town=town,
        waypoints=waypoints,
        scenarios=scenarios,
        weathers=_parse_weathers(elem, path),
        road_id=road_id,
    )


def read_routes(path: str | Path) -> list[Route]:
    """All routes of a Leaderboard 2.0 route file, in file order; errors name the file and line."""
    path = Path(path)
    if not path.is_file():
        raise RouteFileError(path, "route file not found")
    parser = etree.XMLParser(remove_comments=False, resolve_entities=False)
    try:
        root = etree.parse(str(path), parser).getroot()
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno is not None else "?"
        raise RouteFileError(path, f"line {line}: malformed XML: {exc.msg}") from None
    except OSError as exc:
        raise RouteFileError(path, f"cannot be read: {exc}") from None
    if root.tag == "weathers":
        raise RouteFileError(
            path,
            "this is a weather preset file (<weathers> of <case weather_id>), not a route file; "
            "read it with b2d_data.format.weather.load_weather_xml",
        )
    if root.tag != "routes":
        raise RouteFileError(path, f"line {root.sourceline}: root element is <{root.tag}>, expected <routes>")
    routes = [_parse_route(elem, path) for elem in root.iter("route")]
    seen: dict[str, int] = {}
    for route in routes:
        seen[route.id] = seen.get(route.id, 0) + 1
    repeated = sorted(rid for rid, n in seen.items() if n > 1)
    if repeated:
        raise RouteFileError(path, f"route ids appear more than once: {', '.join(repeated[:10])}")
    return routes


def read_route_argument(path: str | Path) -> list[Route]:
    """:func:`read_routes` of a route file named on a command line: a bare shipped name (``bench2drive220.xml``) that
    does not exist here is the file the package ships."""
    from b2d_data.data import shipped_or_given

    return read_routes(shipped_or_given(Path(path)))


def routes_by_id(routes: Iterable[Route]) -> dict[str, Route]:
    """Index routes by their id."""
    return {route.id: route for route in routes}


# ---------------------------------------------------------------------------------------------------------------
# writing


def _num(value: float) -> str:
    return repr(float(value))


def _weather_attributes(percentage: float, weather: WeatherParameters) -> dict[str, str]:
    attrs = {"route_percentage": _num(percentage)}
    attrs.update(weather.to_xml_attributes())
    # Fields outside the eight of weather.xml are written only when they differ from the parser's base.
    for name in _WEATHER_FIELDS:
        if name not in XML_ATTRIBUTES and getattr(weather, name) != getattr(ROUTE_DEFAULT, name):
            attrs[name] = _num(getattr(weather, name))
    return attrs


def _route_element(route: Route) -> etree._Element:
    attrs = {"id": str(route.id), "town": route.town}
    if route.road_id is not None:
        attrs["road_id"] = str(route.road_id)
    elem = etree.Element("route", attrs)
    waypoints = etree.SubElement(elem, "waypoints")
    for p in route.waypoints:
        etree.SubElement(waypoints, "position", {"x": _num(p.x), "y": _num(p.y), "z": _num(p.z)})
    scenarios = etree.SubElement(elem, "scenarios")
    for s in route.scenarios:
        s_elem = etree.SubElement(scenarios, "scenario", {"name": s.name, "type": s.type})
        t = s.trigger_point
        etree.SubElement(
            s_elem,
            "trigger_point",
            {"x": _num(t.location.x), "y": _num(t.location.y), "z": _num(t.location.z), "yaw": _num(t.rotation.yaw)},
        )
        for tag, attributes in s.other_parameters.items():
            etree.SubElement(s_elem, tag, dict(attributes))
    # A route whose weathers are exactly the parser's default is written without <weathers>, as it was read.
    if tuple(route.weathers) != ((0.0, ROUTE_DEFAULT),):
        weathers = etree.SubElement(elem, "weathers")
        for percentage, weather in route.weathers:
            etree.SubElement(weathers, "weather", _weather_attributes(percentage, weather))
    return elem


def write_routes(routes: Sequence[Route], path: str | Path) -> None:
    """Write routes as a Leaderboard 2.0 route file (UTF-8 with declaration, 3-space indentation)."""
    root = etree.Element("routes")
    for route in routes:
        root.append(_route_element(route))
    etree.indent(root, space=_INDENT)
    Path(path).write_bytes(etree.tostring(root, xml_declaration=True, encoding="utf-8", pretty_print=True))
