"""Fixtures for the map tests: a tiny hand-written junction town and the real CARLA towns (each loaded once).

Tiny town (OpenDRIVE frame; CARLA's y is the negated OpenDRIVE y):

- road 1: straight from (0, 0) heading east, 50 m. Lanes: 1 driving (westbound), -1 and -2 driving (eastbound,
  3.5 m), -3 sidewalk (2 m). Centre mark solid yellow (no change), lane -1 broken white (change both), lane -2
  solid white (no change). Road type speed 40 km/h; a 60 km/h speed-limit sign (274) at s = 5 for lanes -1..-2.
  A traffic light (1000001) at s = 48; its references sit on the straight and left-turn connecting roads.
- junction 100: road 10 straight (50, 0) → (70, 0), lanes -1/-2; road 11 left turn, arc of curvature 1/10 from
  (50, 0) to (60, 10), lane -1 (fed by road 1 lane -1); road 12 right turn, arc of curvature −1/10 from
  (50, −3.5) to (60, −13.5), lane -1 (fed by road 1 lane -2). Controller 500 switches the light.
- exits: road 2 east from (70, 0), 30 m, lanes -1/-2 with a stop sign (206) at s = 20 and a crosswalk at s = 10;
  road 3 north from (60, 10), road 4 south from (60, −13.5), 30 m each, lane -1.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from b2d_data.maps import Map, load_opendrive

QUARTER = 10.0 * math.pi / 2.0

_MARK = '<roadMark sOffset="0" type="{type}" color="{color}" width="0.15" laneChange="{change}"/>'


def _lane(lane_id: int, lane_type: str, width: float, mark: tuple[str, str, str], pred=None, succ=None) -> str:
    link = ""
    if pred is not None or succ is not None:
        link = "<link>"
        link += f'<predecessor id="{pred}"/>' if pred is not None else ""
        link += f'<successor id="{succ}"/>' if succ is not None else ""
        link += "</link>"
    t, c, ch = mark
    return (
        f'<lane id="{lane_id}" type="{lane_type}" level="false">{link}'
        f'<width sOffset="0" a="{width}" b="0" c="0" d="0"/>{_MARK.format(type=t, color=c, change=ch)}</lane>'
    )


def _road(road_id, length, geometry, lanes_right, lanes_left="", junction=-1, link="", extra="", center=None):
    t, c, ch = center or ("none", "white", "none")
    left = f"<left>{lanes_left}</left>" if lanes_left else ""
    return (
        f'<road name="Road {road_id}" length="{length}" id="{road_id}" junction="{junction}">'
        f"<link>{link}</link>"
        f'<type s="0" type="town"><speed max="40" unit="km/h"/></type>'
        f"<planView>{geometry}</planView>"
        f'<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>'
        f'<lanes><laneOffset s="0" a="0" b="0" c="0" d="0"/><laneSection s="0">{left}'
        f'<center><lane id="0" type="none" level="false">{_MARK.format(type=t, color=c, change=ch)}</lane></center>'
        f"<right>{lanes_right}</right></laneSection></lanes>{extra}</road>"
    )


def _geom(x, y, hdg, length, kind="<line/>") -> str:
    return f'<geometry s="0" x="{x}" y="{y}" hdg="{hdg}" length="{length}">{kind}</geometry>'


BROKEN_BOTH = ("broken", "white", "both")
SOLID_NONE = ("solid", "white", "none")


def tiny_town_xodr() -> str:
    """The tiny town described in this module's docstring, as OpenDRIVE text."""
    road1 = _road(
        1, 50, _geom(0, 0, 0, 50),
        _lane(-1, "driving", 3.5, BROKEN_BOTH) + _lane(-2, "driving", 3.5, SOLID_NONE)
        + _lane(-3, "sidewalk", 2.0, ("curb", "white", "none")),
        lanes_left=_lane(1, "driving", 3.5, SOLID_NONE),
        link='<successor elementType="junction" elementId="100"/>',
        center=("solid", "yellow", "none"),
        extra=(
            "<signals>"
            '<signal name="Light" id="1" s="48" t="-8" zOffset="0" hOffset="0" roll="0" pitch="0" orientation="-"'
            ' dynamic="yes" country="OpenDRIVE" type="1000001" subtype="-1" value="-1" height="1" width="0.5">'
            '<validity fromLane="0" toLane="0"/></signal>'
            '<signal name="Speed60" id="3" s="5" t="-8" zOffset="2" hOffset="0" roll="0" pitch="0" orientation="-"'
            ' dynamic="no" country="OpenDRIVE" type="274" subtype="" value="60" unit="km/h" height="1" width="1">'
            '<validity fromLane="-1" toLane="-2"/></signal>'
            "</signals>"
        ),
    )  # fmt: skip
    road10 = _road(
        10, 20, _geom(50, 0, 0, 20),
        _lane(-1, "driving", 3.5, BROKEN_BOTH, -1, -1) + _lane(-2, "driving", 3.5, SOLID_NONE, -2, -2),
        junction=100,
        link='<predecessor elementType="road" elementId="1" contactPoint="end"/>'
        '<successor elementType="road" elementId="2" contactPoint="start"/>',
        extra='<signals><signalReference id="1" s="1" t="0" orientation="-"><validity fromLane="-1" toLane="-2"/>'
        "</signalReference></signals>",
    )  # fmt: skip
    road11 = _road(
        11, QUARTER, _geom(50, 0, 0, QUARTER, '<arc curvature="0.1"/>'),
        _lane(-1, "driving", 3.5, SOLID_NONE, -1, -1), junction=100,
        link='<predecessor elementType="road" elementId="1" contactPoint="end"/>'
        '<successor elementType="road" elementId="3" contactPoint="start"/>',
        extra='<signals><signalReference id="1" s="1" t="0" orientation="-"><validity fromLane="-1" toLane="-1"/>'
        "</signalReference></signals>",
    )  # fmt: skip
    road12 = _road(
        12, QUARTER, _geom(50, -3.5, 0, QUARTER, '<arc curvature="-0.1"/>'),
        _lane(-1, "driving", 3.5, SOLID_NONE, -2, -1), junction=100,
        link='<predecessor elementType="road" elementId="1" contactPoint="end"/>'
        '<successor elementType="road" elementId="4" contactPoint="start"/>',
    )  # fmt: skip
    road2 = _road(
        2, 30, _geom(70, 0, 0, 30),
        _lane(-1, "driving", 3.5, BROKEN_BOTH) + _lane(-2, "driving", 3.5, SOLID_NONE),
        link='<predecessor elementType="junction" elementId="100"/>',
        extra=(
            '<objects><object id="7" name="Crosswalk" type="crosswalk" s="10" t="-3.5" zOffset="0" hdg="0"'
            ' orientation="none" length="3" width="7" height="0" pitch="0" roll="0"><outline>'
            '<cornerLocal u="-1.5" v="-3.5" z="0"/><cornerLocal u="1.5" v="-3.5" z="0"/>'
            '<cornerLocal u="1.5" v="3.5" z="0"/><cornerLocal u="-1.5" v="3.5" z="0"/>'
            "</outline></object></objects>"
            "<signals>"
            '<signal name="Stop" id="2" s="20" t="-8" zOffset="2" hOffset="0" roll="0" pitch="0" orientation="-"'
            ' dynamic="no" country="OpenDRIVE" type="206" subtype="-1" value="-1" height="1" width="1">'
            '<validity fromLane="-1" toLane="-2"/></signal>'
            "</signals>"
        ),
    )  # fmt: skip
    road3 = _road(
        3, 30, _geom(60, 10, math.pi / 2, 30), _lane(-1, "driving", 3.5, SOLID_NONE),
        link='<predecessor elementType="junction" elementId="100"/>',
    )  # fmt: skip
    road4 = _road(
        4, 30, _geom(60, -13.5, -math.pi / 2, 30), _lane(-1, "driving", 3.5, SOLID_NONE),
        link='<predecessor elementType="junction" elementId="100"/>',
    )  # fmt: skip
    junction = (
        '<junction id="100" name="cross">'
        '<connection id="0" incomingRoad="1" connectingRoad="10" contactPoint="start">'
        '<laneLink from="-1" to="-1"/><laneLink from="-2" to="-2"/></connection>'
        '<connection id="1" incomingRoad="1" connectingRoad="11" contactPoint="start">'
        '<laneLink from="-1" to="-1"/></connection>'
        '<connection id="2" incomingRoad="1" connectingRoad="12" contactPoint="start">'
        '<laneLink from="-2" to="-1"/></connection>'
        '<controller id="500" type="0" sequence="0"/>'
        "</junction>"
    )
    controller = '<controller name="ctrl500" id="500" sequence="0"><control signalId="1" type=""/></controller>'
    header = (
        '<header revMajor="1" revMinor="4" name="Tiny" version="1">'
        "<geoReference><![CDATA[+proj=tmerc +lat_0=49.0 +lon_0=8.0 +k=1 +x_0=0 +y_0=0]]></geoReference></header>"
    )
    body = road1 + road10 + road11 + road12 + road2 + road3 + road4 + junction + controller
    return f'<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE>{header}{body}</OpenDRIVE>\n'


@pytest.fixture(scope="session")
def tiny_xodr(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny town written to a file named ``Town90.xodr``."""
    path = tmp_path_factory.mktemp("tiny") / "Town90.xodr"
    path.write_text(tiny_town_xodr(), encoding="utf-8")
    return path


@pytest.fixture(scope="session")
def tiny_map(tiny_xodr: Path) -> Map:
    """The tiny town, loaded once."""
    return load_opendrive(tiny_xodr)


class _TownCache:
    """Loads each CARLA town on first use and keeps it for the session."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.maps: dict[str, Map] = {}

    def names(self) -> list[str]:
        return sorted(p.stem for p in self.folder.glob("*.xodr"))

    def __getitem__(self, town: str) -> Map:
        if town not in self.maps:
            self.maps[town] = load_opendrive(self.folder / f"{town}.xodr")
        return self.maps[town]


@pytest.fixture(scope="session")
def carla_towns(carla_maps_dir: Path) -> _TownCache:
    """Lazily loaded shipped CARLA towns (each parsed once per session)."""
    return _TownCache(carla_maps_dir)
