"""CARLA 0.9.15's enums, controls, settings, weather, timestamps and sensor-data classes.

Enums keep CARLA's member names and values (``carla.LaneType.Driving == 2``, ``carla.LaneType.Any == -2``); like
CARLA's enums they are ints, so ``LaneType.Driving | LaneType.Sidewalk`` is a plain int mask, and ``str()`` gives the
member name as CARLA prints it. The sensor-data classes exist so that ``isinstance`` dispatch on
``carla.libcarla.Image`` & co. works; the evaluator hands agents numpy arrays, never these objects.
"""

from __future__ import annotations

from enum import IntEnum, IntFlag
from typing import Any

from b2d_data.sim.light_state import carla_str

from ._geom import Transform, Vector3D

__all__ = [
    "ActorState", "AttachmentType", "CityObjectLabel", "ColorConverter", "GnssMeasurement", "IMUMeasurement", "Image",
    "LandmarkOrientation", "LaneChange", "LaneMarkingColor", "LaneMarkingType", "LaneType", "LidarDetection",
    "LidarMeasurement", "MapLayer", "RadarDetection", "RadarMeasurement", "SemanticLidarDetection",
    "SemanticLidarMeasurement", "SensorData", "Timestamp", "TrafficLightState", "VehicleControl", "VehicleDoor",
    "VehicleFailureState", "VehicleLightState", "VehicleWheelLocation", "WalkerControl", "WeatherParameters",
    "WorldSettings",
]  # fmt: skip


class _CarlaEnum(IntEnum):
    """An int enum whose ``str`` is the member name, as CARLA's boost enums print."""

    def __str__(self) -> str:
        return self.name


class TrafficLightState(_CarlaEnum):
    """carla.TrafficLightState (same ints as ``b2d_data.sim.api.TrafficLightState``)."""

    Red = 0
    Yellow = 1
    Green = 2
    Off = 3
    Unknown = 4


class LaneType(_CarlaEnum):
    """carla.LaneType: one bit per OpenDRIVE lane type; ``Any`` is every bit but NONE's (−2 as CARLA's int32)."""

    NONE = 0x1
    Driving = 0x1 << 1
    Stop = 0x1 << 2
    Shoulder = 0x1 << 3
    Biking = 0x1 << 4
    Sidewalk = 0x1 << 5
    Border = 0x1 << 6
    Restricted = 0x1 << 7
    Parking = 0x1 << 8
    Bidirectional = 0x1 << 9
    Median = 0x1 << 10
    Special1 = 0x1 << 11
    Special2 = 0x1 << 12
    Special3 = 0x1 << 13
    RoadWorks = 0x1 << 14
    Tram = 0x1 << 15
    Rail = 0x1 << 16
    Entry = 0x1 << 17
    Exit = 0x1 << 18
    OffRamp = 0x1 << 19
    OnRamp = 0x1 << 20
    Any = -2


class LaneChange(_CarlaEnum):
    """carla.LaneChange."""

    NONE = 0
    Right = 1
    Left = 2
    Both = 3


class LaneMarkingType(_CarlaEnum):
    """carla.LaneMarkingType."""

    Other = 0
    Broken = 1
    Solid = 2
    SolidSolid = 3
    SolidBroken = 4
    BrokenSolid = 5
    BrokenBroken = 6
    BottsDots = 7
    Grass = 8
    Curb = 9
    NONE = 10


class LaneMarkingColor(_CarlaEnum):
    """carla.LaneMarkingColor (``Standard`` is ``White``)."""

    White = 0
    Standard = 0
    Blue = 1
    Green = 2
    Red = 3
    Yellow = 4
    Other = 5


class CityObjectLabel(_CarlaEnum):
    """carla.CityObjectLabel (the semantic tags of CARLA 0.9.14+)."""

    NONE = 0
    Roads = 1
    Sidewalks = 2
    Buildings = 3
    Walls = 4
    Fences = 5
    Poles = 6
    TrafficLight = 7
    TrafficSigns = 8
    Vegetation = 9
    Terrain = 10
    Sky = 11
    Pedestrians = 12
    Rider = 13
    Car = 14
    Truck = 15
    Bus = 16
    Train = 17
    Motorcycle = 18
    Bicycle = 19
    Static = 20
    Dynamic = 21
    Other = 22
    Water = 23
    RoadLines = 24
    Ground = 25
    Bridge = 26
    RailTrack = 27
    GuardRail = 28
    Any = 0xFF


class AttachmentType(_CarlaEnum):
    """carla.AttachmentType."""

    Rigid = 0
    SpringArm = 1
    SpringArmGhost = 2


