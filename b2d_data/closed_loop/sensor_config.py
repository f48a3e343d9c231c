"""The Leaderboard's rules for an agent's sensor rig, and the rig as our simulator mounts it.

An agent lists its sensors in ``sensors()`` as dicts (``{'type': 'sensor.camera.rgb', 'id': 'CAM_FRONT', 'x': ...}``).
The Leaderboard's agent wrapper first validates the list (:func:`validate_sensor_configuration`: the track, unique ids,
allowed types, a mount radius and a count per type) and then turns each entry into a blueprint with attributes it
forces itself (:func:`preprocess_sensor_spec`). Bench2Drive changes one rule: with ``SAVE_PATH`` set the mount radius
may be 100 m instead of 3 m, so that the agents' top-down ``bev`` camera at z = 50 passes.

This module is the one place these rules live: the stand-in ``leaderboard`` package re-exports them, and the evaluator,
which runs in plain processes, imports them from here. It must not import the stand-in modules (``carla`` & co.).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any

from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.sim.api import (
    CAMERA_RGB,
    FIXED_DELTA_SECONDS,
    GNSS,
    IMU,
    LIDAR_RAY_CAST,
    RADAR,
    SensorMount,
)

#: The pseudo sensors the agent wrapper serves itself instead of spawning them.
SPEEDOMETER = "sensor.speedometer"
OPENDRIVE_MAP = "sensor.opendrive_map"

#: Bench2Drive's per-type sensor limits (``agent_wrapper.SENSORS_LIMITS``).
SENSORS_LIMITS: dict[str, int] = {
    CAMERA_RGB: 8,
    LIDAR_RAY_CAST: 2,
    RADAR: 4,
    GNSS: 1,
    IMU: 1,
    OPENDRIVE_MAP: 1,
    SPEEDOMETER: 1,
}

#: The limits of the qualifier tracks (``agent_wrapper.QUALIFIER_SENSORS_LIMITS``).
QUALIFIER_SENSORS_LIMITS: dict[str, int] = {
    CAMERA_RGB: 4,
    LIDAR_RAY_CAST: 1,
    RADAR: 2,
    GNSS: 1,
    IMU: 1,
    OPENDRIVE_MAP: 1,
    SPEEDOMETER: 1,
}

#: Every sensor type an agent may ask for.
ALLOWED_SENSORS: tuple[str, ...] = tuple(SENSORS_LIMITS)

#: The Leaderboard's mount radius limit (m) and Bench2Drive's, which applies while ``SAVE_PATH`` is set.
LEADERBOARD_MAX_RADIUS = 3.0
BENCH2DRIVE_MAX_RADIUS = 100.0


def max_allowed_radius() -> float:
    """The mount radius limit now: 100 m while the environment sets ``SAVE_PATH`` (Bench2Drive), else 3 m."""
    return BENCH2DRIVE_MAX_RADIUS if os.environ.get("SAVE_PATH") else LEADERBOARD_MAX_RADIUS


#: The limit as Bench2Drive's ``agent_wrapper`` computes it: once, when the module is imported.
#: :func:`validate_sensor_configuration` reads the environment at each call instead (:func:`max_allowed_radius`).
MAX_ALLOWED_RADIUS_SENSOR = max_allowed_radius()


class Track(Enum):
    """The Leaderboard's tracks (``autonomous_agent.Track``); the stand-in ``leaderboard`` re-exports this class."""

    SENSORS = "SENSORS"
    MAP = "MAP"
    SENSORS_QUALIFIER = "SENSORS_QUALIFIER"
    MAP_QUALIFIER = "MAP_QUALIFIER"


class SensorConfigurationInvalid(Exception):
    """The agent's sensor list breaks a Leaderboard rule (the route is then recorded as "Rejected")."""


class SensorReceivedNoData(Exception):
    """A registered sensor delivered no data for the frame the agent is asked to act on."""


@dataclass(frozen=True)
class PseudoSensor:
    """A sensor the agent wrapper serves without spawning one (``sensor.speedometer``, ``sensor.opendrive_map``).

    ``reading_frequency`` is in Hz, as the wrapper passes it to its reader thread.
    """

    sensor_id: str
    type_id: str
    reading_frequency: float


#: Keys each sensor type needs in its spec (besides ``type`` and ``id``), in the order the wrapper reads them.
_REQUIRED_KEYS: dict[str, tuple[str, ...]] = {
    CAMERA_RGB: ("x", "y", "z", "width", "height", "fov"),
    LIDAR_RAY_CAST: ("x", "y", "z"),
    RADAR: ("x", "y", "z", "horizontal_fov", "vertical_fov"),
    GNSS: ("x", "y", "z"),
    IMU: ("x", "y", "z"),
    SPEEDOMETER: (),
    OPENDRIVE_MAP: ("reading_frequency",),
}


