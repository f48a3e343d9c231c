"""The writers that go straight through file descriptors write what the ways they replaced wrote: the annotation's
text and gzip header as ``gzip.open(path, "wt")`` wrote them, the radar h5's bytes as h5py wrote them to a path, any
file through ``write_bytes``."""

from __future__ import annotations

import gzip
import json
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np
import pytest

from b2d_data.codecs import anno_json
from b2d_data.codecs._source import write_bytes
from b2d_data.codecs.anno_json import read_anno, write_anno
from b2d_data.codecs.radar_h5 import RADAR_DATASETS, encode_radar, write_radar


def _random_anno(seed: int) -> dict:
    """An annotation-like dict of ~150 KB of JSON text (several of gzip.open's 8 KB text chunks), NaN included."""
    rng = np.random.default_rng(seed)
    boxes = [{"id": str(i), "location": rng.normal(0, 50, 3).tolist(), "theta": float("nan") if i % 7 == 0 else
              float(rng.uniform(-3, 3)), "class": "vehicle"} for i in range(600)]  # fmt: skip
    return {"x": float(rng.normal()), "bounding_boxes": boxes}


def test_anno_is_what_gzip_open_wrote(tmp_path, monkeypatch):
    # The old writer, verbatim: json text through gzip.open(path, "wt"). mtime frozen: the header holds the time.
    monkeypatch.setattr(gzip.time, "time", lambda: 1_700_000_000.0)
    monkeypatch.setattr(anno_json.time, "time", lambda: 1_700_000_000.0)
    for seed in (0, 1):
        anno = _random_anno(seed)
        (tmp_path / "old").mkdir(exist_ok=True)
        (tmp_path / "new").mkdir(exist_ok=True)
        old, new = tmp_path / "old" / "00042.json.gz", tmp_path / "new" / "00042.json.gz"
        with gzip.open(old, "wt", encoding="utf-8") as f:
            f.write(json.dumps(anno, indent=4))
        size = write_anno(new, anno)
        ours, theirs = new.read_bytes(), old.read_bytes()
        # The header but its level flag (byte 8: ISA-L deflates, not zlib's level 9), then the same text.
        header = len(b"\x1f\x8b\x08\x08") + 4 + 2 + len(b"00042.json\x00")
        assert ours[:8] == theirs[:8] and ours[9:header] == theirs[9:header]
        assert gzip.decompress(ours) == gzip.decompress(theirs) == json.dumps(anno, indent=4).encode()
        assert size == new.stat().st_size
        back = read_anno(new)
        assert back["bounding_boxes"][1] == anno["bounding_boxes"][1]


def _old_radar(path, radar) -> None:
    """The old writer: h5py straight to the path (float16, gzip 9, auto chunks, all five datasets)."""
    with h5py.File(path, "w") as f:
        for key in RADAR_DATASETS:
            arr = np.asarray(radar.get(key, np.zeros((0, 4))), np.float16)
            f.create_dataset(key, data=arr, compression="gzip", compression_opts=9, chunks=True)


@pytest.mark.parametrize("counts", [(40, 0, 12, 75, 3), (0, 0, 0, 0, 0), (1, 75, None, 2, 9)])
def test_radar_bytes_are_those_of_h5py_on_a_path(tmp_path, counts):
    rng = np.random.default_rng(sum(c or 0 for c in counts))
    radar = {k: rng.normal(0, 20, (n, 4)) for k, n in zip(RADAR_DATASETS, counts) if n is not None}
    _old_radar(tmp_path / "old.h5", radar)
    size = write_radar(tmp_path / "new.h5", radar)
    assert (tmp_path / "new.h5").read_bytes() == (tmp_path / "old.h5").read_bytes()
    assert size == (tmp_path / "new.h5").stat().st_size


def test_radar_encoding_from_threads_at_once():
    # Every in-memory HDF5 file has its own name: files open at once in several threads stay apart.
    rng = np.random.default_rng(3)
    radars = [{k: rng.normal(0, 20, (30 + i, 4)) for k in RADAR_DATASETS} for i in range(8)]
    alone = [encode_radar(r) for r in radars]
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(encode_radar, radars))
    assert together == alone
    assert len(set(alone)) == len(alone)


def test_write_bytes(tmp_path):
    path = tmp_path / "f.bin"
    path.write_bytes(b"x" * 1000)  # longer than what follows: truncated, as open(path, "wb") does
    assert write_bytes(path, b"abc") == 3
    assert path.read_bytes() == b"abc"
    data = np.arange(100_000, dtype=np.uint16)
    assert write_bytes(str(path), memoryview(data)) == 200_000  # a multi-byte view counts bytes
    assert path.read_bytes() == data.tobytes()
    with pytest.raises(FileNotFoundError):
        write_bytes(tmp_path / "missing" / "f.bin", b"abc")
