"""Weather → lighting: sun direction and colour, sky, ambient, fog and wet-road parameters for the shaders."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from b2d_data.format.weather import WeatherParameters


def _smoothstep(e0: float, e1: float, x: float) -> float:
    t = min(1.0, max(0.0, (x - e0) / (e1 - e0)))
    return t * t * (3.0 - 2.0 * t)


def _mix(a: tuple[float, float, float], b: tuple[float, float, float], t: float) -> np.ndarray:
    return np.asarray(a) * (1.0 - t) + np.asarray(b) * t


@dataclass(frozen=True)
class Lighting:
    """Uniform values of one weather state (colours are linear-ish RGB in [0, 1])."""

    sun_dir: np.ndarray
    sun_color: np.ndarray
    sky_zenith: np.ndarray
    sky_horizon: np.ndarray
    ambient_sky: np.ndarray
    ambient_ground: np.ndarray
    cloudiness: float
    fog_color: np.ndarray
    fog_density: float
    fog_start: float
    wetness: float
    puddles: float
    night: float

    @classmethod
    def from_weather(cls, w: WeatherParameters) -> Lighting:
        """Derive the lighting from CARLA weather parameters (sun angles in degrees, others in percent)."""
        alt = float(w.sun_altitude_angle)
        az = math.radians(float(w.sun_azimuth_angle))
        ca = math.cos(math.radians(max(alt, -90.0)))
        sun_dir = np.array([ca * math.cos(az), ca * math.sin(az), math.sin(math.radians(alt))])
        cloud = min(1.0, max(0.0, w.cloudiness / 100.0))
        rain = min(1.0, max(0.0, w.precipitation / 100.0))
        day = _smoothstep(-6.0, 12.0, alt)
        night = 1.0 - _smoothstep(-5.0, 3.0, alt)
        low_sun = 1.0 - _smoothstep(4.0, 35.0, alt)
        overcast = max(cloud, rain)

        sun_strength = 0.78 * _smoothstep(-2.0, 10.0, alt) * (1.0 - 0.8 * overcast)
        sun_color = _mix((1.0, 0.97, 0.9), (1.0, 0.62, 0.36), low_sun) * sun_strength

        zen_day = _mix((0.2, 0.4, 0.75), (0.5, 0.53, 0.57), overcast)
        hor_day = _mix((0.66, 0.76, 0.87), (0.68, 0.7, 0.72), overcast)
        hor_day = _mix(tuple(hor_day), (0.95, 0.62, 0.4), low_sun * (1.0 - overcast) * day)
        zen_night, hor_night = (0.006, 0.009, 0.025), (0.035, 0.04, 0.06)
        sky_zenith = _mix(zen_night, tuple(zen_day), day)
        sky_horizon = _mix(hor_night, tuple(hor_day), day)

        amb_day = 0.42 + 0.2 * overcast
        ambient_sky = _mix((0.03, 0.035, 0.05), (amb_day * 0.95, amb_day, amb_day * 1.08), day)
        ambient_ground = ambient_sky * 0.55

        fog = min(1.0, max(0.0, w.fog_density / 100.0))
        fog_density = 0.0015 + 0.035 * fog + 0.012 * rain
        fog_color = _mix((0.03, 0.035, 0.045), (0.7, 0.72, 0.75), day) * (1.0 - 0.25 * overcast)
        wet = max(w.wetness / 100.0, 0.6 * w.precipitation_deposits / 100.0, rain)
        return cls(
            sun_dir=sun_dir,
            sun_color=sun_color,
            sky_zenith=sky_zenith,
            sky_horizon=sky_horizon,
            ambient_sky=ambient_sky,
            ambient_ground=ambient_ground,
            cloudiness=cloud,
            fog_color=fog_color,
            fog_density=fog_density,
            fog_start=max(0.0, float(w.fog_distance)),
            wetness=min(1.0, max(0.0, wet)),
            puddles=min(1.0, max(0.0, w.precipitation_deposits / 100.0)),
            night=night,
        )
