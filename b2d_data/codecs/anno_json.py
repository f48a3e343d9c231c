"""Annotations as gzip JSON (format.md §3): ``json.dump(indent=4)`` through ``gzip.open(path, 'wt')``.

Python's json writes NaN as the bare token ``NaN`` (theta may be NaN), which strict JSON parsers reject;
``read_anno`` accepts it and changes nothing (the known data fixes live in ``b2d_data.coords``).
"""

from __future__ import annotations

import gzip
import io
import json
import os
import zlib
from pathlib import Path

from b2d_data.codecs._source import Source, read_source
from b2d_data.format.anno_schema import check_anno
from b2d_data.format.errors import B2DFormatError

_GZIP_MAGIC = b"\x1f\x8b"


class AnnoSchemaError(ValueError):
    """An annotation dict whose keys do not follow Bench2Drive's order (raised by the strict writer)."""


def validate_anno(anno: dict, *, frame: str = "annotation") -> None:
    """Raise ``AnnoSchemaError`` naming ``frame`` when the key orders differ from Bench2Drive's (format.md §3)."""
    problems = check_anno(anno)
    if problems:
        shown = "; ".join(problems[:5]) + (f"; … {len(problems) - 5} more" if len(problems) > 5 else "")
        raise AnnoSchemaError(f"{frame}: annotation does not follow the Bench2Drive key order: {shown}")


def anno_text(anno: dict, *, strict: bool = False, frame: str = "annotation") -> str:
    """The JSON text Bench2Drive writes (4-space indent, default separators, bare NaN); ``strict`` checks key orders."""
    if strict:
        validate_anno(anno, frame=frame)
    return json.dumps(anno, indent=4)


def encode_anno(
    anno: dict, *, file_name: str = "00000.json.gz", strict: bool = False, frame: str = "annotation"
) -> bytes:
    """Gzip the annotation text as ``gzip.open(file_name, 'wt')`` would (level 9, FNAME without ``.gz``)."""
    text = anno_text(anno, strict=strict, frame=frame)
    bio = io.BytesIO()
    with gzip.GzipFile(filename=file_name, mode="wb", fileobj=bio, compresslevel=9) as f:
        f.write(text.encode("utf-8"))
    return bio.getvalue()


def write_anno(path: str | os.PathLike[str], anno: dict, *, strict: bool = False, frame: str | None = None) -> int:
    """Write ``anno/NNNNN.json.gz`` exactly as the collector does; returns the number of bytes written."""
    text = anno_text(anno, strict=strict, frame=frame or os.fspath(path))
    with gzip.open(path, "wt", encoding="utf-8") as f:
        f.write(text)
    return Path(path).stat().st_size


def read_anno(source: Source, *, name: str | os.PathLike[str] | None = None) -> dict:
    """Decode ``NNNNN.json.gz`` (path or bytes) to the annotation dict; NaN and null values are kept as stored."""
    data, label = read_source(source, name)
    if bytes(data[:2]) != _GZIP_MAGIC:
        raise B2DFormatError(label, "not a gzip file (missing the 1F 8B magic)")
    try:
        raw = gzip.decompress(data)
    except EOFError as exc:
        raise B2DFormatError(label, "truncated gzip stream") from exc
    except (OSError, zlib.error) as exc:
        raise B2DFormatError(label, f"invalid gzip data: {exc}") from exc
    try:
        anno = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise B2DFormatError(label, f"annotation is not UTF-8 text: {exc}") from exc
    except json.JSONDecodeError as exc:
        raise B2DFormatError(label, f"invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from exc
    if not isinstance(anno, dict):
        raise B2DFormatError(label, f"annotation must be a JSON object, got {type(anno).__name__}")
    return anno
