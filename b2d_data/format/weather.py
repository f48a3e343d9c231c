"""The 23 Bench2Drive weather presets of leaderboard/data/weather.xml (format.md §7.2)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

#: Attribute order of a ``<weather>`` element in weather.xml and route files.
XML_ATTRIBUTES: tuple[str, ...] = (
    "cloudiness",
    "precipitation",
    "precipitation_deposits",
    "wetness",
    "wind_intensity",
    "sun_azimuth_angle",
    "sun_altitude_angle",
    "fog_density",
)

#: Key order of the ``weather`` dict written into annotations.
ANNO_KEYS: tuple[str, ...] = (
    "cloudiness",
    "precipitation",
    "precipitation_deposits",
    "wind_intensity",
    "sun_azimuth_angle",
    "sun_altitude_angle",
    "fog_density",
    "fog_distance",
    "wetness",
    "fog_falloff",
)


@dataclass(frozen=True)
class WeatherParameters:
    """CARLA ``WeatherParameters`` subset that Bench2Drive sets (percentages, degrees, metres)."""

    cloudiness: float = 0.0
    precipitation: float = 0.0
    precipitation_deposits: float = 0.0
    wetness: float = 0.0
    wind_intensity: float = 0.0
    sun_azimuth_angle: float = 0.0
    sun_altitude_angle: float = 0.0
    fog_density: float = 0.0
    fog_distance: float = 0.0
    fog_falloff: float = 0.0

    def to_anno(self) -> dict[str, float]:
        """The ``weather`` dict of an annotation, in its key order."""
        return {key: float(getattr(self, key)) for key in ANNO_KEYS}

    def to_xml_attributes(self) -> dict[str, str]:
        """Attributes of a ``<weather>`` element, formatted like the released files (``"5.0"``)."""
        return {key: repr(float(getattr(self, key))) for key in XML_ATTRIBUTES}

    @property
    def is_night(self) -> bool:
        """The sun is below the horizon."""
        return self.sun_altitude_angle < 0.0

    def replace(self, **changes: float) -> WeatherParameters:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)


#: The leaderboard parser's starting point for a route without weather (equals preset 26).
ROUTE_DEFAULT = WeatherParameters(cloudiness=50.0, sun_altitude_angle=70.0)


def _preset(cloud: float, rain: float, deposits: float, wet: float, wind: float, az: float, alt: float, fog: float):
    return WeatherParameters(cloud, rain, deposits, wet, wind, az, alt, fog)


PRESETS: dict[int, WeatherParameters] = {
    0: _preset(5, 0, 0, 0, 10, -1, 90, 2),
    1: _preset(5, 0, 0, 0, 10, -1, 15, 2),
    2: _preset(20, 30, 50, 0, 30, -1, 45, 3),
    3: _preset(60, 60, 60, 0, 60, -1, 45, 3),
    5: _preset(80, 0, 50, 20, 10, -1, 45, 3),
    6: _preset(5, 0, 50, 0, 10, -1, 15, 10),
    7: _preset(5, 0, 0, 0, 10, -1, 45, 2),
    8: _preset(100, 100, 90, 0, 100, -1, 45, 7),
    9: _preset(70, 60, 60, 0, 60, -1, 45, 50),
    10: _preset(40, 100, 90, 0, 100, -1, 0, 7),
    11: _preset(100, 60, 60, 0, 60, -1, 45, 50),
    12: _preset(5, 0, 0, 0, 10, -1, 45, 50),
    13: _preset(5, 0, 0, 0, 10, -1, 15, 50),
    14: _preset(100, 100, 50, 50, 100, -1, 45, 10),
    15: _preset(100, 50, 100, 80, 80, -1, 45, 10),
    18: _preset(40, 0, 50, 0, 10, -1, 15, 2),
    19: _preset(40, 0, 50, 0, 10, -1, -90, 2),
    20: _preset(60, 30, 50, 60, 30, -1, -90, 3),
    21: _preset(100, 100, 90, 100, 100, -1, -90, 3),
    22: _preset(5, 0, 0, 0, 10, -1, -90, 60),
    23: _preset(80, 60, 60, 80, 60, -1, -90, 60),
    25: _preset(100, 100, 90, 100, 100, -1, -90, 100),
    26: _preset(50, 0, 0, 0, 0, 0, 70, 0),
}

WEATHER_IDS: tuple[int, ...] = tuple(sorted(PRESETS))


class UnknownWeatherError(KeyError):
    """A weather id that is not one of the 23 presets."""


def preset(weather_id: int) -> WeatherParameters:
    """The preset of a weather id; raises naming the valid ids."""
    try:
        return PRESETS[int(weather_id)]
    except KeyError:
        raise UnknownWeatherError(
            f"unknown weather id {weather_id!r}; valid ids: {', '.join(map(str, WEATHER_IDS))}"
        ) from None


def weather_id_of(params: WeatherParameters) -> int | None:
    """The first preset whose weather.xml attributes equal ``params`` (the leaderboard's rule), else None."""
    wanted = params.to_xml_attributes()
    for weather_id in WEATHER_IDS:
        if PRESETS[weather_id].to_xml_attributes() == wanted:
            return weather_id
    return None


def load_weather_xml(path: str | Path) -> dict[int, WeatherParameters]:
    """Read a weather.xml file (``<case weather_id>`` blocks); the first ``<weather>`` of each case wins."""
    from lxml import etree

    path = Path(path)
    try:
        root = etree.parse(str(path)).getroot()
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ValueError(f"{path}: not a readable weather XML file: {exc}") from exc
    out: dict[int, WeatherParameters] = {}
    for case in root.iter("case"):
        first = case.find("weather")
        if first is None or case.get("weather_id") is None:
            raise ValueError(f"{path}: <case> on line {case.sourceline} lacks weather_id or a <weather> element")
        values = {key: float(first.get(key, getattr(WeatherParameters(), key))) for key in XML_ATTRIBUTES}
        out[int(case.get("weather_id"))] = WeatherParameters(**values)
    return out
