"""The parquet corpus index: contents, incremental updates, archives, and the open time of a large corpus."""

from __future__ import annotations

import hashlib
import math
import shutil
import time
from pathlib import Path

import pytest

from b2d_data import ClipDataset
from b2d_data.format.names import ClipName
from b2d_data.loaders import CorpusIndex
from b2d_data.loaders.index import index_dir
from b2d_data.loaders.synthetic import SyntheticClipSpec, fabricate_index, write_synthetic_clip
from b2d_data.writers.archive import pack_clip

from .conftest import CLIP_A, CLIP_B


def _rows(index: CorpusIndex) -> dict[str, dict]:
    return {r["name"]: r for r in index.clips.to_pylist()}


def test_index_contents(corpus_copy: Path) -> None:
    index, report = CorpusIndex.build(corpus_copy)
    assert (index_dir(corpus_copy) / "clips.parquet").is_file() and (
        index_dir(corpus_copy) / "frames.parquet"
    ).is_file()
    assert (index.num_clips, index.num_frames) == (2, 18) and sorted(report.scanned) == sorted(
        [str(CLIP_A), str(CLIP_B)]
    )
    a, b = _rows(index)[str(CLIP_A)], _rows(index)[str(CLIP_B)]
    assert (a["scenario"], a["town"], a["route_id"], a["weather_id"], a["n_frames"]) == ("Accident", "Town03", 1, 0, 12)
    assert a["n_rgb_front"] == 12 and a["n_rgb_top_down"] == 0 and a["n_depth_npz_front"] == 0 and a["n_radar"] == 12
    assert b["n_depth_npz_front"] == 6 and b["format_version"] == "bench2drive-v0.0.4"
    frames = index.frames.slice(a["frame_start"], a["n_frames"]).to_pydict()
    # Ego starts at (100, 200) with CARLA yaw 30° and drives 0.5 m per frame; GNSS is 1.4 m behind.
    assert frames["ego_x"][0] == pytest.approx(100.0) and frames["ego_yaw"][0] == pytest.approx(math.radians(30))
    assert frames["ego_x"][2] == pytest.approx(100.0 + math.cos(math.radians(30)) * 1.0)
    assert frames["gnss_x"][0] == pytest.approx(100.0 - 1.4 * math.cos(math.radians(30)))
    assert all(frames["has_expert"]) and frames["frame"] == list(range(12))
    # A second open reads the files: same tables.
    again = CorpusIndex.load(corpus_copy)
    assert again is not None and again.clips.equals(index.clips.replace_schema_metadata(again.clips.schema.metadata))


def test_incremental_update(corpus_copy: Path) -> None:
    CorpusIndex.build(corpus_copy)
    _, report = CorpusIndex.build(corpus_copy)
    assert report.scanned == [] and report.reused == 2
    new = ClipName.parse("ControlLoss_Town11_Route3_Weather11")
    write_synthetic_clip(corpus_copy, SyntheticClipSpec(new, frames=3, dense=False, radar=False, expert=False))
    index, report = CorpusIndex.build(corpus_copy)
    assert report.scanned == [str(new)] and report.reused == 2 and index.num_frames == 21
    time.sleep(0.01)
    (corpus_copy / str(CLIP_A) / "camera" / "rgb_front" / "00011.jpg").unlink()  # a changed clip is rescanned
    shutil.rmtree(corpus_copy / str(CLIP_B))  # a vanished clip is dropped
    index, report = CorpusIndex.build(corpus_copy)
    assert report.scanned == [str(CLIP_A)] and report.removed == [str(CLIP_B)] and report.reused == 1
    assert _rows(index)[str(CLIP_A)]["n_rgb_front"] == 11


def test_archives_are_hashed_and_listed(corpus_copy: Path) -> None:
    info_a = pack_clip(corpus_copy / str(CLIP_A))
    info_b = pack_clip(corpus_copy / str(CLIP_B))
    shutil.rmtree(corpus_copy / str(CLIP_B))  # B exists only as its archive
    index, _ = CorpusIndex.build(corpus_copy)
    a, b = _rows(index)[str(CLIP_A)], _rows(index)[str(CLIP_B)]
    archive_a = corpus_copy / f"{CLIP_A}.tar.gz"
    assert a["sha256"] == hashlib.sha256(archive_a.read_bytes()).hexdigest() == info_a.sha256
    assert a["archive_size"] == info_a.size and a["path"] == str(CLIP_A)
    # The archive-only clip is listed from its members in the same pass that hashes it.
    assert b["path"] == "" and b["sha256"] == info_b.sha256 and b["n_frames"] == 6 and b["n_depth_npz_front"] == 6
    frames = index.frames.slice(b["frame_start"], b["n_frames"]).to_pydict()
    assert frames["ego_x"][0] == pytest.approx(100.0)
    # The dataset serves folders only: the archive-only clip is left out with a warning.
    assert ClipDataset(corpus_copy, cameras=()).clip_names == [str(CLIP_A)]


def test_opening_a_1000_clip_corpus_takes_under_a_second(tmp_path: Path) -> None:
    fabricate_index(tmp_path, n_clips=1000, n_frames=200)
    t0 = time.perf_counter()
    ds = ClipDataset(tmp_path)
    seconds = time.perf_counter() - t0
    print(f"\nopened 1000 clips × 200 frames (index only) in {seconds * 1000:.0f} ms")
    assert len(ds) == 200_000 and len(ds.clip_names) == 1000
    assert seconds < 1.0
    # Waypoints come from the index poses, so a frame's targets need no other annotation.
    assert ds.frame_key(199_999) == (ds.clip_names[-1], 199)


