"""Annotation gzip JSON: exact text, gzip header, NaN token, strict key order, corrupt files."""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import pytest

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
