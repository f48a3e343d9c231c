"""Route XML: every real Bench2Drive route file parses and survives a write/read round trip."""

from __future__ import annotations

import pytest

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.format.weather import PRESETS, ROUTE_DEFAULT, WeatherParameters
from b2d_data.scenarios.route_xml import Route, RouteFileError, ScenarioConfig, read_routes, write_routes

ROUTE_FILES = {
    "bench2drive220.xml": 220,
    "bench2drive_0.0.4_val.xml": 220,
    "drivetransformer_bench2drive_dev10.xml": 10,
    "routes_training.xml": 90,
}


@pytest.mark.parametrize("name", sorted(ROUTE_FILES))
def test_real_route_files_round_trip(b2d_data_dir, tmp_path, name):
    routes = read_routes(b2d_data_dir / name)
    assert len(routes) == ROUTE_FILES[name]
    out = tmp_path / name
    write_routes(routes, out)
    assert read_routes(out) == routes


def test_weather_file_is_refused_explicitly(b2d_data_dir):
    with pytest.raises(RouteFileError, match="weather.xml: this is a weather preset file"):
        read_routes(b2d_data_dir / "weather.xml")


def test_bench2drive220_first_route(b2d_data_dir):
    routes = read_routes(b2d_data_dir / "bench2drive220.xml")
    first = routes[0]
    assert (first.id, first.town, first.road_id, first.scenario_type) == ("1711", "Town12", None, "ParkingCutIn")
    assert first.waypoints[0] == Location(-497.6, 3672.9, 364.9)
    (scenario,) = first.scenarios
    assert scenario.name == "ParkingCutIn_1"
    assert scenario.trigger_point == Transform(Location(-497.7, 3659.9, 364.7), Rotation(yaw=-90.2))
    assert scenario.other_parameters == {"direction": {"value": "left"}} and scenario.parameter("direction") == "left"
    # Both weathers (0 % and 100 %) are preset 15: cloud 100, rain 50, deposits 100, wet 80, wind 80, alt 45, fog 10.
    assert [p for p, _ in first.weathers] == [0.0, 100.0] and first.weather_id == 15
    assert sum(1 for r in routes if r.road_id is not None) == 185  # format.md §7.1


def test_v004_val_weathers(b2d_data_dir):
    routes = read_routes(b2d_data_dir / "bench2drive_0.0.4_val.xml")
    defaults = [r for r in routes if r.weathers == ((0.0, ROUTE_DEFAULT),)]
    # 4 routes have no <weathers>: the parser's base weather, which is preset 26.
    assert len(defaults) == 4 and {r.weather_id for r in defaults} == {26}
    # 10 routes carry −1.0 in every attribute; no preset matches them.
    unset = [r for r in routes if all(v == "-1.0" for _, w in r.weathers for v in w.to_xml_attributes().values())]
    assert len(unset) == 10 and {r.weather_id for r in unset} == {None}


def test_training_routes_with_many_scenarios(b2d_data_dir):
    routes = read_routes(b2d_data_dir / "routes_training.xml")
    assert max(len(r.scenarios) for r in routes) == 84
    first = routes[0]
    # Sun altitude 90 at 0 % and 15 at 100 %: halfway, (90 + 15) / 2 = 52.5; the other fields are equal.
    assert first.weathers[0][1].sun_altitude_angle == 90.0 and first.weathers[1][1].sun_altitude_angle == 15.0
    assert first.weather_at(50.0).sun_altitude_angle == pytest.approx(52.5)
    assert first.weather_at(-5.0) == first.weathers[0][1] and first.weather_at(120.0) == first.weathers[1][1]
    assert first.weather_id == 0  # the first weather is preset 0


def test_constructed_route_round_trip(tmp_path):
    scenario = ScenarioConfig(
        name="HazardAtSideLane_1",
        type="HazardAtSideLane",
        trigger_point=Transform(Location(1.5, -2.0, 0.3), Rotation(yaw=270.0)),
        other_parameters={"distance": {"value": "60"}, "frequency": {"from": "30", "to": "50"}},
    )
    night = PRESETS[21].replace(fog_distance=12.0)  # a field beyond weather.xml's eight survives too
    route = Route(
        id="7",
        town="Town04",
        waypoints=(Location(0.0, 0.0, 0.0), Location(2.0, 0.0, 0.1)),
        scenarios=(scenario,),
        weathers=((0.0, PRESETS[1]), (100.0, night)),
        road_id=42,
    )
    path = tmp_path / "one.xml"
    write_routes([route], path)
    text = path.read_text()
    assert text.startswith("<?xml version='1.0' encoding='utf-8'?>\n<routes>\n   <route id=\"7\"")
    assert read_routes(path) == [route]


