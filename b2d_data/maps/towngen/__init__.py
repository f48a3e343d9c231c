"""Procedural towns written as OpenDRIVE: named presets and a seed, covering every road layout the 44 scenarios need.

``generate_town(preset, seed)`` returns OpenDRIVE 1.4 text, ``write_town(preset, seed, path)`` writes it; each
preset carries a ``Town<digits>`` name (Town100+) so that clip names stay valid.
"""

from b2d_data.maps.towngen.presets import (
    ALL_LAYOUTS,
    DEFAULT_PRESET,
    TOWN_PRESETS,
    TownPreset,
    UnknownPresetError,
    build_town,
    generate_town,
    get_preset,
    plan_town,
    write_town,
)
from b2d_data.maps.towngen.validate import validate_xodr

__all__ = [
    "ALL_LAYOUTS", "DEFAULT_PRESET", "TOWN_PRESETS", "TownPreset", "UnknownPresetError", "build_town",
    "generate_town", "get_preset", "plan_town", "validate_xodr", "write_town",
]  # fmt: skip
