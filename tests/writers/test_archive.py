"""Clip archives, sha256/size, official split-list format, safe extraction."""

from __future__ import annotations

import hashlib
import io
import json
import tarfile
from collections.abc import Callable
from pathlib import Path

import pytest

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.record import FrameRecord
from b2d_data.writers import (
    ArchiveInfo,
    ClipWriter,
    extract_archive,
    pack_clip,
    read_split_list,
    split_list_text,
    verify_archive,
    write_split_list,
)

CLIP = "Accident_Town03_Route156_Weather0"


@pytest.fixture
def clip_dir(tmp_path: Path, record_factory: Callable[..., FrameRecord]) -> Path:
    with ClipWriter(tmp_path / "v1", CLIP) as writer:
        for i in range(2):
            writer.write(record_factory(i))
    return tmp_path / "v1" / CLIP


def files_of(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_pack_hash_and_extract(tmp_path: Path, clip_dir: Path) -> None:
    info = pack_clip(clip_dir, tmp_path / "archives")
    archive = tmp_path / "archives" / f"{CLIP}.tar.gz"
    data = archive.read_bytes()
    assert info == ArchiveInfo(f"{CLIP}.tar.gz", hashlib.sha256(data).hexdigest(), len(data))
    with tarfile.open(archive) as tar:
        names = tar.getnames()
        assert all(n == CLIP or n.startswith(f"{CLIP}/") for n in names)
        assert f"{CLIP}/anno/00000.json.gz" in names and f"{CLIP}/expert_assessment/-0001.npz" in names
        assert {m.uid for m in tar.getmembers()} == {0}
    assert pack_clip(clip_dir, tmp_path / "again").sha256 == info.sha256  # same folder, same bytes
    verify_archive(archive, info)
    out = extract_archive(archive, tmp_path / "extracted")
    assert out == tmp_path / "extracted" / CLIP
    assert files_of(out) == files_of(clip_dir)
    assert [p.name for p in (tmp_path / "extracted").iterdir()] == [CLIP]
    with pytest.raises(FileExistsError):
        extract_archive(archive, tmp_path / "extracted")


def test_verify_detects_mismatch(tmp_path: Path, clip_dir: Path) -> None:
    info = pack_clip(clip_dir, tmp_path)
    archive = tmp_path / info.name
    with pytest.raises(B2DFormatError, match="size"):
        verify_archive(archive, ArchiveInfo(info.name, info.sha256, info.size + 1))
    with pytest.raises(B2DFormatError, match="sha256"):
        verify_archive(archive, ArchiveInfo(info.name, "0" * 64, info.size))


def test_split_list_matches_the_official_files(b2d_data_dir: Path) -> None:
    for name in ("bench2drive_mini_10.json", "bench2drive_base_1000.json"):
        path = b2d_data_dir / name
        entries = read_split_list(path)
        # Re-serialising the official list gives its exact bytes: same indent, key order, no final newline.
        assert split_list_text(entries) == path.read_text(encoding="utf-8")
    mini = read_split_list(b2d_data_dir / "bench2drive_mini_10.json")
    assert len(mini) == 10
    first = list(mini)[:2]
    assert first == ["AccidentTwoWays_Town12_Route1444_Weather0.tar.gz", "Accident_Town03_Route156_Weather0.tar.gz"]
    assert mini[first[1]].size == 264497958
    assert len(read_split_list(b2d_data_dir / "bench2drive_full+sup_13638.json")) == 13638


def test_split_list_round_trip(tmp_path: Path) -> None:
    entries = [
        ArchiveInfo("Accident_Town03_Route156_Weather0.tar.gz", "a" * 64, 10),
        ArchiveInfo("AccidentTwoWays_Town12_Route1444_Weather0.tar.gz", "b" * 64, 20),
    ]
    path = write_split_list(tmp_path / "mine.json", entries)
    text = path.read_text()
    assert text == (
        "{\n"
        '    "AccidentTwoWays_Town12_Route1444_Weather0.tar.gz": {\n'
        f'        "sha256": "{"b" * 64}",\n'
        '        "size": 20\n'
        "    },\n"
        '    "Accident_Town03_Route156_Weather0.tar.gz": {\n'
        f'        "sha256": "{"a" * 64}",\n'
        '        "size": 10\n'
        "    }\n"
        "}"
    )
    assert list(read_split_list(path).values()) == sorted(entries, key=lambda e: e.name)
    (tmp_path / "bad.json").write_text(json.dumps({"x.tar.gz": {"sha256": "abc", "size": 1}}))
    with pytest.raises(B2DFormatError, match="bad.json"):
        read_split_list(tmp_path / "bad.json")


def make_tar(path: Path, members: list[tuple[tarfile.TarInfo, bytes | None]]) -> Path:
    with tarfile.open(path, "w:gz") as tar:
        for info, data in members:
            if data is not None:
                info.size = len(data)
            tar.addfile(info, io.BytesIO(data) if data is not None else None)
    return path


def file_member(name: str) -> tuple[tarfile.TarInfo, bytes]:
    return tarfile.TarInfo(name), b"payload"


def test_unsafe_archives_are_refused(tmp_path: Path) -> None:
    link = tarfile.TarInfo(f"{CLIP}/anno")
    link.type, link.linkname = tarfile.SYMTYPE, "/etc"
    cases = {
        "dotdot": [file_member(f"{CLIP}/../../evil.txt")],
        "absolute": [file_member("/tmp/evil.txt")],
        "symlink": [(link, None)],
        "mixed": [file_member(f"{CLIP}/anno/00000.json.gz"), file_member("other/file")],
    }
    for case, members in cases.items():
        (tmp_path / case).mkdir()
        archive = make_tar(tmp_path / case / f"{CLIP}.tar.gz", members)
        with pytest.raises(B2DFormatError, match=rf"{CLIP}\.tar\.gz"):
            extract_archive(archive, tmp_path / case / "out")
        assert not (tmp_path / case / "out" / CLIP).exists()
        assert not any(p.name.startswith(".") for p in (tmp_path / case / "out").iterdir())
    assert not (tmp_path / "evil.txt").exists()


def test_archive_without_root_folder_and_truncated(tmp_path: Path) -> None:
    archive = make_tar(tmp_path / f"{CLIP}.tar.gz", [file_member("anno/00000.json.gz")])
    out = extract_archive(archive, tmp_path / "out")
    assert (out / "anno/00000.json.gz").read_bytes() == b"payload"
    data = archive.read_bytes()
    cut = tmp_path / "cut" / f"{CLIP}.tar.gz"
    cut.parent.mkdir()
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(B2DFormatError, match="truncated"):
        extract_archive(cut, tmp_path / "cut_out")
