"""The 23 weather presets equal the real weather.xml."""

from __future__ import annotations

import pytest

from b2d_data.format.weather import PRESETS, ROUTE_DEFAULT, UnknownWeatherError, load_weather_xml, preset, weather_id_of


def test_presets_equal_weather_xml(b2d_data_dir):
    from_xml = load_weather_xml(b2d_data_dir / "weather.xml")
    assert sorted(from_xml) == sorted(PRESETS) and len(PRESETS) == 23
    for weather_id, params in from_xml.items():
        assert PRESETS[weather_id] == params, weather_id


def test_weather_id_lookup_and_default():
    assert weather_id_of(PRESETS[14]) == 14
    assert weather_id_of(ROUTE_DEFAULT) == 26  # the route parser's base weather equals preset 26
    assert weather_id_of(PRESETS[3].replace(cloudiness=61.0)) is None
    with pytest.raises(UnknownWeatherError, match="unknown weather id 4"):
        preset(4)
