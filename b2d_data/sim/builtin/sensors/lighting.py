"""Weather → lighting: sun direction and colour, sky, ambient, fog, shadows and wet-road parameters for the shaders.

Fog is Unreal Engine 4's exponential height fog, which CARLA's weather drives: UE takes ``FogDensity`` and
``FogHeightFalloff`` per 1000 cm in base-2 exponentials, i.e. an extinction ``ln(2)² · FogDensity / 10`` per metre
at the fog's base height, halving every ``10 / FogHeightFalloff`` metres above it. CARLA's weather hands UE
``fog_density / 100`` (assumed: the mapping lives in CARLA's weather blueprint, not in its C++ source) and
``fog_falloff`` as given; ``fog_distance`` is UE's start distance (no fog on the first metres of every ray). The
base height is the world's z = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from b2d_data.format.weather import WeatherParameters

#: Fog extinction per metre at the base height for ``fog_density`` = 100 (UE FogDensity 1.0): ln(2)² / 10.
FOG_EXTINCTION_AT_100 = math.log(2.0) ** 2 / 10.0
#: Height falloff per metre for ``fog_falloff`` = 1 (UE FogHeightFalloff 1.0): ln(2) / 10.
FOG_FALLOFF_PER_UNIT = math.log(2.0) / 10.0
#: Extra extinction per metre of heavy rain (precipitation 100): streaks and spray, which CARLA draws as particles.
RAIN_EXTINCTION = 0.012
#: Height of the fog's base (world z, metres).
FOG_BASE_HEIGHT = 0.0


def _smoothstep(e0: float, e1: float, x: float) -> float:
    t = min(1.0, max(0.0, (x - e0) / (e1 - e0)))
    return t * t * (3.0 - 2.0 * t)


def _mix(a: tuple[float, float, float], b: tuple[float, float, float], t: float) -> np.ndarray:
    return np.asarray(a) * (1.0 - t) + np.asarray(b) * t


def fog_amount(
    camera: np.ndarray, point: np.ndarray, density: float, falloff: float, start: float, base: float = FOG_BASE_HEIGHT
) -> float:
    """Fraction of fog colour in the pixel of ``point`` seen from ``camera`` (the scene shader's ``fog_amount``).

    The optical depth is the line integral of ``density · exp(−falloff · (z − base))`` along the ray from the point
    ``start`` metres out (or the camera, when the point is nearer) to the point; the fog amount is
    ``1 − exp(−optical depth)``.
    """
    d = np.asarray(point, np.float64) - np.asarray(camera, np.float64)
    length = float(np.linalg.norm(d))
    inside = max(length - start, 0.0)
    slope = d[2] / max(length, 1e-4)
    h0 = float(camera[2]) + slope * min(start, length) - base
    x = falloff * slope * inside
    g = (1.0 - math.exp(-x)) / x if abs(x) > 1e-4 else 1.0 - 0.5 * x
    depth = density * math.exp(-falloff * h0) * inside * g
    return 1.0 - math.exp(-depth)


@dataclass(frozen=True)
class Lighting:
    """Uniform values of one weather state (colours are linear-ish RGB in [0, 1]; lengths in metres)."""

    sun_dir: np.ndarray
    sun_color: np.ndarray
    sky_zenith: np.ndarray
    sky_horizon: np.ndarray
    ambient_sky: np.ndarray
    ambient_ground: np.ndarray
    cloudiness: float
    fog_color: np.ndarray
    fog_density: float  # extinction per metre at the fog's base height
    fog_start: float
    wetness: float
    puddles: float
    night: float
    fog_falloff: float = 0.0  # per metre of height
    shadow_strength: float = 0.0  # share of the sun's light a fully shadowed fragment loses (0: no shadow pass)
    shadow_softness: float = 0.0  # penumbra radius in metres (overcast skies blur the shadows)
    vehicle_lights_on: bool = False  # vehicles drive with their lamps lit (CARLA's traffic-manager rule)
    beams: float = 0.0  # how much of the low beams' light shows against the daylight (0 by day, 1 at night)

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
        fog_density = FOG_EXTINCTION_AT_100 * fog + RAIN_EXTINCTION * rain
        # The fog's colour is the ambient light it scatters: the night sky glow (city lights on low clouds) at night.
        fog_color = _mix((0.06, 0.065, 0.08), (0.7, 0.72, 0.75), day) * (1.0 - 0.25 * overcast)
        wet = max(w.wetness / 100.0, 0.6 * w.precipitation_deposits / 100.0, rain)
        # Clouds in front of the sun widen the penumbra and fill the shadows with sky light; sun_color already
        # carries the dimmer sun, so a shadow's depth falls twice with cloud (the sun's share and this strength).
        # Where a shadow would take less than 0.06 of the light (an overcast or a set sun) there is no shadow pass.
        shadow_strength = 1.0 - 0.7 * overcast
        if shadow_strength * float(np.max(sun_color)) < 0.06:
            shadow_strength = 0.0
        # CARLA's traffic manager lights the lamps when the sun is below 15°, in fog denser than 20 or in rain
        # heavier than 80 (traffic_manager constants VehicleLight); against daylight the beams do not show.
        lights_on = alt < 15.0 or w.fog_density > 20.0 or w.precipitation > 80.0
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
            fog_falloff=FOG_FALLOFF_PER_UNIT * max(0.0, float(w.fog_falloff)),
            shadow_strength=shadow_strength,
            shadow_softness=0.12 + 1.2 * overcast,
            vehicle_lights_on=lights_on,
            beams=(1.0 - _smoothstep(-5.0, 15.0, alt)) if lights_on else 0.0,
        )
