"""Shared pieces of the closed-loop tests: short routes on the shipped Town01 and the test agents' paths."""

from __future__ import annotations

from pathlib import Path

import pytest

from b2d_data.format.transform import Location
from b2d_data.format.weather import preset
from b2d_data.scenarios.route_xml import Route, write_routes

AGENTS = Path(__file__).resolve().parent / "agents"
BEHAVIOUR_AGENT = AGENTS / "behaviour_agent.py"
B2D_STYLE_AGENT = AGENTS / "b2d_style_agent.py"

#: A straight 30 m stretch of Town01's road at y = 59.5 (part of bench2drive220 route 24841), driven east.
STRAIGHT = (Location(191.2, 59.5, 0.0), Location(221.2, 59.5, 0.0))


def short_routes(path: Path, ids: list[str], weather_id: int = 1, missing_town: str | None = None) -> Path:
    """A route file with one 30 m Town01 route per id (clear weather), plus one on ``missing_town`` if given."""
    weather = preset(weather_id)
    routes = [Route(id=i, town="Town01", waypoints=STRAIGHT, weathers=((0.0, weather), (100.0, weather))) for i in ids]
    if missing_town is not None:
        routes.append(Route(id="999", town=missing_town, waypoints=STRAIGHT))
    write_routes(routes, path)
    return path


@pytest.fixture
def route_file(tmp_path: Path) -> Path:
    """Two short Town01 routes (ids 1 and 2) and one on Town02, whose map the package does not ship."""
    return short_routes(tmp_path / "routes.xml", ["1", "2"], missing_town="Town02")
