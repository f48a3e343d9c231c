"""Town resolution for collection: generated presets or OpenDRIVE files, cached per corpus and per process.

A run's town is a :class:`TownSource`: a generated preset (materialised once as ``<out>/towns/<Town>.xodr``) or an
OpenDRIVE file the user gave. Worker processes only ever see a resolved source (a file path) and load each file once
(:func:`load_map` keeps the loaded maps for the life of the process). The town's HD map is exported once per corpus
as ``<out>/maps/<Town>_HD_map.npz`` (:func:`ensure_hdmap`), atomically, by the process that plans the collection.
"""

from __future__ import annotations

import logging
import os
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path

from b2d_data.codecs import layout
from b2d_data.format.names import is_town_name
from b2d_data.maps import Map, load_opendrive

log = logging.getLogger(__name__)

#: Sub-folder of a corpus holding the generated towns' OpenDRIVE files.
TOWNS_DIR = "towns"
#: Generated towns are always built with this seed: a town name (``Town100``) must mean one road network per corpus.
TOWN_SEED = 0

_MAP_CACHE: dict[tuple[str, int, int], Map] = {}


class TownError(ValueError):
    """A town that cannot be used: unknown preset, missing or unreadable file, or a name unfit for clip names."""


@dataclass(frozen=True)
class TownSource:
    """Where a town comes from: a generated ``preset`` or an OpenDRIVE file ``xodr`` (exactly one is set)."""

    preset: str | None = None
    xodr: Path | None = None

    def __post_init__(self) -> None:
        if (self.preset is None) == (self.xodr is None):
            raise ValueError("a TownSource needs exactly one of preset and xodr")

    @property
    def name(self) -> str:
        """The town name the map (and every clip name) carries."""
        if self.preset is not None:
            return preset_town_name(self.preset)
        assert self.xodr is not None
        return self.xodr.stem

    def describe(self) -> str:
        """Human-readable origin, for messages."""
        return f"preset {self.preset!r} ({self.name})" if self.preset is not None else str(self.xodr)

    def materialise(self, out_root: str | os.PathLike[str]) -> TownSource:
        """A file-backed source: generated presets are written once to ``<out>/towns/<Town>.xodr``."""
        if self.xodr is not None:
            return self
        assert self.preset is not None
        target = Path(out_root) / TOWNS_DIR / f"{self.name}.xodr"
        if not target.is_file():
            from b2d_data.maps import towngen

            target.parent.mkdir(parents=True, exist_ok=True)
            temp = target.with_name(f".{target.name}.tmp-{os.getpid()}-{secrets.token_hex(3)}")
            try:
                temp.write_text(towngen.generate_town(self.preset, TOWN_SEED), encoding="utf-8")
                os.replace(temp, target)
            finally:
                temp.unlink(missing_ok=True)
            log.info("generated town %s (preset %s) at %s", self.name, self.preset, target)
        return TownSource(xodr=target)


def preset_town_name(preset: str) -> str:
    """The ``Town<digits>`` name of a generated preset; :class:`TownError` lists the known presets."""
    from b2d_data.maps import towngen

    try:
        return towngen.get_preset(preset).town
    except towngen.UnknownPresetError as exc:
        from b2d_data.data import shipped_towns

        shipped = ", ".join(shipped_towns())
        raise TownError(f"{exc}; shipped CARLA towns: {shipped}") from None


def default_preset() -> str:
    """The preset holding every road layout the scenarios need (but a one-way road's left kerb: preset downtown)."""
    from b2d_data.maps import towngen

    return towngen.DEFAULT_PRESET


def xodr_source(path: str | os.PathLike[str]) -> TownSource:
    """A source for an existing OpenDRIVE file whose stem is a valid town name (it becomes the clips' town)."""
    p = Path(path)
    if not p.is_file():
        raise TownError(f"OpenDRIVE file {p} does not exist")
    if not is_town_name(p.stem):
        raise TownError(
            f"{p}: the map is named after its file stem {p.stem!r}, which is not a town name usable in clip names "
            "(Town<digits> or Town<digits>HD); rename the file, e.g. to Town200.xodr"
        )
    return TownSource(xodr=p)


def shipped_town(town: str) -> TownSource | None:
    """A CARLA town shipped with the package (Town01, Town04, Town06, Town07, Town10HD) as a source, else None."""
    from b2d_data.data import carla_maps_dir

    return xodr_in_folder(carla_maps_dir(), town)


def xodr_in_folder(folder: str | os.PathLike[str], town: str) -> TownSource | None:
    """``<folder>/<town>.xodr`` as a source, or None when the folder has no such file."""
    path = Path(folder) / f"{town}.xodr"
    return xodr_source(path) if path.is_file() else None


def route_town(town: str, xodr: Path | None = None, preset: str | None = None) -> TownSource | None:
    """The map of a route file's town, or None when there is none: the ``xodr`` file (when its stem is ``town``) or
    folder (``<xodr>/<town>.xodr``), else a generated preset of that town name (only ``preset`` when given), else a
    shipped CARLA town. Raises :class:`TownError` for a town or file name unfit for clip names (a route file's town
    becomes part of a path only once it is known to be a plain ``Town<digits>`` name)."""
    if not is_town_name(town):
        raise TownError(f"route town {town!r} is not a town name (Town<digits> or Town<digits>HD)")
    if xodr is not None:
        if xodr.is_dir():
            return xodr_in_folder(xodr, town)
        source = xodr_source(xodr)
        return source if source.name == town else None
    from b2d_data.maps import towngen

    presets = {p.town: p.name for p in towngen.TOWN_PRESETS.values()}
    if preset is not None:
        return TownSource(preset=preset) if presets.get(town) == preset else None
    return TownSource(preset=presets[town]) if town in presets else shipped_town(town)


def load_map(source: TownSource) -> Map:
    """The Map of a file-backed source, loaded once per process (reloaded when the file changes)."""
    if source.xodr is None:
        raise ValueError(f"{source.describe()}: materialise the source before loading it")
    path = source.xodr.resolve()
    try:
        stat = path.stat()
    except OSError as exc:
        raise TownError(f"cannot read OpenDRIVE file {path}: {exc}") from None
    key = (str(path), stat.st_mtime_ns, stat.st_size)
    cached = _MAP_CACHE.get(key)
    if cached is None:
        try:
            cached = load_opendrive(path)
        except Exception as exc:  # a broken file must become one clear message, whatever the parser raised
            raise TownError(f"cannot load OpenDRIVE file {path}: {exc}") from exc
        # One town per path: drop older versions of the same file.
        for old in [k for k in _MAP_CACHE if k[0] == key[0]]:
            del _MAP_CACHE[old]
        _MAP_CACHE[key] = cached
    return cached


def ensure_hdmap(world_map: Map, out_root: str | os.PathLike[str]) -> Path:
    """Export the town's HD map to ``<out>/maps/<Town>_HD_map.npz`` unless it is there; the file appears atomically."""
    target = layout.hdmap_path(out_root, world_map.name)
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    # A temporary folder named like the writers' temporaries, so that resume removes it after a crash.
    temp = target.parent / f".{target.name}.tmp-{os.getpid()}-{secrets.token_hex(3)}"
    temp.mkdir()
    try:
        written = world_map.save_hdmap(temp / target.name)
        os.replace(written, target)
    finally:
        shutil.rmtree(temp, ignore_errors=True)
    log.info("exported the HD map of %s to %s", world_map.name, target)
    return target
