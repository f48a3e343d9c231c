"""Clips shaped like the released Bench2Drive ones load, quirks included."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest

from b2d_data import ClipDataset
from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import read_anno, write_anno
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.version import FORMAT_FILE
from b2d_data.loaders import CorpusIndex

from .conftest import CLIP_A, CLIP_B

TRUNCATED = "Accident_Town03_Route1_Weathe"


@pytest.fixture()
def released(corpus_copy: Path) -> Path:
    """Clip A mutated to the released quirks, under ``v1/`` as Bench2DriveZoo lays clips out."""
    v1 = corpus_copy / "v1"
    v1.mkdir()
    clip = v1 / TRUNCATED  # the Base list's truncated "Weathe" name
    shutil.move(corpus_copy / str(CLIP_A), clip)
    (clip / FORMAT_FILE).unlink()  # released clips have no b2d_format.json
    shutil.rmtree(clip / "radar")  # some released clips have no radar
    for frame, key, value in ((2, "theta", float("nan")), (3, "speed", None)):
        path = layout.anno_path(clip, frame)
        anno = read_anno(path)
        anno[key] = value
        write_anno(path, anno)
    return corpus_copy


def test_released_clip_loads_with_its_quirks(released: Path) -> None:
    clip = released / "v1" / TRUNCATED
    assert (clip / "expert_assessment" / "-0001.npz").is_file()  # frame 0's expert vector
    ds = ClipDataset(released, clips=[TRUNCATED], radar=True, expert=True, cameras=("front",))
    assert len(ds) == 12
    s2, s3, s0 = ds[2], ds[3], ds[0]
    assert s0["weather_id"] == -1 and s0["clip"] == TRUNCATED  # weather unknown
    # NaN theta counts as π (heading due south): ISO yaw = π/2 − π = −π/2.
    assert float(s2["ego_compass_yaw"]) == pytest.approx(-math.pi / 2)
    # Null speed counts as 0.
    assert float(s3["ego_speed"]) == 0.0
    # No radar folder: empty radar, flagged.
    assert s0["radar"].shape == (0, 3) and not bool(s0["radar_valid"])
    # Frame 0 reads -0001.npz (value 0.5 + 0, action 0); frame 3 reads 00002.npz (value 3.5, action 3).
    assert float(s0["expert_value"]) == pytest.approx(0.5) and int(s0["expert_action"]) == 0
    assert float(s3["expert_value"]) == pytest.approx(3.5) and int(s3["expert_action"]) == 3
    # Action 3 decodes through Think2Drive's table to throttle 0.7, steer −0.2, no brake, forward.
    assert s3["expert_control"].tolist() == pytest.approx([0.7, -0.2, 0.0, 0.0])
    # The exact pose is unaffected by the NaN compass: waypoints still run straight ahead.
    assert s2["future_waypoints"][0] == pytest.approx([2.5, 0.0], abs=1e-4)


def test_index_records_released_layout(released: Path) -> None:
    index, _ = CorpusIndex.build(released)
    rows = {r["name"]: r for r in index.clips.to_pylist()}
    row = rows[TRUNCATED]
    assert row["path"] == f"v1/{TRUNCATED}" and row["weather_id"] == -1 and row["format_version"] == ""
    assert row["n_radar"] == 0 and row["n_expert"] == 12 and row["n_anno"] == 12
    assert rows[str(CLIP_B)]["format_version"] == "bench2drive-v0.0.4"
    frames = index.frames.slice(row["frame_start"], row["n_frames"]).to_pydict()
    assert math.isnan(frames["theta"][2]) and frames["speed"][3] == 0.0


def test_released_expert_feature_is_not_reshaped(released: Path) -> None:
    # A released clip's feature is Think2Drive's latent: the BEV reshape must refuse it, naming the missing record.
    ds = ClipDataset(released, clips=[TRUNCATED], expert_bev=True, cameras=(), lidar=False)
    with pytest.raises(B2DFormatError, match=FORMAT_FILE):
        ds[0]
