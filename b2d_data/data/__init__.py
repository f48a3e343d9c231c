"""Files shipped with the package: CARLA town maps (MIT) and Bench2Drive route, split and result files (Apache-2.0)."""

from __future__ import annotations

from pathlib import Path

_ROOT = Path(__file__).resolve().parent


def carla_maps_dir() -> Path:
    """The folder of the shipped CARLA ``<Town>.xodr`` files (Town01, Town04, Town06, Town07, Town10HD)."""
    return _ROOT / "carla_maps"


def shipped_towns() -> list[str]:
    """Names of the shipped CARLA towns, sorted (``Town01`` …)."""
    return sorted(p.stem for p in carla_maps_dir().glob("*.xodr"))


def bench2drive_dir() -> Path:
    """The folder of the shipped Bench2Drive files (route XML, weather.xml, split lists, VAD's merged result)."""
    return _ROOT / "bench2drive"


def bench2drive_file(name: str) -> Path:
    """A shipped Bench2Drive file by name, e.g. ``bench2drive220.xml``; FileNotFoundError lists what ships."""
    path = bench2drive_dir() / name
    if not path.is_file():
        shipped = ", ".join(sorted(p.name for p in bench2drive_dir().iterdir() if p.suffix in (".xml", ".json")))
        raise FileNotFoundError(f"{path}: no such shipped Bench2Drive file (shipped: {shipped})")
    return path


def shipped_or_given(path: Path) -> Path:
    """``path``, or the shipped Bench2Drive file of that name when ``path`` is a bare name that does not exist here."""
    shipped = bench2drive_dir() / path.name
    if not path.exists() and path.parent == Path(".") and shipped.is_file():
        return shipped
    return path