def test_default_weather_route_is_written_without_weathers(tmp_path):
    route = Route(id="1", town="Town01", waypoints=(Location(),))
    path = tmp_path / "r.xml"
    write_routes([route], path)
    assert "<weathers" not in path.read_text()
    (back,) = read_routes(path)
    assert back.weathers == ((0.0, WeatherParameters(cloudiness=50.0, sun_altitude_angle=70.0)),)


@pytest.mark.parametrize(
    ("xml", "problem"),
    [
        ("<routes>\n  <route id='1' town='Town01'>\n</routes>", "line 3: malformed XML"),
        ("<routes><route id='1'/></routes>", "line 1: <route> needs both 'id' and 'town'"),
        ("<routes>\n<route id='1' town='T'><waypoints>\n<position x='a' y='0' z='0'/></waypoints></route></routes>",
         "line 3: <position x='a'> is not a number"),
        ("<routes><route id='1' town='T'><waypoints><position x='0' y='0' z='0'/></waypoints><scenarios>\n"
         "<scenario name='A_1' type='A'><distance value='3'/></scenario></scenarios></route></routes>",
         "line 2: scenario 'A_1' has no <trigger_point>"),
        ("<routes><route id='1' town='T'><waypoints/></route></routes>", "route 1 has no <position> keypoint"),
        ("<routes><route id='1' town='T'><waypoints><position x='0' y='0' z='0'/></waypoints></route>"
         "<route id='1' town='T'><waypoints><position x='0' y='0' z='0'/></waypoints></route></routes>",
         "route ids appear more than once: 1"),
        ("<case/>", "root element is <case>"),
    ],
)  # fmt: skip
def test_malformed_files_name_file_and_line(tmp_path, xml, problem):
    path = tmp_path / "bad.xml"
    path.write_text(xml)
    with pytest.raises(RouteFileError) as exc:
        read_routes(path)
    assert str(exc.value).startswith(f"{path}: ") and problem in str(exc.value)


def test_missing_file(tmp_path):
    with pytest.raises(RouteFileError, match="route file not found"):
        read_routes(tmp_path / "none.xml")


_ONE_ROUTE = (
    "<routes>\n<route id='{id}' town='{town}'>\n<waypoints><position x='0' y='0' z='0'/></waypoints>\n<scenarios>\n"
    "<scenario name='{name}' type='{type}'><trigger_point x='0' y='0' z='0' yaw='0'/></scenario>\n"
    "</scenarios></route></routes>"
)


@pytest.mark.parametrize(
    ("field", "value", "line"),
    [("type", "../../evil", 5), ("name", "a/b", 5), ("town", "../Town200", 2), ("id", "../../x", 2),
     ("type", ".hidden", 5)],
)  # fmt: skip
def test_names_that_would_become_paths_are_refused(tmp_path, field, value, line):
    values = {"id": "1", "town": "Town01", "name": "Accident_1", "type": "Accident"} | {field: value}
    path = tmp_path / "hostile.xml"
    path.write_text(_ONE_ROUTE.format(**values))
    with pytest.raises(RouteFileError) as exc:
        read_routes(path)
    # The file, the line of the element and the offending value are all named.
    what = {"type": "scenario type", "name": "scenario name", "town": "route town", "id": "route id"}[field]
    assert str(exc.value).startswith(f"{path}: line {line}: {what} {value!r} is not a plain name")


def test_plain_names_with_dots_and_dashes_are_kept(tmp_path):
    path = tmp_path / "ok.xml"
    path.write_text(_ONE_ROUTE.format(id="7", town="Town10HD", name="My-Scenario.v2_1", type="My_Type"))
    (route,) = read_routes(path)
    assert (route.id, route.town, route.scenarios[0].name, route.scenario_type) == (
        "7", "Town10HD", "My-Scenario.v2_1", "My_Type")  # fmt: skip
