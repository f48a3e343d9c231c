"""Conversions between the stand-in ``carla`` values and b2d-data's own (frozen) records.

Used by the stand-in modules and by the evaluator (which imports ``carla._convert`` in a route process to turn the
agent's ``carla.VehicleControl`` into the simulator's control).
"""

from __future__ import annotations

import math
from typing import Any

from b2d_data.format import transform as fmt
from b2d_data.sim import api

from ._geom import BoundingBox, GeoLocation, Location, Rotation, Transform, Vector3D
from ._types import VehicleControl, WalkerControl, WeatherParameters

__all__ = [
    "from_carla_location", "from_carla_rotation", "from_carla_transform", "from_carla_vector", "to_b2d_control",
    "to_carla_bbox", "to_carla_control", "to_carla_geolocation", "to_carla_location", "to_carla_rotation",
    "to_carla_transform", "to_carla_vector", "to_carla_walker_control", "to_carla_weather",
]  # fmt: skip


def to_carla_location(loc: fmt.Location) -> Location:
    """Our Location → carla.Location."""
    return Location(loc.x, loc.y, loc.z)


def to_carla_vector(vec: fmt.Vector3D) -> Vector3D:
    """Our Vector3D → carla.Vector3D."""
    return Vector3D(vec.x, vec.y, vec.z)


def to_carla_rotation(rot: fmt.Rotation) -> Rotation:
    """Our Rotation → carla.Rotation."""
    return Rotation(pitch=rot.pitch, yaw=rot.yaw, roll=rot.roll)


def to_carla_transform(t: fmt.Transform) -> Transform:
    """Our Transform → carla.Transform."""
    return Transform(to_carla_location(t.location), to_carla_rotation(t.rotation))


def to_carla_bbox(box: fmt.BoundingBox) -> BoundingBox:
    """Our BoundingBox (half extents) → carla.BoundingBox."""
    return BoundingBox(to_carla_location(box.location), to_carla_vector(box.extent), to_carla_rotation(box.rotation))


def to_carla_geolocation(geo: Any) -> GeoLocation:
    """Any latitude/longitude/altitude record → carla.GeoLocation."""
    return GeoLocation(geo.latitude, geo.longitude, geo.altitude)


def from_carla_location(loc: Any) -> fmt.Location:
    """A carla.Location (or anything with x, y, z) → our Location."""
    return fmt.Location(float(loc.x), float(loc.y), float(loc.z))


from_carla_vector = from_carla_location


def from_carla_rotation(rot: Any) -> fmt.Rotation:
    """A carla.Rotation (or anything with pitch, yaw, roll) → our Rotation."""
    return fmt.Rotation(pitch=float(rot.pitch), yaw=float(rot.yaw), roll=float(rot.roll))


def from_carla_transform(t: Any) -> fmt.Transform:
    """A carla.Transform → our Transform."""
    return fmt.Transform(from_carla_location(t.location), from_carla_rotation(t.rotation))


def to_carla_control(control: api.VehicleControl | None) -> VehicleControl:
    """The simulator's vehicle control → carla.VehicleControl (zeros for None)."""
    if control is None:
        return VehicleControl()
    return VehicleControl(float(control.throttle), float(control.steer), float(control.brake), bool(control.hand_brake),
                          bool(control.reverse), bool(control.manual_gear_shift), int(control.gear))  # fmt: skip


def to_carla_walker_control(control: api.WalkerControl | None) -> WalkerControl:
    """The simulator's walker control → carla.WalkerControl."""
    if control is None:
        return WalkerControl()
    return WalkerControl(to_carla_vector(control.direction), float(control.speed), bool(control.jump))


def to_carla_weather(weather: Any) -> WeatherParameters:
    """Our WeatherParameters → carla.WeatherParameters (fields we do not model keep CARLA's defaults)."""
    out = WeatherParameters()
    for name in WeatherParameters._FIELDS:
        if hasattr(weather, name):
            setattr(out, name, float(getattr(weather, name)))
    return out


def _number(control: Any, name: str) -> float:
    try:
        value = float(getattr(control, name))
    except AttributeError:
        raise TypeError(f"the agent's control has no '{name}' (expected a carla.VehicleControl)") from None
    except (TypeError, ValueError):
        raise TypeError(
            f"the agent's control has a non-numeric {name}={getattr(control, name)!r} (expected a float)"
        ) from None
    if math.isnan(value):
        # NaN would silently become a full throttle or brake somewhere downstream; the agent is broken, say so.
        raise ValueError(f"the agent's control has {name}=nan; run_step must return finite throttle, steer and brake")
    return value


def to_b2d_control(control: Any) -> api.VehicleControl:
    """An agent's carla.VehicleControl → the simulator's control, clamped as CARLA clamps it.

    Throttle and brake are clamped to [0, 1], steer to [−1, 1] (±inf clamp too). A NaN raises ValueError naming the
    field; a missing or non-numeric field raises TypeError.
    """
    throttle = min(max(_number(control, "throttle"), 0.0), 1.0)
    steer = min(max(_number(control, "steer"), -1.0), 1.0)
    brake = min(max(_number(control, "brake"), 0.0), 1.0)
    return api.VehicleControl(
        throttle=throttle,
        steer=steer,
        brake=brake,
        hand_brake=bool(getattr(control, "hand_brake", False)),
        reverse=bool(getattr(control, "reverse", False)),
        manual_gear_shift=bool(getattr(control, "manual_gear_shift", False)),
        gear=int(getattr(control, "gear", 0)),
    )
