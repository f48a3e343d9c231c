"""The on-disk contract: names, sensor rig, semantic tags, commands, weathers, annotation schema, versions."""

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import CARLA_TOWNS, ClipName, ClipNameError, canonical_clip_prefix, is_town_name
from b2d_data.format.record import CameraFrame, FrameRecord
from b2d_data.format.rig import ALL_CAMERAS, CAMERAS, LIDAR, RADARS_V0, RADARS_V004, TOP_DOWN, camera
from b2d_data.format.road_option import RoadOption
from b2d_data.format.scenario_types import SCENARIO_TYPES, Ability, ScenarioType, scenario_type
from b2d_data.format.semantic import SemanticTag
from b2d_data.format.version import DEFAULT_FORMAT, FormatVersion
from b2d_data.format.weather import PRESETS as WEATHER_PRESETS
from b2d_data.format.weather import WeatherParameters

__all__ = [
    "ALL_CAMERAS", "B2DFormatError", "CAMERAS", "CARLA_TOWNS", "DEFAULT_FORMAT", "LIDAR", "RADARS_V0", "RADARS_V004", "SCENARIO_TYPES",
    "TOP_DOWN", "WEATHER_PRESETS", "Ability", "CameraFrame", "ClipName", "ClipNameError", "FormatVersion",
    "FrameRecord", "RoadOption", "ScenarioType", "SemanticTag", "WeatherParameters", "camera",
    "canonical_clip_prefix", "is_town_name", "scenario_type",
]  # fmt: skip
