"""Resolve a town given by name or path: an .xodr file, a generated preset, or a CARLA town name."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from b2d_data.data import carla_maps_dir, shipped_towns
from b2d_data.maps.map import Map, load_opendrive

#: Environment variable naming a folder of ``<Town>.xodr`` files (e.g. CARLA's OpenDRIVE maps).
CARLA_MAPS_ENV = "B2D_CARLA_MAPS"


class UnknownTownError(ValueError):
    """A town spec that is neither a file, a generated preset nor a town found in the map folders."""


def map_folders() -> list[Path]:
    """Folders searched for ``<Town>.xodr``: ``$B2D_CARLA_MAPS`` first, then the CARLA towns shipped with the package."""
    folders = [Path(os.environ[CARLA_MAPS_ENV])] if os.environ.get(CARLA_MAPS_ENV) else []
    folders.append(carla_maps_dir())
    return folders


def resolve_town(town: Map | str | os.PathLike[str]) -> Map:
    """A Map from a Map, an .xodr path, a generated-town preset (name or town name; seed 0) or a CARLA town name."""
    if not isinstance(town, (str, os.PathLike)):
        return town  # a Map, or any object with the Map API (tests use light stand-ins)
    path = Path(town)
    if path.suffix.lower() == ".xodr" or path.exists():
        if not path.is_file():
            raise UnknownTownError(f"OpenDRIVE file {path} does not exist")
        return load_opendrive(path)
    from b2d_data.maps import towngen

    name = str(town)
    presets = {p.name: p for p in towngen.TOWN_PRESETS.values()}
    presets.update({p.town: p for p in towngen.TOWN_PRESETS.values()})
    if name in presets:
        preset = presets[name]
        folder = Path(tempfile.mkdtemp(prefix="b2d_town_"))
        return load_opendrive(towngen.write_town(preset.name, 0, folder / f"{preset.town}.xodr"))
    for folder in map_folders():
        if (folder / f"{name}.xodr").is_file():
            return load_opendrive(folder / f"{name}.xodr")
    known = ", ".join(sorted(presets))
    shipped = ", ".join(shipped_towns())
    raise UnknownTownError(
        f"unknown town {name!r}: give an .xodr path, a generated preset ({known}), a shipped CARLA town ({shipped}), "
        f"or a town whose .xodr is in ${CARLA_MAPS_ENV}"
    )