class VehicleDoor(_CarlaEnum):
    """carla.VehicleDoor."""

    FL = 0
    FR = 1
    RL = 2
    RR = 3
    All = 6


class VehicleWheelLocation(_CarlaEnum):
    """carla.VehicleWheelLocation."""

    FL_Wheel = 0
    FR_Wheel = 1
    BL_Wheel = 2
    BR_Wheel = 3
    Front_Wheel = 0
    Back_Wheel = 2


class VehicleFailureState(_CarlaEnum):
    """carla.VehicleFailureState."""

    NONE = 0
    Rollover = 1
    Engine = 2
    TirePuncture = 3


class ActorState(_CarlaEnum):
    """carla.ActorState."""

    Invalid = 0
    Active = 1
    Dormant = 2


class LandmarkOrientation(_CarlaEnum):
    """carla.LandmarkOrientation."""

    Positive = 0
    Negative = 1
    Both = 2


class ColorConverter(_CarlaEnum):
    """carla.ColorConverter."""

    Raw = 0
    Depth = 1
    LogarithmicDepth = 2
    CityScapesPalette = 3


class MapLayer(IntFlag):
    """carla.MapLayer."""

    NONE = 0
    Buildings = 0x1
    Decals = 0x1 << 1
    Foliage = 0x1 << 2
    Ground = 0x1 << 3
    ParkedVehicles = 0x1 << 4
    Particles = 0x1 << 5
    Props = 0x1 << 6
    StreetLights = 0x1 << 7
    Walls = 0x1 << 8
    All = 0xFFFF

    def __str__(self) -> str:
        return self.name or str(int(self))


class VehicleLightState(IntFlag):
    """carla.VehicleLightState: a bit set of the lights that are on."""

    NONE = 0
    Position = 0x1
    LowBeam = 0x1 << 1
    HighBeam = 0x1 << 2
    Brake = 0x1 << 3
    RightBlinker = 0x1 << 4
    LeftBlinker = 0x1 << 5
    Reverse = 0x1 << 6
    Fog = 0x1 << 7
    Interior = 0x1 << 8
    Special1 = 0x1 << 9
    Special2 = 0x1 << 10
    All = 0xFFFFFFFF

    def __str__(self) -> str:
        # CARLA binds this as a Boost.Python enum: str is a member's name only for a value that is one member,
        # else the decimal value (Special1 | Special2 -> "1536"); Bench2Drive's annotations store that string.
        return carla_str(int(self))


class VehicleControl:
    """carla.VehicleControl: what an agent's ``run_step`` returns (mutable, unclamped, like CARLA's)."""

    __slots__ = ("brake", "gear", "hand_brake", "manual_gear_shift", "reverse", "steer", "throttle")
    __hash__ = object.__hash__

    def __init__(
        self,
        throttle: float = 0.0,
        steer: float = 0.0,
        brake: float = 0.0,
        hand_brake: bool = False,
        reverse: bool = False,
        manual_gear_shift: bool = False,
        gear: int = 0,
    ) -> None:
        self.throttle = throttle
        self.steer = steer
        self.brake = brake
        self.hand_brake = hand_brake
        self.reverse = reverse
        self.manual_gear_shift = manual_gear_shift
        self.gear = gear

    def __repr__(self) -> str:
        return (
            f"VehicleControl(throttle={float(self.throttle):.6f}, steer={float(self.steer):.6f}, "
            f"brake={float(self.brake):.6f}, hand_brake={bool(self.hand_brake)}, reverse={bool(self.reverse)}, "
            f"manual_gear_shift={bool(self.manual_gear_shift)}, gear={int(self.gear)})"
        )

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, VehicleControl):
            return NotImplemented
        return all(getattr(self, name) == getattr(other, name) for name in self.__slots__)

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result


class WalkerControl:
    """carla.WalkerControl: a world-frame direction, a speed (m/s) and a jump flag."""

    __slots__ = ("direction", "jump", "speed")
    __hash__ = object.__hash__

    def __init__(self, direction: Vector3D | None = None, speed: float = 0.0, jump: bool = False) -> None:
        self.direction = Vector3D(direction) if direction is not None else Vector3D(1.0, 0.0, 0.0)
        self.speed = speed
        self.jump = jump

    def __repr__(self) -> str:
        return f"WalkerControl(direction={self.direction!r}, speed={float(self.speed):.6f}, jump={bool(self.jump)})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, WalkerControl):
            return NotImplemented
        return self.direction == other.direction and self.speed == other.speed and self.jump == other.jump


