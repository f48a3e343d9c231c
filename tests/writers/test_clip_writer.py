"""ClipWriter: exact layout, decoded content, atomicity, crash clean-up, frame order, HD map, process pool."""

from __future__ import annotations

import gzip
import json
import os
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from b2d_data.codecs import (
    read_anno,
    read_depth_npz,
    read_depth_png,
    read_expert,
    read_format_info,
    read_instance_png,
    read_jpeg,
    read_laz,
    read_radar,
    read_semantic_png,
)
from b2d_data.codecs.anno_json import AnnoSchemaError
from b2d_data.codecs.depth import depth_to_png_pixels
from b2d_data.codecs.jpeg import jpeg_planes
from b2d_data.format.names import ClipName
from b2d_data.format.record import FrameRecord
from b2d_data.format.version import FormatVersion
from b2d_data.writers import ClipWriter, ClipWriterError, remove_stale_temporaries

CLIP = ClipName.parse("Accident_Town03_Route156_Weather0")
SURROUND = ("front", "front_left", "front_right", "back", "back_left", "back_right")

RecordFactory = Callable[..., FrameRecord]


def expected_files(frames: int, *, float_depth: bool = False) -> set[str]:
    """The relative paths a full clip of ``frames`` frames holds (format.md §1.3), worked out from the spec."""
    files = {"b2d_format.json"}
    for i in range(frames):
        n = f"{i:05d}"
        files |= {f"anno/{n}.json.gz", f"lidar/{n}.laz", f"radar/{n}.h5", f"camera/rgb_top_down/{n}.jpg"}
        files.add(f"expert_assessment/{i - 1:05}.npz")
        for cam in SURROUND:
            files |= {f"camera/rgb_{cam}/{n}.jpg", f"camera/depth_{cam}/{n}.png",
                      f"camera/semantic_{cam}/{n}.png", f"camera/instance_{cam}/{n}.png"}  # fmt: skip
            if float_depth:
                files.add(f"camera/depth_{cam}/{n}.npz")
    return files


def listing(clip_dir: Path) -> set[str]:
    return {p.relative_to(clip_dir).as_posix() for p in clip_dir.rglob("*") if p.is_file()}


def write_clip(root: Path, records: list[FrameRecord], **kwargs: object) -> Path:
    with ClipWriter(root, CLIP, **kwargs) as writer:  # type: ignore[arg-type]
        for record in records:
            writer.write(record)
    return root / str(CLIP)


def assert_clip_matches(clip_dir: Path, records: list[FrameRecord]) -> None:
    """Decode every file and compare with the records, within each codec's precision."""
    for rec in records:
        i = rec.index
        anno = read_anno(clip_dir / f"anno/{i:05d}.json.gz")
        assert json.dumps(anno, indent=4) == json.dumps(rec.anno, indent=4)  # NaN-safe equality, same key order
        for cam, frame in rec.cameras.items():
            rgb = read_jpeg(clip_dir / f"camera/rgb_{cam}/{i:05d}.jpg")
            assert rgb.shape == frame.rgb.shape
            assert np.abs(rgb.astype(int) - frame.rgb).mean() < 6  # q20 on smooth ramps
            if frame.depth is None:
                assert not (clip_dir / f"camera/depth_{cam}").exists()
                continue
            depth = read_depth_png(clip_dir / f"camera/depth_{cam}/{i:05d}.png")
            assert np.array_equal(depth, depth_to_png_pixels(frame.depth).astype(np.float32))
            assert np.abs(depth - np.clip(frame.depth, 0, 255)).max() <= 0.5
            assert np.array_equal(read_semantic_png(clip_dir / f"camera/semantic_{cam}/{i:05d}.png"), frame.semantic)
            tags, ids = read_instance_png(clip_dir / f"camera/instance_{cam}/{i:05d}.png")
            assert np.array_equal(tags, frame.semantic) and np.array_equal(ids, frame.instance)
        assert np.abs(read_laz(clip_dir / f"lidar/{i:05d}.laz") - rec.lidar).max() <= 0.0005 + 1e-9
        radar = read_radar(clip_dir / f"radar/{i:05d}.h5")
        for name, arr in (rec.radar or {}).items():
            assert np.array_equal(radar[name], arr.astype(np.float16).astype(np.float32))
        # The −1 shift: frame i's vector is in file i − 1.
        assert np.array_equal(read_expert(clip_dir / f"expert_assessment/{i - 1:05}.npz"), rec.expert_assessment)


