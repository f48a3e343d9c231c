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

from b2d_data.codecs._source import Source, read_source, write_bytes
from b2d_data.format.anno_schema import check_anno
from b2d_data.format.errors import B2DFormatError

_GZIP_MAGIC = b"\x1f\x8b"

#: Largest decompressed annotation :func:`read_anno` accepts (bytes). Annotations of the largest towns are a few MB;
#: the cap stops a small crafted file from inflating to gigabytes (300 KB of gzip held 300 MB of spaces). Read at
#: call time, so setting ``anno_json.MAX_ANNO_BYTES`` changes it for every reader.
MAX_ANNO_BYTES = 64 << 20


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
        # The text wrapper of gzip.open flushes the gzip file when it closes (a zlib sync flush) before the gzip
        # file ends the stream: the same here, so that the bytes are those of gzip.open (mtime aside).
        f.flush()
    return bio.getvalue()


def write_anno(path: str | os.PathLike[str], anno: dict, *, strict: bool = False, frame: str | None = None) -> int:
    """Write ``anno/NNNNN.json.gz`` exactly as the collector does; returns the number of bytes written."""
    # Encoded in memory and written in one go: the bytes of gzip.open(path, "wt") with three file system calls.
    data = encode_anno(anno, file_name=os.path.basename(os.fspath(path)), strict=strict, frame=frame or os.fspath(path))
    return write_bytes(path, data)


def gunzip_capped(data: bytes | memoryview, limit: int) -> bytes:
    """Decompress a (multi-member) gzip stream, refusing to produce more than ``limit`` bytes.

    Raises ``ValueError`` past the limit, ``EOFError`` when the stream is cut off and ``zlib.error`` on bad data.
    """
    out = bytearray()
    rest: bytes | memoryview = data
    while len(rest):
        inflater = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)  # gzip header and trailer (CRC, length) checked
        pending = rest
        while not inflater.eof:
            # In 1 MiB steps (no second buffer the size of the text); at most one byte over the limit is produced,
            # which is enough to tell that it was exceeded.
            chunk = inflater.decompress(pending, min(1 << 20, limit + 1 - len(out)))
            pending = inflater.unconsumed_tail
            out += chunk
            if len(out) > limit:
                raise ValueError(f"decompresses to more than {limit} bytes")
            if not chunk and not pending:
                raise EOFError("compressed data ended before the end-of-stream marker")
        # Like gzip.decompress: further members may follow, and zero padding after the last one is ignored.
        rest = inflater.unused_data.lstrip(b"\x00")
    return bytes(out)


def read_anno(source: Source, *, name: str | os.PathLike[str] | None = None, max_bytes: int | None = None) -> dict:
    """Decode ``NNNNN.json.gz`` (path or bytes) to the annotation dict; NaN and null values are kept as stored.

    The decompressed text may not exceed ``max_bytes`` (default :data:`MAX_ANNO_BYTES`).
    """
    data, label = read_source(source, name)
    if bytes(data[:2]) != _GZIP_MAGIC:
        raise B2DFormatError(label, "not a gzip file (missing the 1F 8B magic)")
    limit = MAX_ANNO_BYTES if max_bytes is None else max_bytes
    try:
        raw = gunzip_capped(data, limit)
    except ValueError as exc:
        raise B2DFormatError(
            label,
            f"annotation {exc} (a gzip bomb, or an annotation larger than b2d_data.codecs.anno_json.MAX_ANNO_BYTES)",
        ) from None
    except EOFError as exc:
        raise B2DFormatError(label, "truncated gzip stream") from exc
    except zlib.error as exc:
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