def test_collection_side_folders_are_not_clips(tmp_path):
    # b2d-collect keeps failed runs under failed/<clip> (with --keep-failed): they must not enter the corpus.
    from b2d_data.loaders.clip_scan import discover_clips

    spec = dict(frames=1, dense=False, lidar_points=5, radar=False, expert=False, cameras=("front",))
    write_synthetic_clip(tmp_path, SyntheticClipSpec(ClipName.parse("Accident_Town03_Route1_Weather0"), **spec))
    write_synthetic_clip(tmp_path / "failed",
                         SyntheticClipSpec(ClipName.parse("Accident_Town03_Route2_Weather0"), **spec))  # fmt: skip
    assert [str(c.name) for c in discover_clips(tmp_path)] == ["Accident_Town03_Route1_Weather0"]


def test_a_stray_file_does_not_stretch_the_clip(corpus_copy: Path, caplog: pytest.LogCaptureFixture) -> None:
    clip = corpus_copy / str(CLIP_A)  # frames 0..11 in every modality folder
    shutil.copy(clip / "anno" / "00011.json.gz", clip / "anno" / "99999.json.gz")
    shutil.copy(clip / "camera" / "rgb_front" / "00003.jpg", clip / "camera" / "rgb_front" / "00500.jpg")
    with caplog.at_level("WARNING", logger="b2d_data.loaders.clip_scan"):
        index, report = CorpusIndex.build(corpus_copy)
    a = _rows(index)[str(CLIP_A)]
    # Clip A keeps its 12 frames (the old index filled 0..99999: 100 000 frames), clip B its 6.
    assert (a["n_frames"], a["first_frame"], a["n_anno"], a["n_rgb_front"]) == (12, 0, 12, 12)
    assert index.num_frames == 18 and not report.errors
    assert len(ClipDataset(corpus_copy, clips=[str(CLIP_A)], cameras=())) == 12
    stray = [r.getMessage() for r in caplog.records if "stray" in r.getMessage()]
    assert stray == [
        f"{clip}: 2 stray file(s) outside the frames 0..11 that most modality folders hold are ignored: "
        "anno/99999.json.gz, camera/rgb_front/00500.jpg"
    ]


def test_a_stray_member_does_not_stretch_an_archived_clip(corpus_copy: Path) -> None:
    clip = corpus_copy / str(CLIP_B)  # 6 frames
    shutil.copy(clip / "anno" / "00005.json.gz", clip / "anno" / "99999.json.gz")
    pack_clip(clip)
    shutil.rmtree(clip)
    index, _ = CorpusIndex.build(corpus_copy)
    b = _rows(index)[str(CLIP_B)]
    assert b["path"] == "" and (b["n_frames"], b["n_anno"]) == (6, 6)


def test_missing_files_inside_the_clip_keep_its_length_and_are_reported(
    corpus_copy: Path, caplog: pytest.LogCaptureFixture
) -> None:
    clip = corpus_copy / str(CLIP_A)
    (clip / "lidar" / "00011.laz").unlink()  # the last frame lacks one file: it is still the clip's last frame
    for path in (clip / "camera").glob("*/00004.*"):  # frame 4 lacks every camera file
        path.unlink()
    with caplog.at_level("WARNING", logger="b2d_data.loaders.clip_scan"):
        index, _ = CorpusIndex.build(corpus_copy)
    a = _rows(index)[str(CLIP_A)]
    assert (a["n_frames"], a["n_lidar"], a["n_rgb_front"], a["n_anno"]) == (12, 11, 11, 12)
    # 6 RGB (no top-down camera here) + 6 × (depth, semantic, instance) = 24 camera files of frame 4, plus the LAZ
    # of frame 11: 25 files, the first 5 in sorted order shown.
    (missing,) = [r.getMessage() for r in caplog.records if "missing within" in r.getMessage()]
    assert missing.startswith(f"{clip}: 25 file(s) missing within frames 0..11: camera/depth_back/00004.png, ")
    assert missing.endswith("(+20 more)")


def test_archive_scan_does_not_read_an_oversized_annotation_member(
    corpus_copy: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    from b2d_data.codecs import anno_json

    clip = corpus_copy / str(CLIP_B)  # 6 frames
    assert min(p.stat().st_size for p in (clip / "anno").iterdir()) > 100
    pack_clip(clip)
    shutil.rmtree(clip)
    monkeypatch.setattr(anno_json, "MAX_ANNO_BYTES", 100)  # below every annotation member's size
    with caplog.at_level("WARNING", logger="b2d_data.loaders.clip_scan"):
        index, _ = CorpusIndex.build(corpus_copy)
    b = _rows(index)[str(CLIP_B)]
    frames = index.frames.slice(b["frame_start"], b["n_frames"]).to_pydict()
    # The members are still listed as frames, but none was read for its pose.
    assert b["n_frames"] == 6 and all(math.isnan(x) for x in frames["ego_x"])
    skipped = [r.getMessage() for r in caplog.records if "more than an annotation may be" in r.getMessage()]
    assert len(skipped) == 6 and f"{CLIP_B}/anno/00000.json.gz is " in skipped[0]