def test_synchronous_clip_layout_and_content(tmp_path: Path, record_factory: RecordFactory) -> None:
    records = [record_factory(i) for i in range(3)]
    clip_dir = write_clip(tmp_path, records)
    assert listing(clip_dir) == expected_files(3)
    assert sorted(p.name for p in tmp_path.iterdir()) == [str(CLIP)]  # no temporary left
    assert_clip_matches(clip_dir, records)
    info = read_format_info(clip_dir)
    assert info is not None
    assert info.format_version is FormatVersion.V0 and info.frames == 3 and info.clip == str(CLIP)
    assert info.cameras["front"].width == 64 and info.cameras["front"].height == 36
    assert info.cameras["front"].dense_labels and not info.cameras["top_down"].dense_labels
    assert not info.float_depth and info.lidar and info.radar and info.expert_assessment


def test_v004_adds_float_depth(tmp_path: Path, record_factory: RecordFactory) -> None:
    records = [record_factory(i) for i in range(2)]
    clip_dir = write_clip(tmp_path, records, format_version=FormatVersion.V004)
    assert listing(clip_dir) == expected_files(2, float_depth=True)
    depth = read_depth_npz(clip_dir / "camera/depth_back/00001.npz")
    assert np.array_equal(depth, records[1].cameras["back"].depth)
    assert read_format_info(clip_dir).float_depth  # type: ignore[union-attr]


def test_uint8_depth_writes_the_same_depth_pngs(tmp_path: Path, record_factory: RecordFactory) -> None:
    # The renderer can hand over depth already rounded to the PNG's uint8 metres: same files as from float depth.
    records = [record_factory(i) for i in range(2)]
    rounded = [record_factory(i) for i in range(2)]
    for rec in rounded:
        for frame in rec.cameras.values():
            if frame.depth is not None:
                frame.depth = depth_to_png_pixels(frame.depth)
    a, b = write_clip(tmp_path / "float", records), write_clip(tmp_path / "uint8", rounded)
    pngs = sorted(p.relative_to(a) for p in a.glob("camera/depth_*/*.png"))
    assert len(pngs) == 2 * len(SURROUND)
    for rel in pngs:
        assert (a / rel).read_bytes() == (b / rel).read_bytes()
    with ClipWriter(tmp_path / "v004", CLIP, format_version=FormatVersion.V004) as writer:
        with pytest.raises(ValueError, match="front: .*uint8"):  # no float depth to put in the npz files
            writer.write(rounded[0])
        writer.abort()


def test_pool_writes_the_same_content(tmp_path: Path, record_factory: RecordFactory) -> None:
    records = [record_factory(i, seed=7) for i in range(4)]
    sync_dir = write_clip(tmp_path / "sync", records)
    originals = [(r.cameras["front"].rgb.copy(), r.lidar.copy()) for r in records]  # type: ignore[union-attr]
    with ClipWriter(tmp_path / "pool", CLIP, workers=2, max_in_flight=2) as writer:
        for record in records:
            writer.write(record)
            assert len(writer._in_flight) <= 2  # back-pressure: never more frames queued than allowed
            # The caller may reuse its buffers as soon as write() returns.
            record.cameras["front"].rgb[...] = 0
            record.lidar[...] = 1e3  # type: ignore[index]
    pool_dir = tmp_path / "pool" / str(CLIP)
    for record, (rgb, lidar) in zip(records, originals):
        record.cameras["front"].rgb[...] = rgb
        record.lidar[...] = lidar  # type: ignore[index]
    assert listing(pool_dir) == listing(sync_dir) == expected_files(4)
    assert_clip_matches(pool_dir, records)
    for rel in sorted(listing(sync_dir) - {"b2d_format.json"}):
        a, b = (sync_dir / rel).read_bytes(), (pool_dir / rel).read_bytes()
        if rel.endswith(".json.gz"):  # the gzip header holds the write time
            a, b = gzip.decompress(a), gzip.decompress(b)
        assert a == b, rel


def test_pool_error_names_the_frame_and_leaves_nothing(tmp_path: Path, record_factory: RecordFactory) -> None:
    bad = record_factory(1)
    bad.lidar = np.array([[0.0, 0.0, 0.0], [3e6, 0.0, 0.0]])  # 3000 km: does not fit LAS's int32 at 1 mm
    with pytest.raises(ClipWriterError, match=rf"{CLIP}: frame 1 \(annotation/lidar/radar/expert\).*Overflow"):
        with ClipWriter(tmp_path, CLIP, workers=1) as writer:
            writer.write(record_factory(0))
            writer.write(bad)
            writer.write(record_factory(2))
    assert list(tmp_path.iterdir()) == []


