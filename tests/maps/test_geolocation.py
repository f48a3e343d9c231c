"""CARLA's GNSS projection (spherical Mercator scaled by cos(lat_0))."""

from __future__ import annotations

import math

import pytest

from b2d_data.format.transform import Location
from b2d_data.maps import GeoReference


def test_one_degree_of_longitude_at_the_equator():
    # With lat_0 = lon_0 = 0 the scale is 1: x = π·R/180 = 111319.49 m east is exactly 1° of longitude.
    geo = GeoReference(0.0, 0.0)
    g = geo.transform(Location(math.pi * 6378137.0 / 180.0, 0.0, 3.0))
    assert g.longitude == pytest.approx(1.0, abs=1e-12) and g.latitude == pytest.approx(0.0, abs=1e-12)
    assert g.altitude == 3.0
    # North is −y in CARLA: y = −R·ln(tan(45° + 0.5°)) is 1° of latitude.
    north = geo.transform(Location(0.0, -6378137.0 * math.log(math.tan(math.radians(45.5))), 0.0))
    assert north.latitude == pytest.approx(1.0, abs=1e-9)


def test_round_trip_and_header_parsing(tiny_map):
    assert (tiny_map.geo_reference.lat_0, tiny_map.geo_reference.lon_0) == (49.0, 8.0)
    origin = tiny_map.transform_to_geolocation(Location(0.0, 0.0, 0.0))
    assert (origin.latitude, origin.longitude) == pytest.approx((49.0, 8.0), abs=1e-12)
    for loc in (Location(123.4, -567.8, 9.0), Location(-3000.0, 2500.0, -1.5)):
        g = tiny_map.transform_to_geolocation(loc)
        back = tiny_map.geolocation_to_location(g.latitude, g.longitude, g.altitude)
        assert back.distance(loc) < 1e-6
    # East moves longitude up, south (+y) moves latitude down.
    east = tiny_map.transform_to_geolocation((100.0, 0.0, 0.0))
    south = tiny_map.transform_to_geolocation((0.0, 100.0, 0.0))
    assert east.longitude > 8.0 and south.latitude < 49.0


def test_missing_reference_defaults_to_zero():
    assert GeoReference.parse("") == GeoReference(0.0, 0.0)
    assert GeoReference.parse("+proj=tmerc +lat_0=-33.5 +lon_0=1e1") == GeoReference(-33.5, 10.0)
