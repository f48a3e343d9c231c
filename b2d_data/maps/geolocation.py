"""CARLA's GNSS projection: world location ↔ latitude/longitude around the map's geo reference.

CARLA reads ``+lat_0`` / ``+lon_0`` from the header ``geoReference`` (0, 0 when absent) and projects with a
spherical Mercator scaled by cos(lat_0) (``carla::geom::GeoLocation::Transform``; the leaderboard's
``_location_to_gps`` is the same formula). East is +x; north is −y, because CARLA's y points south.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from b2d_data.format.transform import Location

#: WGS84 equatorial radius used by CARLA (m).
EARTH_RADIUS_EQUA = 6378137.0

_NUMBER = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"


@dataclass(frozen=True)
class GeoLocation:
    """carla.GeoLocation: degrees and metres."""

    latitude: float
    longitude: float
    altitude: float


@dataclass(frozen=True)
class GeoReference:
    """The map's projection origin (degrees)."""

    lat_0: float = 0.0
    lon_0: float = 0.0
    altitude: float = 0.0

    @classmethod
    def parse(cls, text: str) -> GeoReference:
        """Read ``+lat_0=`` and ``+lon_0=`` from a PROJ string (missing values stay 0, as in CARLA)."""
        lat = re.search(r"\+lat_0=" + _NUMBER, text or "")
        lon = re.search(r"\+lon_0=" + _NUMBER, text or "")
        return cls(float(lat.group(1)) if lat else 0.0, float(lon.group(1)) if lon else 0.0)

    def _scale(self) -> float:
        return math.cos(math.radians(self.lat_0))

    def _origin_mercator(self) -> tuple[float, float]:
        scale = self._scale()
        mx = scale * math.radians(self.lon_0) * EARTH_RADIUS_EQUA
        my = scale * EARTH_RADIUS_EQUA * math.log(math.tan(math.radians(90.0 + self.lat_0) / 2.0))
        return mx, my

    def transform(self, location: Location) -> GeoLocation:
        """World location → latitude, longitude (degrees) and altitude (m)."""
        scale = self._scale()
        mx, my = self._origin_mercator()
        mx += location.x
        my -= location.y
        lon = math.degrees(mx / (EARTH_RADIUS_EQUA * scale))
        lat = 360.0 * math.atan(math.exp(my / (EARTH_RADIUS_EQUA * scale))) / math.pi - 90.0
        return GeoLocation(lat, lon, self.altitude + location.z)

    def inverse(self, latitude: float, longitude: float, altitude: float = 0.0) -> Location:
        """Latitude, longitude (degrees), altitude (m) → world location."""
        scale = self._scale()
        mx0, my0 = self._origin_mercator()
        mx = scale * math.radians(longitude) * EARTH_RADIUS_EQUA
        my = scale * EARTH_RADIUS_EQUA * math.log(math.tan(math.radians(90.0 + latitude) / 2.0))
        return Location(mx - mx0, -(my - my0), altitude - self.altitude)
