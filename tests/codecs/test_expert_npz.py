"""Expert npz: the −1 file-name shift, np.savez byte identity, tolerant decoding."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from b2d_data.codecs.expert_npz import (
    encode_expert,
    expert_file_name,
    expert_frame_index,
    read_expert,
    split_expert,
    write_expert,
)
from b2d_data.format.errors import B2DFormatError


def test_file_names_are_shifted_by_minus_one() -> None:
    assert expert_file_name(0) == "-0001.npz"
    assert expert_file_name(1) == "00000.npz"
    assert expert_file_name(42) == "00041.npz"
    assert expert_frame_index("-0001.npz") == 0
    assert expert_frame_index(Path("clip/expert_assessment/00041.npz")) == 42
    for k in range(0, 200, 7):
        assert expert_frame_index(expert_file_name(k)) == k
    with pytest.raises(ValueError):
        expert_frame_index("00041.json")


def test_bytes_equal_np_savez(tmp_path: Path) -> None:
    vector = np.random.default_rng(5).normal(size=1538).astype(np.float32)
    reference = tmp_path / "ref.npz"
    np.savez(reference, vector)
    ours = tmp_path / "-0001.npz"
    write_expert(ours, vector)
    with np.load(ours) as npz:
        assert npz.files == ["arr_0"]
    assert ours.read_bytes() == reference.read_bytes()
    assert np.array_equal(read_expert(ours), vector)


def test_split_and_other_keys() -> None:
    vector = np.concatenate([np.zeros(1536), [0.75, 12.0]])
    feature, value, action = split_expert(read_expert(encode_expert(vector)))
    assert feature.shape == (1536,) and value == 0.75 and action == 12
    bio = io.BytesIO()
    np.savez(bio, feature=vector)
    assert np.array_equal(read_expert(bio.getvalue()), vector)


def test_bad_expert_files() -> None:
    bio = io.BytesIO()
    np.savez(bio, np.zeros((2, 2)))
    with pytest.raises(B2DFormatError, match="e.npz.*1-D"):
        read_expert(bio.getvalue(), name="e.npz")
    with pytest.raises(B2DFormatError, match="e.npz"):
        read_expert(b"PK\x03\x04 broken", name="e.npz")