class WorldSettings:
    """carla.WorldSettings (constructor defaults are CARLA's; the running world reports synchronous 20 Hz)."""

    _FIELDS = ("synchronous_mode", "no_rendering_mode", "fixed_delta_seconds", "substepping", "max_substep_delta_time",
               "max_substeps", "max_culling_distance", "deterministic_ragdolls", "tile_stream_distance",
               "actor_active_distance", "spectator_as_ego")  # fmt: skip

    def __init__(
        self,
        synchronous_mode: bool = False,
        no_rendering_mode: bool = False,
        fixed_delta_seconds: float | None = 0.0,
        substepping: bool = True,
        max_substep_delta_time: float = 0.01,
        max_substeps: int = 10,
        max_culling_distance: float = 0.0,
        deterministic_ragdolls: bool = False,
        tile_stream_distance: float = 3000.0,
        actor_active_distance: float = 2000.0,
        spectator_as_ego: bool = True,
    ) -> None:
        self.synchronous_mode = synchronous_mode
        self.no_rendering_mode = no_rendering_mode
        self.fixed_delta_seconds = fixed_delta_seconds
        self.substepping = substepping
        self.max_substep_delta_time = max_substep_delta_time
        self.max_substeps = max_substeps
        self.max_culling_distance = max_culling_distance
        self.deterministic_ragdolls = deterministic_ragdolls
        self.tile_stream_distance = tile_stream_distance
        self.actor_active_distance = actor_active_distance
        self.spectator_as_ego = spectator_as_ego

    def __repr__(self) -> str:
        return "WorldSettings(" + ", ".join(f"{k}={getattr(self, k)}" for k in self._FIELDS) + ")"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, WorldSettings):
            return NotImplemented
        return all(getattr(self, k) == getattr(other, k) for k in self._FIELDS)

    __hash__ = object.__hash__


class WeatherParameters:
    """carla.WeatherParameters with CARLA's attribute names and constructor defaults."""

    _FIELDS = ("cloudiness", "precipitation", "precipitation_deposits", "wind_intensity", "sun_azimuth_angle",
               "sun_altitude_angle", "fog_density", "fog_distance", "wetness", "fog_falloff", "scattering_intensity",
               "mie_scattering_scale", "rayleigh_scattering_scale", "dust_storm")  # fmt: skip

    def __init__(
        self,
        cloudiness: float = 0.0,
        precipitation: float = 0.0,
        precipitation_deposits: float = 0.0,
        wind_intensity: float = 0.0,
        sun_azimuth_angle: float = 0.0,
        sun_altitude_angle: float = 0.0,
        fog_density: float = 0.0,
        fog_distance: float = 0.0,
        wetness: float = 0.0,
        fog_falloff: float = 0.0,
        scattering_intensity: float = 0.0,
        mie_scattering_scale: float = 0.0,
        rayleigh_scattering_scale: float = 0.0331,
        dust_storm: float = 0.0,
    ) -> None:
        self.cloudiness = float(cloudiness)
        self.precipitation = float(precipitation)
        self.precipitation_deposits = float(precipitation_deposits)
        self.wind_intensity = float(wind_intensity)
        self.sun_azimuth_angle = float(sun_azimuth_angle)
        self.sun_altitude_angle = float(sun_altitude_angle)
        self.fog_density = float(fog_density)
        self.fog_distance = float(fog_distance)
        self.wetness = float(wetness)
        self.fog_falloff = float(fog_falloff)
        self.scattering_intensity = float(scattering_intensity)
        self.mie_scattering_scale = float(mie_scattering_scale)
        self.rayleigh_scattering_scale = float(rayleigh_scattering_scale)
        self.dust_storm = float(dust_storm)

    def __repr__(self) -> str:
        return "WeatherParameters(" + ", ".join(f"{k}={getattr(self, k):.6f}" for k in self._FIELDS) + ")"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, WeatherParameters):
            return NotImplemented
        return all(getattr(self, k) == getattr(other, k) for k in self._FIELDS)

    __hash__ = object.__hash__


class Timestamp:
    """carla.Timestamp of a world tick."""

    __slots__ = ("delta_seconds", "elapsed_seconds", "frame", "platform_timestamp")

    def __init__(
        self, frame: int = 0, elapsed_seconds: float = 0.0, delta_seconds: float = 0.0, platform_timestamp: float = 0.0
    ) -> None:
        self.frame = int(frame)
        self.elapsed_seconds = float(elapsed_seconds)
        self.delta_seconds = float(delta_seconds)
        self.platform_timestamp = float(platform_timestamp)

    def __repr__(self) -> str:
        return (f"Timestamp(frame={self.frame}, elapsed_seconds={self.elapsed_seconds:.6f}, "
                f"delta_seconds={self.delta_seconds:.6f}, platform_timestamp={self.platform_timestamp:.6f})")  # fmt: skip

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Timestamp):
            return NotImplemented
        return self.frame == other.frame

    __hash__ = object.__hash__


