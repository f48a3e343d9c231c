"""``b2d_format.json``: how a clip written by b2d-data was written (absent from released Bench2Drive clips)."""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

from b2d_data.codecs._source import read_source
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.version import FORMAT_FILE, FormatVersion


@dataclass(frozen=True)
class CameraInfo:
    """Resolution of one camera folder and whether depth/semantic/instance were written for it."""

    width: int
    height: int
    dense_labels: bool


@dataclass(frozen=True)
class ClipFormatInfo:
    """Contents of ``<clip>/b2d_format.json``."""

    format_version: FormatVersion
    b2d_data_version: str
    clip: str
    frames: int
    frame_rate_hz: float = 10.0
    cameras: dict[str, CameraInfo] = field(default_factory=dict)  # folder name (``front``) → info
    float_depth: bool = False  # ``camera/depth_<cam>/NNNNN.npz`` present
    lidar: bool = True
    radar: bool = True
    expert_assessment: bool = False  # ``expert_assessment/`` present (first file ``-0001.npz``)
    #: Layout of the vectors' feature part (b2d_data.format.expert_feature.layout_record); None: undescribed.
    expert_feature: dict[str, object] | None = None
    written_at: str = ""  # ISO 8601 UTC time of close()
    extra: dict[str, object] = field(default_factory=dict)  # free-form notes (e.g. simulator, seed)

    def to_json(self) -> str:
        """The JSON text stored in the clip (4-space indent, like the annotations)."""
        data = asdict(self)
        data["format_version"] = self.format_version.value
        return json.dumps(data, indent=4)

    @classmethod
    def from_json(cls, text: str, path: str | os.PathLike[str] = FORMAT_FILE) -> ClipFormatInfo:
        """Parse the stored text; unknown keys (from newer writers) are ignored."""
        try:
            data = json.loads(text)
            version = FormatVersion(data["format_version"])
            cameras = {k: CameraInfo(int(v["width"]), int(v["height"]), bool(v["dense_labels"]))
                       for k, v in data.get("cameras", {}).items()}
            known = {f for f in cls.__dataclass_fields__} - {"format_version", "cameras"}
            rest = {k: v for k, v in data.items() if k in known}
            return cls(format_version=version, cameras=cameras, **rest)
        except (json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError) as exc:
            raise B2DFormatError(path, f"invalid {FORMAT_FILE}: {exc!r}") from exc


def write_format_info(clip_dir: str | os.PathLike[str], info: ClipFormatInfo) -> Path:
    """Write ``<clip_dir>/b2d_format.json`` and return its path."""
    path = Path(clip_dir) / FORMAT_FILE
    path.write_text(info.to_json(), encoding="utf-8")
    return path


def read_format_info(clip_dir: str | os.PathLike[str]) -> ClipFormatInfo | None:
    """Read ``<clip_dir>/b2d_format.json``; ``None`` when the clip has none (a released Bench2Drive clip)."""
    path = Path(clip_dir) / FORMAT_FILE
    if not path.is_file():
        return None
    data, label = read_source(path)
    try:
        text = bytes(data).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise B2DFormatError(label, f"invalid {FORMAT_FILE}: not UTF-8") from exc
    return ClipFormatInfo.from_json(text, label)
