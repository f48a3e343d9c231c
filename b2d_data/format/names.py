"""Clip names ``<Scenario>_<Town>_Route<id>_Weather<w>`` and town names (format.md §1.1)."""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass

from b2d_data.format.scenario_types import BY_CLIP_PREFIX, BY_XML_TYPE, NO_SCENARIO

logger = logging.getLogger(__name__)

#: The 12 CARLA towns that Bench2Drive uses (note ``Town10HD``, never ``Town10``).
CARLA_TOWNS: tuple[str, ...] = (
    "Town01", "Town02", "Town03", "Town04", "Town05", "Town06",
    "Town07", "Town10HD", "Town11", "Town12", "Town13", "Town15",
)  # fmt: skip

_TOWN_RE = re.compile(r"Town\d+(?:HD)?")
_CLIP_RE = re.compile(
    r"^(?P<scenario>T_Junction|[A-Za-z0-9]+)_(?P<town>Town\d+(?:HD)?)_Route(?P<route>\d+)_(?P<wtag>W[a-z]*)(?P<weather>\d*)$"
)
_ARCHIVE_SUFFIXES = (".tar.gz", ".tgz", ".tar")
# One path component of ordinary characters; never "." or ".." (no leading dot) and no separator.
_SAFE_NAME_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,199}")


class ClipNameError(ValueError):
    """A clip name that does not follow ``<Scenario>_<Town>_Route<id>_Weather<w>``."""


class UnsafeNameError(ValueError):
    """A name read from a file that could not be used in a file path as it is (``../x``, ``a/b``, ``.hidden``)."""


def is_safe_name(value: str) -> bool:
    """True when ``value`` is fit to be part of a file name: one path component of ordinary characters."""
    return isinstance(value, str) and _SAFE_NAME_RE.fullmatch(value) is not None


def check_safe_name(value: str, what: str) -> str:
    """``value`` when it is fit to be part of a file name, else :class:`UnsafeNameError` naming ``what`` and it."""
    if not is_safe_name(value):
        raise UnsafeNameError(
            f"{what} {value!r} is not a plain name (letters, digits, '_', '-', '.', not starting with '.'); "
            "it would become part of a file path"
        )
    return value


def is_town_name(text: str) -> bool:
    """True when ``text`` is spelled like a town in clip names (``Town<digits>`` or ``Town<digits>HD``)."""
    return _TOWN_RE.fullmatch(text) is not None


def canonical_clip_prefix(scenario: str) -> str:
    """Map an XML scenario type to its clip prefix (``SequentialLaneChange`` → ``LaneChange``)."""
    if scenario in BY_XML_TYPE:
        return BY_XML_TYPE[scenario].clip_prefix
    return scenario


@dataclass(frozen=True, order=True)
class ClipName:
    """A parsed clip name; ``weather_id`` is ``None`` when the released name is truncated."""

    scenario: str
    town: str
    route_id: int
    weather_id: int | None

    def __post_init__(self) -> None:
        # A clip name becomes folder and file names (clips, results/, writer temporaries).
        check_safe_name(self.scenario, "scenario")
        check_safe_name(self.town, "town")

    @classmethod
    def parse(cls, text: str) -> ClipName:
        """Parse a clip name, an archive name (``.tar.gz``) or a path ending in one."""
        raw = text
        name = text.rstrip("/").split("/")[-1]
        for suffix in _ARCHIVE_SUFFIXES:
            if name.endswith(suffix):
                name = name[: -len(suffix)]
                break
        match = _CLIP_RE.match(name)
        if match is None:
            raise ClipNameError(
                f"malformed clip name {raw!r}: expected <Scenario>_<Town>_Route<id>_Weather<w>, "
                "e.g. Accident_Town03_Route156_Weather0"
            )
        wtag, weather = match["wtag"], match["weather"]
        if wtag == "Weather" and weather:
            weather_id: int | None = int(weather)
        elif "Weather".startswith(wtag) and not weather:
            # The released Base list holds one name cut off inside "Weather": keep it, weather unknown.
            logger.warning("clip name %r is truncated: weather unknown", raw)
            weather_id = None
        else:
            raise ClipNameError(f"malformed clip name {raw!r}: bad weather part {wtag + weather!r}")
        return cls(canonical_clip_prefix(match["scenario"]), match["town"], int(match["route"]), weather_id)

    def __str__(self) -> str:
        weather = "" if self.weather_id is None else str(self.weather_id)
        return f"{self.scenario}_{self.town}_Route{self.route_id}_Weather{weather}"

    @property
    def xml_type(self) -> str:
        """The scenario's XML/class type (``LaneChange`` → ``SequentialLaneChange``); ``NoScenario`` stays."""
        entry = BY_CLIP_PREFIX.get(self.scenario)
        return entry.xml_type if entry else self.scenario

    @property
    def is_known_scenario(self) -> bool:
        """True for the 44 Bench2Drive scenarios, the LB2.0-only training types and ``NoScenario``."""
        return self.scenario in BY_CLIP_PREFIX or self.scenario == NO_SCENARIO

    @property
    def archive_name(self) -> str:
        """File name of the clip's archive, as in the official split files."""
        return f"{self}.tar.gz"
