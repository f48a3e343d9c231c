"""Radar h5: float16 datasets with gzip 9 and auto chunks, empty radars, missing files/datasets, corruption."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from b2d_data.codecs.radar_h5 import RADAR_DATASETS, encode_radar, read_radar, write_radar
from b2d_data.format.errors import B2DFormatError


def detections() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(4)
    return {name: rng.uniform([0, -0.3, -0.3, -20], [100, 0.3, 0.3, 20], (n, 4)) for name, n in
            zip(RADAR_DATASETS, (7, 0, 2, 1, 3))}  # fmt: skip


def test_datasets_on_disk(tmp_path: Path) -> None:
    path = tmp_path / "00000.h5"
    write_radar(path, detections())
    with h5py.File(path, "r") as f:
        assert sorted(f.keys()) == sorted(RADAR_DATASETS)
        for name, n in zip(RADAR_DATASETS, (7, 0, 2, 1, 3)):
            dset = f[name]
            assert dset.shape == (n, 4) and dset.dtype == np.float16
            assert dset.compression == "gzip" and dset.compression_opts == 9 and dset.chunks is not None


def test_round_trip_within_float16(tmp_path: Path) -> None:
    src = detections()
    back = read_radar(encode_radar(src))
    assert list(back) == list(RADAR_DATASETS)
    for name, arr in src.items():
        assert back[name].dtype == np.float32
        assert np.array_equal(back[name], arr.astype(np.float16).astype(np.float32))
    assert read_radar(encode_radar(src), dtype=np.float16)["radar_front"].dtype == np.float16


def test_absent_radars_are_stored_empty() -> None:
    back = read_radar(encode_radar({"radar_front": np.ones((2, 4))}))
    assert back["radar_front"].shape == (2, 4) and back["radar_back_right"].shape == (0, 4)
    with pytest.raises(ValueError, match="front"):
        encode_radar({"front": np.ones((2, 4))})


def test_missing_file_and_dataset(tmp_path: Path) -> None:
    with pytest.raises(B2DFormatError, match="none.h5"):
        read_radar(tmp_path / "none.h5")
    assert read_radar(tmp_path / "none.h5", missing_ok=True) == {}
    path = tmp_path / "partial.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("radar_front", data=np.ones((1, 4), np.float16))
    with pytest.raises(B2DFormatError, match="partial.h5.*radar_front_left"):
        read_radar(path)
    assert list(read_radar(path, missing_ok=True)) == ["radar_front"]


def test_corrupt_h5(tmp_path: Path) -> None:
    data = encode_radar(detections())
    (tmp_path / "cut.h5").write_bytes(data[: len(data) // 2])
    with pytest.raises(B2DFormatError, match="cut.h5"):
        read_radar(tmp_path / "cut.h5")
    (tmp_path / "junk.h5").write_bytes(b"junk" * 100)
    with pytest.raises(B2DFormatError, match="junk.h5"):
        read_radar(tmp_path / "junk.h5", missing_ok=True)
