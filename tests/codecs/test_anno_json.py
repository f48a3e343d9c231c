"""Annotation gzip JSON: exact text, gzip header, NaN token, strict key order, corrupt files."""

from __future__ import annotations

import gzip
import json
import math
import zlib
from pathlib import Path

import pytest

from b2d_data.codecs import anno_json
from b2d_data.codecs.anno_json import AnnoSchemaError, encode_anno, read_anno, validate_anno, write_anno
from b2d_data.format.anno_schema import EGO_KEYS, TOP_LEVEL_KEYS
from b2d_data.format.errors import B2DFormatError


def anno() -> dict:
    values: dict[str, object] = {key: 0.5 for key in TOP_LEVEL_KEYS}
    values.update(theta=float("nan"), speed=None, reverse=False, sensors={},
                  bounding_boxes=[{key: 1 for key in EGO_KEYS} | {"class": "ego_vehicle"}])  # fmt: skip
    return values


def test_file_layout(tmp_path: Path) -> None:
    path = tmp_path / "00003.json.gz"
    write_anno(path, anno())
    raw = path.read_bytes()
    assert raw[:3] == b"\x1f\x8b\x08"  # gzip magic, deflate
    assert raw[3] & 0x08  # FNAME set, as gzip.open writes it
    assert raw[10:21] == b"00003.json\x00"
    assert raw[8] == 2  # XFL: level 9
    text = gzip.decompress(raw).decode("utf-8")
    assert text == json.dumps(anno(), indent=4)
    assert '\n    "theta": NaN,\n' in text and '\n    "speed": null,\n' in text
    assert text.startswith('{\n    "x": 0.5,\n    "y": 0.5,')


def test_round_trip_keeps_nan_and_null(tmp_path: Path) -> None:
    back = read_anno(encode_anno(anno(), file_name="00000.json.gz"))
    assert math.isnan(back["theta"]) and back["speed"] is None
    assert list(back) == list(TOP_LEVEL_KEYS)
    assert gzip.decompress(encode_anno(anno())).decode() == json.dumps(anno(), indent=4)


def test_strict_key_order() -> None:
    bad = anno()
    bad = {"y": bad.pop("y"), **bad}
    with pytest.raises(AnnoSchemaError, match="frame 7.*top-level keys"):
        encode_anno(bad, strict=True, frame="frame 7")
    with pytest.raises(AnnoSchemaError):
        validate_anno(bad, frame="x")
    encode_anno(bad)  # not strict: written as given


def test_corrupt_annotations(tmp_path: Path) -> None:
    good = encode_anno(anno())
    cases = {
        "plain.json.gz": json.dumps(anno()).encode(),
        "cut.json.gz": good[: len(good) // 2],
        "badjson.json.gz": gzip.compress(b'{"x": 1,'),
        "list.json.gz": gzip.compress(b"[1, 2]"),
    }
    for name, content in cases.items():
        (tmp_path / name).write_bytes(content)
        with pytest.raises(B2DFormatError, match=name.replace(".", r"\.")):
            read_anno(tmp_path / name)
    corrupt = bytearray(good)
    corrupt[20:40] = b"\xff" * 20
    with pytest.raises(B2DFormatError, match="gzip"):
        read_anno(bytes(corrupt), name="c.json.gz")


def _spaces_bomb(n_bytes: int) -> bytes:
    """A gzip member holding ``n_bytes`` spaces (about 1000× smaller), built without holding the text in memory."""
    deflate = zlib.compressobj(9, zlib.DEFLATED, 16 + zlib.MAX_WBITS)
    chunk = b" " * (1 << 20)
    parts = [deflate.compress(chunk) for _ in range(n_bytes >> 20)]
    return b"".join(parts) + deflate.flush()


def test_gzip_bomb_is_refused_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "anno" / "00030.json.gz"
    path.parent.mkdir()
    path.write_bytes(_spaces_bomb(4 << 20))  # 4 MiB of spaces in a few KB
    assert len(path.read_bytes()) < 20_000
    with pytest.raises(B2DFormatError) as info:
        read_anno(path, max_bytes=1 << 20)
    assert str(info.value).startswith(f"{path}: annotation decompresses to more than 1048576 bytes (a gzip bomb")
    # The module constant is the default cap, read at each call.
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(anno_json, "MAX_ANNO_BYTES", 2 << 20)
        with pytest.raises(B2DFormatError, match="more than 2097152 bytes"):
            read_anno(path)
    # Under the cap the same text is read (and is not JSON): the cap, not the content, refused it above.
    with pytest.raises(B2DFormatError, match="invalid JSON"):
        read_anno(path, max_bytes=4 << 20)


def test_gzip_bomb_memory_stays_near_the_cap() -> None:
    import tracemalloc

    bomb = _spaces_bomb(256 << 20)  # 256 MiB of spaces (~250 KB of gzip)
    tracemalloc.start()
    try:
        with pytest.raises(B2DFormatError, match=f"more than {anno_json.MAX_ANNO_BYTES} bytes"):
            read_anno(bomb, name="bomb.json.gz")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # gzip.decompress built the whole 256 MiB (peak ≥ 256 MiB); the capped reader stops at 64 MiB + 1 byte, inflated
    # in 1 MiB steps, so its peak is the cap plus a few MiB (bytearray growth): measured 67.5 MiB, bound 72 MiB.
    assert anno_json.MAX_ANNO_BYTES == 64 << 20 and peak < 72 << 20


def test_multi_member_gzip_still_reads() -> None:
    # gzip files may hold several members (e.g. appended); their texts are concatenated, as gzip.decompress does.
    data = gzip.compress(b'{"x": 1, ') + gzip.compress(b'"y": 2}') + b"\x00\x00"
    assert read_anno(data) == {"x": 1, "y": 2}