class SensorData:
    """carla.SensorData: frame, timestamp (s) and the sensor's world transform at capture."""

    def __init__(self, frame: int = 0, timestamp: float = 0.0, transform: Transform | None = None) -> None:
        self.frame = int(frame)
        self.timestamp = float(timestamp)
        self.transform = transform if transform is not None else Transform()


class Image(SensorData):
    """carla.Image: ``raw_data`` is BGRA bytes, row-major ``height × width``."""

    def __init__(self, width: int = 0, height: int = 0, fov: float = 90.0, raw_data: bytes = b"", **kw: Any) -> None:
        super().__init__(**kw)
        self.width, self.height, self.fov, self.raw_data = int(width), int(height), float(fov), raw_data

    def __len__(self) -> int:
        return self.width * self.height


class LidarDetection:
    """carla.LidarDetection: a point (sensor frame) and its intensity."""

    def __init__(self, point: Vector3D | None = None, intensity: float = 0.0) -> None:
        self.point, self.intensity = point if point is not None else Vector3D(), float(intensity)


class SemanticLidarDetection:
    """carla.SemanticLidarDetection."""

    def __init__(
        self, point: Vector3D | None = None, cos_inc_angle: float = 0.0, object_idx: int = 0, object_tag: int = 0
    ) -> None:
        self.point = point if point is not None else Vector3D()
        self.cos_inc_angle, self.object_idx, self.object_tag = float(cos_inc_angle), int(object_idx), int(object_tag)


class LidarMeasurement(SensorData):
    """carla.LidarMeasurement: ``raw_data`` is float32 (x, y, z, intensity) per point."""

    def __init__(
        self,
        channels: int = 0,
        horizontal_angle: float = 0.0,
        raw_data: bytes = b"",
        points_per_channel: tuple[int, ...] = (),
        **kw: Any,
    ) -> None:
        super().__init__(**kw)
        self.channels, self.horizontal_angle, self.raw_data = int(channels), float(horizontal_angle), raw_data
        self._points_per_channel = tuple(points_per_channel)

    def get_point_count(self, channel: int) -> int:
        """Points of one channel in this measurement."""
        return self._points_per_channel[channel] if channel < len(self._points_per_channel) else 0

    def __len__(self) -> int:
        return len(self.raw_data) // 16


class SemanticLidarMeasurement(LidarMeasurement):
    """carla.SemanticLidarMeasurement: ``raw_data`` holds x, y, z, cos_inc_angle (float32), idx, tag (uint32)."""

    def __len__(self) -> int:
        return len(self.raw_data) // 24


class RadarDetection:
    """carla.RadarDetection: altitude/azimuth (rad), depth (m), velocity (m/s)."""

    def __init__(self, altitude: float = 0.0, azimuth: float = 0.0, depth: float = 0.0, velocity: float = 0.0) -> None:
        self.altitude, self.azimuth, self.depth, self.velocity = (
            float(altitude),
            float(azimuth),
            float(depth),
            float(velocity),
        )


class RadarMeasurement(SensorData):
    """carla.RadarMeasurement: ``raw_data`` is float32 (velocity, azimuth, altitude, depth) per detection."""

    def __init__(self, raw_data: bytes = b"", **kw: Any) -> None:
        super().__init__(**kw)
        self.raw_data = raw_data

    def get_detection_count(self) -> int:
        """Number of detections."""
        return len(self.raw_data) // 16

    def __len__(self) -> int:
        return self.get_detection_count()


class GnssMeasurement(SensorData):
    """carla.GnssMeasurement (degrees, metres)."""

    def __init__(self, latitude: float = 0.0, longitude: float = 0.0, altitude: float = 0.0, **kw: Any) -> None:
        super().__init__(**kw)
        self.latitude, self.longitude, self.altitude = float(latitude), float(longitude), float(altitude)


class IMUMeasurement(SensorData):
    """carla.IMUMeasurement: accelerometer (m/s²), gyroscope (rad/s), compass (rad)."""

    def __init__(
        self, accelerometer: Vector3D | None = None, gyroscope: Vector3D | None = None, compass: float = 0.0, **kw: Any
    ) -> None:
        super().__init__(**kw)
        self.accelerometer = accelerometer if accelerometer is not None else Vector3D()
        self.gyroscope = gyroscope if gyroscope is not None else Vector3D()
        self.compass = float(compass)
