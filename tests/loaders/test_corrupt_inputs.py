"""Corrupt inputs raise errors naming the file; ``on_error="skip"`` reports and skips them instead."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from torch.utils.data import DataLoader

from b2d_data import ClipDataset
from b2d_data.codecs import layout
from b2d_data.format.errors import B2DFormatError
from b2d_data.loaders import BadFrame, CorpusIndex, collate

from .conftest import CLIP_A


def _corrupt(root: Path) -> dict[int, str]:
    """Break frames 2..6 of clip A in five ways; returns frame → the file the error must name."""
    clip = root / str(CLIP_A)
    jpg = layout.image_path(clip, "rgb", "front", 2)
    jpg.write_bytes(jpg.read_bytes()[: len(jpg.read_bytes()) // 2])  # truncated JPEG
    layout.lidar_path(clip, 3).write_bytes(b"LASF" + bytes(range(200)))  # garbage LAZ
    layout.anno_path(clip, 4).write_bytes(b"\x1f\x8b\x08\x00garbage, not deflate")  # invalid gzip
    layout.image_path(clip, "rgb", "front", 5).unlink()  # a missing file
    for path in clip.rglob("00006.*"):  # a whole frame missing
        path.unlink()
    return {
        2: "camera/rgb_front/00002.jpg",
        3: "lidar/00003.laz",
        4: "anno/00004.json.gz",
        5: "camera/rgb_front/00005.jpg",
        6: "anno/00006.json.gz",
    }


def test_each_corrupt_input_raises_naming_the_file(corpus_copy: Path) -> None:
    expected = _corrupt(corpus_copy)
    ds = ClipDataset(corpus_copy, clips=[str(CLIP_A)], cameras=("front",))
    assert len(ds) == 12  # the whole-missing frame 6 is still listed, so its absence is reported
    for frame, name in expected.items():
        with pytest.raises(B2DFormatError) as info:
            ds[frame]
        assert name in str(info.value) and str(CLIP_A) in str(info.value)
    ds[7]  # frames around the damage still load


def test_skip_mode_reports_bad_frames(corpus_copy: Path, tmp_path: Path) -> None:
    expected = _corrupt(corpus_copy)
    log = tmp_path / "bad.jsonl"
    ds = ClipDataset(corpus_copy, clips=[str(CLIP_A)], cameras=("front",), on_error="skip", error_log=log)
    samples = [ds[i] for i in range(len(ds))]
    # A skipped frame comes back as its BadFrame record (it used to be None, which torch's default collate refused).
    assert [i for i, s in enumerate(samples) if isinstance(s, BadFrame)] == sorted(expected)
    assert [s for s in samples if isinstance(s, BadFrame)] == ds.bad_frames
    assert {b.frame: b for b in ds.bad_frames}.keys() == expected.keys()
    assert all(expected[b.frame] in b.error for b in ds.bad_frames)
    # From DataLoader workers the report goes to the JSON-lines log; collate drops and counts the skipped frames.
    log.unlink()
    batches = list(DataLoader(ds, batch_size=12, num_workers=2, collate_fn=collate))
    assert sum(b["skipped"] for b in batches) == 5 and sum(b["batch_size"] for b in batches) == 7
    logged = [json.loads(line) for line in log.read_text().splitlines()]
    assert sorted(r["frame"] for r in logged) == sorted(expected)


def test_skip_mode_with_a_plain_dataloader(corpus_copy: Path) -> None:
    # The README's loop, DataLoader(ds, batch_size=..., num_workers=2) with torch's default collate: it raised
    # "default_collate: batch must contain tensors, ... found <class 'NoneType'>" on the first skipped frame.
    _corrupt(corpus_copy)  # frames 2, 3, 4, 5, 6 of the 12 are bad
    ds = ClipDataset(corpus_copy, clips=[str(CLIP_A)], cameras=("front",), on_error="skip")
    batches = list(DataLoader(ds, batch_size=3, num_workers=2))
    # Batches of frames [0 1 2] [3 4 5] [6 7 8] [9 10 11]: the second is all bad, the third starts with a bad frame.
    assert [b["batch_size"] for b in batches] == [2, 0, 2, 3] and [b["skipped"] for b in batches] == [1, 3, 1, 0]
    assert [b["frame"].tolist() for b in batches if b["batch_size"]] == [[0, 1], [7, 8], [9, 10, 11]]
    assert batches[0]["images"].shape == (2, 1, 36, 64, 3) and len(batches[0]["lidar"]) == 2


def test_malformed_clip_name(corpus_copy: Path) -> None:
    bad = corpus_copy / "Accident_Town03_RouteX_Weather0"
    shutil.copytree(corpus_copy / str(CLIP_A), bad)
    # Opened directly, the clip folder is rejected with its path and the expected pattern.
    with pytest.raises(B2DFormatError, match="RouteX") as info:
        ClipDataset(bad)
    assert "Weather" in str(info.value)
    # In a corpus, the index records the error naming the folder and the dataset leaves the clip out.
    index, report = CorpusIndex.build(corpus_copy)
    assert str(bad) in report.errors[bad.name]
    ds = ClipDataset(corpus_copy, cameras=())
    assert bad.name not in ds.clip_names and len(ds.clip_names) == 2
