"""b2d-index, b2d-split, b2d-verify and b2d-view --mcap, run through their ``main(argv)``."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from b2d_data.cli import index as index_cli
from b2d_data.cli import split as split_cli
from b2d_data.cli import verify as verify_cli
from b2d_data.cli import view as view_cli
from b2d_data.format.names import ClipName
from b2d_data.loaders.synthetic import SyntheticClipSpec, fabricate_index, write_synthetic_clip
from b2d_data.splits import SplitManifest

SMALL = dict(frames=2, dense=False, lidar_points=20, radar=False, expert=False, cameras=("front",))


@pytest.fixture(scope="module")
def small_corpus(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("cli_corpus")
    for name in ("Accident_Town03_Route1_Weather0", "ControlLoss_Town11_Route2_Weather11"):
        write_synthetic_clip(root, SyntheticClipSpec(ClipName.parse(name), **SMALL))
    return root


def test_b2d_index(small_corpus: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = tmp_path / "c"
    shutil.copytree(small_corpus, root)
    assert index_cli.main([str(root)]) == 0
    assert "2 clips, 4 frames (2 scanned, 0 unchanged" in capsys.readouterr().out
    assert index_cli.main([str(root)]) == 0
    assert "(0 scanned, 2 unchanged" in capsys.readouterr().out
    shutil.copytree(root / "Accident_Town03_Route1_Weather0", root / "Accident_Town03_Route1_Wether0")
    assert index_cli.main([str(root)]) == 1  # a malformed clip name is an error naming the folder
    assert "Accident_Town03_Route1_Wether0" in capsys.readouterr().err
    assert index_cli.main([str(tmp_path / "nowhere")]) == 2


def test_b2d_split_import_and_generate(b2d_data_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "base.json"
    base_list = b2d_data_dir / "bench2drive_base_1000.json"
    val_list = b2d_data_dir / "bench2drive_base_train_val_split.json"
    rc = split_cli.main(["import", str(base_list), "--val", str(val_list), "--name", "base", "--out", str(out)])
    assert rc == 0
    manifest = SplitManifest.load(out)
    assert (len(manifest.train), len(manifest.val)) == (950, 50)
    corpus = tmp_path / "corpus"
    fabricate_index(corpus, n_clips=120, n_frames=2)
    for kind, n in (("mini", 10), ("base", 120)):
        path = tmp_path / f"{kind}.json"
        assert split_cli.main(["generate", str(corpus), "--split", kind, "--seed", "7", "--out", str(path)]) == 0
        generated = SplitManifest.load(path)
        assert len(generated.entries()) == n and generated.seed == 7
    # 120 clips < 1000: val keeps one clip per scenario (44 here) rather than 50 of 120.
    assert len(SplitManifest.load(tmp_path / "base.json").val) == 44
    assert split_cli.main(["import", str(tmp_path / "missing.json"), "--out", str(out)]) == 2


def test_b2d_verify_names_every_mismatch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    archives = tmp_path / "archives"
    archives.mkdir()
    listing = {}
    for i, name in enumerate(["A_Town01_Route1_Weather0", "B_Town01_Route2_Weather0", "C_Town01_Route3_Weather0",
                              "D_Town01_Route4_Weather0"]):  # fmt: skip
        data = bytes([i]) * (1000 + i)
        listing[f"{name}.tar.gz"] = {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data)}
        if name.startswith("A"):
            (archives / f"{name}.tar.gz").write_bytes(data)  # good
        elif name.startswith("B"):
            (archives / f"{name}.tar.gz").write_bytes(data[:-1])  # wrong size
        elif name.startswith("C"):
            (archives / "v1").mkdir()
            (archives / "v1" / f"{name}.tar.gz").write_bytes(bytes([9]) * len(data))  # right size, wrong hash, nested
        # D is missing
    list_file = tmp_path / "list.json"
    list_file.write_text(json.dumps(listing, indent=4))
    assert verify_cli.main([str(archives), "--list", str(list_file), "--no-progress"]) == 1
    out = capsys.readouterr().out
    assert "SIZE     B_Town01_Route2_Weather0.tar.gz" in out
    assert "SHA256   C_Town01_Route3_Weather0.tar.gz" in out
    assert "MISSING  D_Town01_Route4_Weather0.tar.gz" in out
    assert "A_Town01" not in out.split("archives match")[0]
    assert "1 of 4 archives match" in out
    good = tmp_path / "good.json"
    good.write_text(json.dumps({k: v for k, v in listing.items() if k.startswith("A")}))
    assert verify_cli.main([str(archives), "--list", str(good), "--no-progress"]) == 0


def test_b2d_view_mcap(small_corpus: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("foxglove")
    clip = small_corpus / "Accident_Town03_Route1_Weather0"
    out = tmp_path / "clip.mcap"
    assert view_cli.main(["--mcap", str(clip), str(out), "--cameras", "front"]) == 0
    assert out.is_file() and "2 frames" in capsys.readouterr().out
    assert view_cli.main(["--mcap", str(clip), str(out)]) == 1  # exists, no --overwrite
    assert view_cli.main(["--mcap", str(tmp_path), str(tmp_path / "x.mcap")]) == 1  # not a clip
    with pytest.raises(SystemExit):
        view_cli.main([])
