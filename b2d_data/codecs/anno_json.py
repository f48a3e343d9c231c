"""Annotations as gzip JSON (format.md §3): the text of ``json.dump(indent=4)``, gzipped with ``gzip.open``'s header.

Python's json writes NaN as the bare token ``NaN`` (theta may be NaN), which strict JSON parsers reject;
``read_anno`` accepts it and changes nothing (the known data fixes live in ``b2d_data.coords``).
"""

from __future__ import annotations

import json
import logging
import os
import struct
import time
import zlib
from itertools import chain
from json.encoder import encode_basestring_ascii
from operator import add
from typing import Any

from isal import isal_zlib as _isal_zlib

from b2d_data.codecs._source import Source, read_source, write_bytes
from b2d_data.format.anno_schema import check_anno
from b2d_data.format.errors import B2DFormatError

logger = logging.getLogger(__name__)

_GZIP_MAGIC = b"\x1f\x8b"
_FNAME = 0x08  # gzip header flag: a file name follows
_OS_UNKNOWN = 255  # the OS byte CPython's gzip writes
#: ISA-L's deflate level for annotations (0–3): 2 compresses as well as 3 at a quarter of its time.
ANNO_LEVEL = 2

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
    return dumps_indent4(anno)


# ------------------------------------------------------------------------------------ json.dumps(indent=4), faster
# With ``indent`` set, CPython's json falls back to its pure-Python encoder: a generator per container and a call
# per item (~1.6 ms for one frame's ~1,400 numbers). The writer below renders the same text with fewer Python steps:
# leaf lists of floats in one ``join``, matrices (lists of equal-length float lists) through one cached ``%``
# template, dict keys as cached prefixes. It handles exactly the builtin types build_annotation emits (dict with str
# keys, list, tuple, str, int, float, bool, None) by *exact* type and renders them by json's own rules; anything
# else (numpy scalars, subclasses, non-str keys, nesting deeper than its tables) raises ``_Unsupported`` and the
# whole document goes through ``json.dumps`` instead, so the text (or the error) is always json's.

_INDENT = "    "
#: Nesting depths with precomputed line breaks; deeper documents take json.dumps.
_MAX_DEPTH = 64
_NEWLINE = tuple("\n" + _INDENT * depth for depth in range(_MAX_DEPTH + 3))
_ITEM_SEP = tuple("," + newline for newline in _NEWLINE)
#: json writes the IEEE specials as these tokens (allow_nan=True); float.__repr__ spells them nan / inf / -inf.
_FLOAT_SPECIALS = {"nan": "NaN", "inf": "Infinity", "-inf": "-Infinity"}
_FLOAT_ONLY = {float}
_LIST_ONLY = {list}
_STR_ONLY = {str}
_float_repr = float.__repr__
_int_repr = int.__repr__
#: Caches of rendered skeletons: few distinct (depth, shape) and (depth, key tuple) pairs occur in annotations, but
#: arbitrary input must not grow them without bound.
_CACHE_LIMIT = 4096
_matrix_templates: dict[tuple[int, int, int], str] = {}
_key_prefixes: dict[tuple[int, tuple[str, ...]], list[str]] = {}


class _Unsupported(Exception):
    """A value the fast writer does not render itself (json.dumps takes the whole document)."""


def _float_text(value: float) -> str:
    # json tests o != o and compares with ±inf; for an exact float the repr tells the same (every NaN is 'nan').
    text = _float_repr(value)
    return _FLOAT_SPECIALS.get(text, text)


def _matrix_template(depth: int, rows: int, cols: int) -> str:
    key = (depth, rows, cols)
    template = _matrix_templates.get(key)
    if template is None:
        row = "[" + _NEWLINE[depth + 2] + _ITEM_SEP[depth + 2].join(["%s"] * cols) + _NEWLINE[depth + 1] + "]"
        template = "[" + _NEWLINE[depth + 1] + _ITEM_SEP[depth + 1].join([row] * rows) + _NEWLINE[depth] + "]"
        if len(_matrix_templates) < _CACHE_LIMIT:
            _matrix_templates[key] = template
    return template