def test_exception_inside_with_leaves_no_clip(tmp_path: Path, record_factory: RecordFactory) -> None:
    with pytest.raises(RuntimeError, match="simulator crashed"):
        with ClipWriter(tmp_path, CLIP) as writer:
            writer.write(record_factory(0))
            raise RuntimeError("simulator crashed")
    assert list(tmp_path.iterdir()) == []
    writer = ClipWriter(tmp_path, CLIP)
    writer.write(record_factory(0))
    writer.abort()
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ClipWriterError, match="aborted"):
        writer.write(record_factory(1))


def test_crashed_writer_is_cleaned_up(tmp_path: Path) -> None:
    conftest = Path(__file__).with_name("conftest.py")
    script = textwrap.dedent(f"""
        import importlib.util, os
        spec = importlib.util.spec_from_file_location("synth", {str(conftest)!r})
        synth = importlib.util.module_from_spec(spec); spec.loader.exec_module(synth)
        from b2d_data.writers import ClipWriter
        writer = ClipWriter({str(tmp_path)!r}, {str(CLIP)!r})
        writer.write(synth.make_record(0))
        os._exit(3)  # killed before close(): no clean-up code runs
    """)
    assert subprocess.run([sys.executable, "-c", script], timeout=60).returncode == 3
    leftovers = [p.name for p in tmp_path.iterdir()]
    assert len(leftovers) == 1 and leftovers[0].startswith(f".{CLIP}.tmp-")
    live = ClipWriter(tmp_path, "Accident_Town03_Route157_Weather0")  # a running writer must survive
    removed = remove_stale_temporaries(tmp_path)
    assert [p.name for p in removed] == leftovers
    assert [p.name for p in tmp_path.iterdir()] == [live.temp_dir.name]
    live.abort()


def test_frame_order_and_layout_checks(tmp_path: Path, record_factory: RecordFactory) -> None:
    with ClipWriter(tmp_path, CLIP) as writer:
        with pytest.raises(ValueError, match=rf"{CLIP} frame 1: .*consecutive.*expected 0"):
            writer.write(record_factory(1))
        writer.write(record_factory(0))
        with pytest.raises(ValueError, match="frame 2"):
            writer.write(record_factory(2))
        with pytest.raises(ValueError, match="radar"):
            writer.write(record_factory(1, radar=False))
        writer.write(record_factory(1))  # still usable after refused frames
    assert read_format_info(tmp_path / str(CLIP)).frames == 2  # type: ignore[union-attr]


def test_strict_annotations(tmp_path: Path, record_factory: RecordFactory) -> None:
    record = record_factory(0)
    record.anno = {"y": record.anno.pop("y"), **record.anno}
    with ClipWriter(tmp_path, CLIP) as writer:
        with pytest.raises(AnnoSchemaError, match=rf"{CLIP} frame 0: .*key order"):
            writer.write(record)
        writer.write(record_factory(0))
    lenient = tmp_path / "lenient"
    write_clip(lenient, [record], strict_anno=False)
    assert list(read_anno(lenient / str(CLIP) / "anno/00000.json.gz"))[0] == "y"


def test_refuses_to_overwrite(tmp_path: Path, record_factory: RecordFactory) -> None:
    write_clip(tmp_path, [record_factory(0)])
    with pytest.raises(FileExistsError, match=str(CLIP)):
        ClipWriter(tmp_path, CLIP)
    clip_dir = write_clip(tmp_path, [record_factory(0), record_factory(1)], overwrite=True)
    assert read_format_info(clip_dir).frames == 2  # type: ignore[union-attr]
    assert sorted(p.name for p in tmp_path.iterdir()) == [str(CLIP)]


def test_hdmap_is_installed_once(tmp_path: Path, record_factory: RecordFactory) -> None:
    source = tmp_path / "src" / "Town03_HD_map.npz"
    source.parent.mkdir()
    np.savez_compressed(source, arr=np.arange(10))
    root = tmp_path / "v1"
    write_clip(root, [record_factory(0)], hdmap=source)
    installed = root / "maps" / "Town03_HD_map.npz"
    assert installed.read_bytes() == source.read_bytes()
    stamp = installed.stat().st_mtime_ns
    other = ClipName.parse("Accident_Town03_Route157_Weather0")
    with ClipWriter(root, other, hdmap=source) as writer:
        writer.write(record_factory(0))
    assert installed.stat().st_mtime_ns == stamp
    assert sorted(p.name for p in (root / "maps").iterdir()) == ["Town03_HD_map.npz"]
    with pytest.raises(FileNotFoundError):
        ClipWriter(root, "Accident_Town03_Route158_Weather0", hdmap=tmp_path / "missing.npz")