def _track(value: Any) -> Track:
    """A Track from our enum, the stand-in's, another Enum with the same values, or the plain string."""
    raw = value.value if isinstance(value, Enum) else value
    try:
        return Track(raw)
    except ValueError:
        names = ", ".join(t.value for t in Track)
        raise SensorConfigurationInvalid(f"unknown track {raw!r}; the tracks are {names}") from None


def _label(sensor: Mapping[str, Any], index: int) -> str:
    sensor_id = sensor.get("id") if isinstance(sensor, Mapping) else None
    return f"sensor '{sensor_id}'" if sensor_id is not None else f"sensor #{index}"


def _number(sensor: Mapping[str, Any], key: str, label: str) -> float:
    value = sensor[key]
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SensorConfigurationInvalid(f"{label}: '{key}' must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise SensorConfigurationInvalid(f"{label}: '{key}' must be finite, got {value!r}")
    return number


def _check_keys(sensor: Mapping[str, Any], label: str) -> None:
    sensor_type = sensor["type"]
    missing = [key for key in _REQUIRED_KEYS[sensor_type] if key not in sensor]
    if missing:
        raise SensorConfigurationInvalid(
            f"{label} of type '{sensor_type}' lacks required key(s) {', '.join(repr(k) for k in missing)} "
            f"(a {sensor_type} needs {', '.join(_REQUIRED_KEYS[sensor_type]) or 'only type and id'})"
        )


def validate_sensor_configuration(sensors: Sequence[Mapping[str, Any]], agent_track: Any, selected_track: Any) -> None:
    """Raise :class:`SensorConfigurationInvalid` where the Leaderboard's agent wrapper would reject the rig.

    The checks and their messages follow Bench2Drive's ``agent_wrapper.validate_sensor_configuration``, in its order:
    the agent's track must be the selected one; per sensor, a unique id, no ``sensor.opendrive_map`` on the SENSORS
    track, an allowed type and a mount radius ``sqrt(x² + y² + z²)`` within :func:`max_allowed_radius`; finally at most
    the track's limit of each type. Beyond the Leaderboard (where these end in a KeyError or a crash later), a spec
    that is not a dict, lacks ``type``/``id`` or a key its type needs, or gives a non-numeric pose is rejected with a
    message that names the sensor and the key.
    """
    track = _track(agent_track)
    selected = _track(selected_track)
    if selected != track:
        raise SensorConfigurationInvalid(f"You are submitting to the wrong track [{selected}]!")
    if isinstance(sensors, (str, bytes, Mapping)) or not isinstance(sensors, Sequence):
        raise SensorConfigurationInvalid(f"sensors() must return a list of dicts, got {type(sensors).__name__}")
    limit_radius = max_allowed_radius()
    sensor_count: dict[str, int] = {}
    sensor_ids: set[Any] = set()
    for index, sensor in enumerate(sensors):
        label = _label(sensor, index)
        if not isinstance(sensor, Mapping):
            raise SensorConfigurationInvalid(f"{label}: a sensor spec must be a dict, got {type(sensor).__name__}")
        for key in ("type", "id"):
            if key not in sensor:
                raise SensorConfigurationInvalid(f"{label} lacks the required key '{key}'")
        sensor_id = sensor["id"]
        if sensor_id in sensor_ids:
            raise SensorConfigurationInvalid(f"Duplicated sensor tag [{sensor_id}]")
        sensor_ids.add(sensor_id)
        sensor_type = sensor["type"]
        if track is Track.SENSORS and str(sensor_type).startswith(OPENDRIVE_MAP):
            raise SensorConfigurationInvalid(f"Illegal sensor '{OPENDRIVE_MAP}' used for Track [{track}]!")
        if sensor_type not in SENSORS_LIMITS:
            raise SensorConfigurationInvalid(f"Illegal sensor '{sensor_type}' used for Track [{track}]!")
        _check_keys(sensor, label)
        if all(key in sensor for key in ("x", "y", "z")):
            x, y, z = (_number(sensor, key, label) for key in ("x", "y", "z"))
            if math.sqrt(x * x + y * y + z * z) > limit_radius:
                raise SensorConfigurationInvalid(
                    f"Illegal sensor extrinsics used for sensor '{sensor_id}'. Max allowed radius is {limit_radius}m"
                )
        sensor_count[sensor_type] = sensor_count.get(sensor_type, 0) + 1
    limits = QUALIFIER_SENSORS_LIMITS if track in (Track.SENSORS_QUALIFIER, Track.MAP_QUALIFIER) else SENSORS_LIMITS
    for sensor_type, max_instances in limits.items():
        count = sensor_count.get(sensor_type, 0)
        if count > max_instances:
            raise SensorConfigurationInvalid(
                f"Too many {sensor_type} used! Maximum number allowed is {max_instances}, but {count} were requested."
            )


def _pose(spec: Mapping[str, Any], label: str, rotate: bool = True) -> Transform:
    """The mount pose of a spec; roll/pitch/yaw default to 0 (the wrapper would raise a KeyError)."""
    location = Location(_number(spec, "x", label), _number(spec, "y", label), _number(spec, "z", label))
    if not rotate:
        return Transform(location, Rotation())
    angles = {key: (_number(spec, key, label) if key in spec else 0.0) for key in ("pitch", "yaw", "roll")}
    return Transform(location, Rotation(pitch=angles["pitch"], yaw=angles["yaw"], roll=angles["roll"]))


def preprocess_sensor_spec(
    spec: Mapping[str, Any], delta_seconds: float = FIXED_DELTA_SECONDS
) -> SensorMount | PseudoSensor:
    """One sensor spec as the agent wrapper spawns it: the mount with the attributes the wrapper forces.

    Attribute values are the strings the wrapper writes (``str(85)`` → ``'85'``, ``str(0.000005)`` → ``'5e-06'``).
    The speedometer reads at ``1 / delta_seconds``; ``sensor.opendrive_map`` at the spec's ``reading_frequency``.
    GNSS mounts ignore the spec's rotation, as the wrapper does.
    """
    if not isinstance(spec, Mapping) or "type" not in spec or "id" not in spec:
        raise SensorConfigurationInvalid(f"a sensor spec must be a dict with 'type' and 'id', got {spec!r}")
    sensor_type, sensor_id = spec["type"], spec["id"]
    label = f"sensor '{sensor_id}'"
    if sensor_type not in SENSORS_LIMITS:
        raise SensorConfigurationInvalid(f"Illegal sensor '{sensor_type}' used ({label})")
    _check_keys(spec, label)
    if sensor_type == SPEEDOMETER:
        if not delta_seconds > 0:
            raise ValueError(f"delta_seconds must be > 0, got {delta_seconds}")
        return PseudoSensor(str(sensor_id), sensor_type, 1.0 / delta_seconds)
    if sensor_type == OPENDRIVE_MAP:
        return PseudoSensor(str(sensor_id), sensor_type, _number(spec, "reading_frequency", label))
    attributes: dict[str, str]
    if sensor_type == CAMERA_RGB:
        attributes = {
            "image_size_x": str(spec["width"]),
            "image_size_y": str(spec["height"]),
            "fov": str(spec["fov"]),
        }
    elif sensor_type == LIDAR_RAY_CAST:
        attributes = {
            "range": str(85),
            "rotation_frequency": str(10),
            "channels": str(64),
            "upper_fov": str(10),
            "lower_fov": str(-30),
            "points_per_second": str(600000),
            "atmosphere_attenuation_rate": str(0.004),
            "dropoff_general_rate": str(0.45),
            "dropoff_intensity_limit": str(0.8),
            "dropoff_zero_intensity": str(0.4),
        }
    elif sensor_type == RADAR:
        attributes = {
            "horizontal_fov": str(spec["horizontal_fov"]),
            "vertical_fov": str(spec["vertical_fov"]),
            "points_per_second": "1500",
            "range": "100",
        }
    elif sensor_type == GNSS:
        attributes = {
            "noise_alt_stddev": str(0.000005),
            "noise_lat_stddev": str(0.000005),
            "noise_lon_stddev": str(0.000005),
            "noise_alt_bias": str(0.0),
            "noise_lat_bias": str(0.0),
            "noise_lon_bias": str(0.0),
        }
    else:  # IMU
        attributes = {
            "noise_accel_stddev_x": str(0.001),
            "noise_accel_stddev_y": str(0.001),
            "noise_accel_stddev_z": str(0.015),
            "noise_gyro_stddev_x": str(0.001),
            "noise_gyro_stddev_y": str(0.001),
            "noise_gyro_stddev_z": str(0.001),
        }
    transform = _pose(spec, label, rotate=sensor_type != GNSS)
    return SensorMount(sensor_id=str(sensor_id), type_id=sensor_type, transform=transform, attributes=attributes)


def preprocess_sensors(
    sensors: Sequence[Mapping[str, Any]], delta_seconds: float = FIXED_DELTA_SECONDS
) -> tuple[list[SensorMount], list[PseudoSensor]]:
    """Every spec of a validated rig, split into physical mounts and pseudo sensors (each in the agent's order)."""
    mounts: list[SensorMount] = []
    pseudo: list[PseudoSensor] = []
    for spec in sensors:
        item = preprocess_sensor_spec(spec, delta_seconds)
        (pseudo if isinstance(item, PseudoSensor) else mounts).append(item)
    return mounts, pseudo