def _prefixes(depth: int, keys: tuple[Any, ...]) -> list[str]:
    """``{``/``,`` + line break + encoded key + ``": "`` before each value of a dict with these keys."""
    if set(map(type, keys)) != _STR_ONLY:
        raise _Unsupported  # json turns int/float/bool/None keys into strings: left to it
    cache_key = (depth, keys)
    prefixes = _key_prefixes.get(cache_key)
    if prefixes is None:
        newline, sep = _NEWLINE[depth + 1], _ITEM_SEP[depth + 1]
        encoded = [encode_basestring_ascii(key) + ": " for key in keys]
        prefixes = ["{" + newline + encoded[0]] + [sep + key for key in encoded[1:]]
        if len(_key_prefixes) < _CACHE_LIMIT:
            _key_prefixes[cache_key] = prefixes
    return prefixes


def _render_list(value: list | tuple, depth: int) -> str:
    if not value:
        return "[]"
    inner = depth + 1
    first = type(value[0])
    if first is float:
        if set(map(type, value)) == _FLOAT_ONLY:
            body = _ITEM_SEP[inner].join(map(_float_repr, value))
            if "n" in body:  # nan / inf: a finite repr holds no 'n'
                body = _ITEM_SEP[inner].join(map(_float_text, value))
            return "[" + _NEWLINE[inner] + body + _NEWLINE[depth] + "]"
    elif first is list and set(map(type, value)) == _LIST_ONLY:
        lengths = set(map(len, value))
        if len(lengths) == 1:
            flat = tuple(chain.from_iterable(value))
            if flat and set(map(type, flat)) == _FLOAT_ONLY:
                template = _matrix_template(depth, len(value), len(flat) // len(value))
                text = template % tuple(map(_float_repr, flat))
                if "n" in text:  # the template itself is brackets, commas and white space
                    text = template % tuple(map(_float_text, flat))
                return text
    return "[" + _NEWLINE[inner] + _ITEM_SEP[inner].join([_render(item, inner) for item in value]) + _NEWLINE[depth] + "]"


def _render_dict(value: dict, depth: int) -> str:
    if not value:
        return "{}"
    prefixes = _prefixes(depth, tuple(value))
    inner = depth + 1
    return "".join(map(add, prefixes, [_render(item, inner) for item in value.values()])) + _NEWLINE[depth] + "}"


def _render(value: Any, depth: int) -> str:
    kind = type(value)
    if kind is list or kind is tuple:
        return _render_list(value, depth)
    if kind is float:
        return _float_text(value)
    if kind is str:
        return encode_basestring_ascii(value)
    if kind is dict:
        return _render_dict(value, depth)
    if kind is int:
        return _int_repr(value)
    if kind is bool:
        return "true" if value else "false"
    if value is None:
        return "null"
    raise _Unsupported


def dumps_indent4(obj: Any) -> str:
    """Exactly ``json.dumps(obj, indent=4)`` (same text, same errors), several times faster on annotations."""
    try:
        return _render(obj, 0)
    except (_Unsupported, IndexError, RecursionError) as exc:
        # Unknown types, deeper than the line-break tables, or circular: json.dumps writes it or raises its error.
        logger.debug("annotation text through json.dumps (%s)", type(exc).__name__)
        return json.dumps(obj, indent=4)


def encode_anno(
    anno: dict, *, file_name: str = "00000.json.gz", strict: bool = False, frame: str = "annotation"
) -> bytes:
    """Gzip the annotation text with ``gzip.open(file_name, 'wt')``'s header (FNAME without ``.gz``, write time, OS
    255), deflated by ISA-L.

    zlib's level 9, which gzip.open uses, cost ~2 ms of CPU a frame for the ~80 KB text; ISA-L's level 2 ~0.05 ms,
    for files ~25 % larger (~2 KB a frame, 0.3 % of a frame's files). The text, and so what any gzip reader returns,
    is the same.
    """
    text = anno_text(anno, strict=strict, frame=frame).encode("utf-8")
    name = file_name[:-3] if file_name.endswith(".gz") else file_name
    header = struct.pack("<BBBBIBB", 0x1F, 0x8B, 8, _FNAME, int(time.time()), 0, _OS_UNKNOWN)
    body = _isal_zlib.compress(text, ANNO_LEVEL, wbits=-15)  # a raw deflate stream
    trailer = struct.pack("<II", zlib.crc32(text), len(text) & 0xFFFFFFFF)
    return b"".join((header, name.encode("latin-1"), b"\0", body, trailer))


def write_anno(path: str | os.PathLike[str], anno: dict, *, strict: bool = False, frame: str | None = None) -> int:
    """Write ``anno/NNNNN.json.gz`` exactly as the collector does; returns the number of bytes written."""
    # Encoded in memory and written in one go: three file system calls.
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
