"""Annotation gzip JSON: exact text, gzip header, NaN token, strict key order, corrupt files."""

from __future__ import annotations

import enum
import gzip
import io
import json
import math
import random
import time
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
    assert raw[8] == 0 and raw[9] == 255  # XFL: no level claimed; OS unknown, as CPython writes it
    assert abs(int.from_bytes(raw[4:8], "little") - time.time()) < 60  # MTIME: the write time
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


# ------------------------------------------------------------------- the fast writer is json.dumps(indent=4)

_FLOATS = [0.0, -0.0, 1.0, -1.5, 0.1, 1e-7, 1e-320, 5e-324, 1.7976931348623157e308, -2.5e22, 1e16, 123456789.125,
           float("nan"), float("inf"), float("-inf"), -float("nan")]  # fmt: skip
_STRINGS = ["", "ego_vehicle", 'quo"te', "back\\slash", "tab\tnew\nline\x00\x1f", "ünïcødé ✓ 🚗", "[1, 2]", "a,b:{c}",
            "%s %d %%", "n", "\u2028\ud800"]  # fmt: skip


def _random_value(rng: random.Random, depth: int) -> object:
    roll = rng.random()
    if depth > 5 or roll < 0.45:
        scalar = rng.choice(["float", "float", "int", "bool", "none", "str"])
        if scalar == "float":
            return rng.choice(_FLOATS) if rng.random() < 0.3 else rng.uniform(-1e3, 1e3) * 10.0 ** rng.randint(-8, 8)
        if scalar == "int":
            return rng.choice([0, 1, -1, 7, 2**63, -(2**70), rng.randint(-10**6, 10**6)])
        if scalar == "bool":
            return rng.random() < 0.5
        return None if scalar == "none" else rng.choice(_STRINGS)
    if roll < 0.6:  # a float row or matrix, the writer's fast paths (with the odd NaN or int among them)
        rows, cols = rng.randint(0, 4), rng.randint(0, 4)
        matrix = [[rng.choice(_FLOATS) if rng.random() < 0.05 else rng.uniform(-500, 500) for _ in range(cols)]
                  for _ in range(rows)]  # fmt: skip
        if rows and cols and rng.random() < 0.1:
            matrix[rng.randrange(rows)][rng.randrange(cols)] = rng.choice([1, True, None, "x"])
        if rows and rng.random() < 0.1:
            matrix[rng.randrange(rows)] = matrix[0][:-1] if cols else [1.0]  # ragged
        return matrix if rng.random() < 0.5 else (matrix[0] if matrix else [])
    if roll < 0.8:
        items = [_random_value(rng, depth + 1) for _ in range(rng.randint(0, 5))]
        return tuple(items) if rng.random() < 0.2 else items
    return {rng.choice(_STRINGS) + str(i): _random_value(rng, depth + 1) for i in range(rng.randint(0, 6))}


def test_fast_writer_matches_json_dumps_on_hand_built_values() -> None:
    cases: list[object] = [
        anno(), {}, [], (), [[]], [{}], {"a": []}, {"a": {}}, [[], {}, [[]]], 0.0, -0.0, "x", None, True, False, 3,
        [1.0, 2.0, 3.0], [[1.0, 2.0], [3.0, 4.0]], [[1.0, 2.0], [3.0]], [[1.0], [2.0], [3.0]], [[1.0, 2]],
        [1.0, 2], [1, 2.0], [True, 1.0], [1.0, True], [float("nan"), 1.0], [[float("inf"), -0.0], [float("-inf"), 1e300]],
        [[[1.0, 2.0], [3.0, 4.0]]], ([1.0, 2.0], [3.0, 4.0]), [(1.0, 2.0), (3.0, 4.0)], ((1.0,),),
        {"semantic_tags": [[14]], "bone": [[[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]], "ids": [1, 2, 3]},
        {s: s for s in _STRINGS}, {"k": [None, True, False, 0, -0.0, "", [], {}]},
        {"n": float("nan"), "i": float("inf"), "m": float("-inf")}, [2**100, -(2**100)], {"deep": [[[[[[[]]]]]]]},
    ]  # fmt: skip
    for value in cases:
        assert anno_json.dumps_indent4(value) == json.dumps(value, indent=4), value


def test_fast_writer_matches_json_dumps_on_random_values() -> None:
    rng = random.Random(1234)
    for _ in range(3000):
        value = _random_value(rng, 0)
        assert anno_json.dumps_indent4(value) == json.dumps(value, indent=4), value


def test_fast_writer_leaves_other_types_to_json() -> None:
    np = pytest.importorskip("numpy")
    # Types json takes its own way (subclasses, numpy float64, non-str keys) give json's text...
    for value in ([np.float64(0.1), 0.2], {"a": np.float64("nan")}, {1: "a", 2.5: "b", None: "c", False: "d"},
                  [IntFlag(3), 1.0], {"k": StrKind.A}, [[1.0, np.float64(2.0)]]):  # fmt: skip
        assert anno_json.dumps_indent4(value) == json.dumps(value, indent=4)
    # ...types json refuses raise json's error, and a circular document json's ValueError.
    for bad in ([np.float32(1.0)], {"a": np.int64(1)}, {"a": {1, 2}}, [np.array([1.0])]):
        with pytest.raises(TypeError, match="is not JSON serializable"):
            anno_json.dumps_indent4(bad)
    loop: list[object] = [1.0]
    loop.append(loop)
    with pytest.raises(ValueError, match="Circular reference"):
        anno_json.dumps_indent4(loop)
    deep: list[object] = []
    for _ in range(200):  # deeper than the writer's line-break tables: json.dumps writes it
        deep = [deep, 1.0]
    assert anno_json.dumps_indent4(deep) == json.dumps(deep, indent=4)


class IntFlag(int):
    """An int subclass: json writes int.__repr__ of it."""


class StrKind(str, enum.Enum):
    A = "a"


def test_fast_writer_is_what_the_files_hold(tmp_path: Path) -> None:
    rng = random.Random(7)
    value = {key: _random_value(rng, 1) for key in TOP_LEVEL_KEYS}
    path = tmp_path / "00001.json.gz"
    write_anno(path, value)
    assert gzip.decompress(path.read_bytes()).decode("utf-8") == json.dumps(value, indent=4)
    with gzip.open(tmp_path / "ref.json.gz", "wt") as f:
        json.dump(value, f, indent=4)
    ref = (tmp_path / "ref.json.gz").read_bytes()
    ours = encode_anno(value, file_name="ref.json.gz")
    # gzip.open's header but the mtime (bytes 4-7) and the level flag (byte 8); the same text inside.
    assert ours[:4] == ref[:4] and ours[9:19] == ref[9:19] == b"\xffref.json\x00"
    assert gzip.decompress(ours) == gzip.decompress(ref)
    with gzip.open(io.BytesIO(ours), "rt") as f:  # as Bench2Drive's loaders open it
        assert f.read() == json.dumps(value, indent=4)