def test_invalid_records_are_refused_before_writing(tmp_path: Path, record_factory: RecordFactory) -> None:
    with ClipWriter(tmp_path, CLIP) as writer:
        record = record_factory(0)
        record.cameras["top_down"].depth = np.zeros((36, 64), np.float32)
        with pytest.raises(ValueError, match="top_down"):
            writer.write(record)
        record = record_factory(0)
        record.cameras["front"].semantic = None
        with pytest.raises(ValueError, match="together"):
            writer.write(record)
        record = record_factory(0)
        record.cameras["front"].rgb = record.cameras["front"].rgb.astype(np.float32)
        with pytest.raises(ValueError, match="uint8"):
            writer.write(record)
        writer.write(record_factory(0))
    assert read_anno(tmp_path / str(CLIP) / "anno/00000.json.gz")["theta"] == 1.25
    assert not any(name.startswith(".") for name in os.listdir(tmp_path))


def test_an_unreaped_dead_writer_counts_as_dead():
    # A child that exited but was not waited for is a zombie: kill(pid, 0) still succeeds, yet no writer runs.
    import time

    from b2d_data.writers.clip_writer import _pid_alive

    pid = os.fork()
    if pid == 0:
        os._exit(0)
    try:
        for _ in range(100):  # wait until the child has become a zombie
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            if state == "Z":
                break
            time.sleep(0.01)
        assert not _pid_alive(pid)
        assert _pid_alive(os.getpid())
    finally:
        os.waitpid(pid, 0)


def test_expert_feature_is_recorded_only_with_expert_files(tmp_path: Path, record_factory: RecordFactory) -> None:
    record = {"name": "b2d-bev-raster", "version": 1, "shape": [6, 16, 16]}
    with_expert = write_clip(tmp_path / "a", [record_factory(0)], expert_feature=record)
    info = read_format_info(with_expert)
    assert info is not None and info.expert_assessment and info.expert_feature == record
    without = write_clip(tmp_path / "b", [record_factory(0, expert=False)], expert_feature=record)
    info = read_format_info(without)
    assert info is not None and not info.expert_assessment and info.expert_feature is None
    with pytest.raises(TypeError, match="JSON-serialisable"):
        ClipWriter(tmp_path / "c", CLIP, expert_feature={"shape": np.zeros(3)})


def test_jpeg_planes_write_the_images_in_sync_and_pool(tmp_path: Path, record_factory: RecordFactory) -> None:
    # The renderer may hand colour over as the JPEG's planes (no rgb): same files, sync or through the pool.
    records = [record_factory(i, seed=3) for i in range(2)]
    as_planes = [record_factory(i, seed=3) for i in range(2)]
    for rec in as_planes:
        for frame in rec.cameras.values():
            frame.jpeg_planes, frame.rgb = jpeg_planes(frame.rgb), None
    rgb_dir = write_clip(tmp_path / "rgb", records)
    for name, kwargs in (("sync", {}), ("pool", {"workers": 2})):
        planes_dir = write_clip(tmp_path / name, as_planes, **kwargs)
        assert listing(planes_dir) == listing(rgb_dir)
        for rel in sorted(p.relative_to(rgb_dir) for p in rgb_dir.glob("camera/rgb_*/*.jpg")):
            a, b = read_jpeg(rgb_dir / rel).astype(int), read_jpeg(planes_dir / rel).astype(int)
            assert np.abs(a - b).mean() < 1.0, rel  # codec noise between two libjpeg-turbo builds
        assert_clip_matches(planes_dir, records)


def test_a_camera_needs_rgb_or_planes(tmp_path: Path, record_factory: RecordFactory) -> None:
    with ClipWriter(tmp_path, CLIP) as writer:
        record = record_factory(0)
        record.cameras["front"].rgb = None
        with pytest.raises(ValueError, match="front: give either rgb or jpeg_planes"):
            writer.write(record)
        record = record_factory(0)
        y, cb, _ = jpeg_planes(record.cameras["back"].rgb)
        record.cameras["back"].jpeg_planes, record.cameras["back"].rgb = (y, cb, cb[:-1]), None
        with pytest.raises(ValueError, match="back: 4:2:0 planes"):
            writer.write(record)
        writer.abort()
