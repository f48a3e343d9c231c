"""Time writing full-resolution Bench2Drive frames: each codec alone, ClipWriter with workers=0 and with a pool.

A frame is 6 × 1600×900 (RGB JPEG q20 + uint8 depth PNG + semantic PNG + instance PNG), a 1600×900 top-down
JPEG, a 60k-point LiDAR LAZ, 5 radars (h5), a gzip JSON annotation with 50 boxes and an expert vector.
Images are synthetic (smooth shading plus noise), so byte sizes are indicative only.

    python scripts/bench_writer.py --frames 16 --workers 1 2
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from b2d_data.codecs import (
    write_anno,
    write_depth_png,
    write_expert,
    write_instance_png,
    write_jpeg,
    write_laz,
    write_radar,
    write_semantic_png,
)
from b2d_data.format.anno_schema import DYNAMIC_VEHICLE_KEYS, EGO_KEYS, TOP_LEVEL_KEYS
from b2d_data.format.record import CameraFrame, FrameRecord
from b2d_data.format.rig import ALL_CAMERAS, RADARS_V0
from b2d_data.writers import ClipWriter

H, W = 900, 1600


def synthetic_camera(rng: np.random.Generator, dense: bool) -> CameraFrame:
    """A road-like camera frame: sky, ground plane with distance-dependent depth, boxes, mild texture noise."""
    v, u = np.mgrid[0:H, 0:W].astype(np.float32)
    ground = v > H / 2
    depth = np.where(ground, 1.6 * 1142.5 / np.maximum(v - H / 2 + 0.5, 0.5), 1000.0).astype(np.float32)
    semantic = np.where(ground, 1, 11).astype(np.uint8)
    instance = np.zeros((H, W), np.uint16)
    rgb = np.empty((H, W, 3), np.uint8)
    rgb[..., 0] = np.where(ground, 90, 150)
    rgb[..., 1] = np.where(ground, 90, 190)
    rgb[..., 2] = np.where(ground, 95, 235)
    for k in range(25):
        x0, y0 = int(rng.integers(0, W - 240)), int(rng.integers(300, 700))
        w, h = int(rng.integers(60, 240)), int(rng.integers(40, 180))
        depth[y0 : y0 + h, x0 : x0 + w] = rng.uniform(4.0, 90.0)
        semantic[y0 : y0 + h, x0 : x0 + w] = rng.choice([14, 15, 12, 3, 9])
        instance[y0 : y0 + h, x0 : x0 + w] = 100 + k
        rgb[y0 : y0 + h, x0 : x0 + w] = rng.integers(0, 256, 3)
    noise = rng.normal(0.0, 6.0, (H, W, 1)).astype(np.float32)
    rgb = np.clip(rgb + noise, 0, 255).astype(np.uint8)
    rgb = cv2.GaussianBlur(rgb, (3, 3), 0)
    if not dense:
        return CameraFrame(rgb=rgb)
    depth += rng.normal(0.0, 0.05, depth.shape).astype(np.float32)
    return CameraFrame(rgb=rgb, depth=depth, semantic=semantic, instance=instance)


def synthetic_anno(rng: np.random.Generator, boxes: int = 50) -> dict:
    """An annotation in Bench2Drive key order with ``boxes`` vehicles (4×4 matrices, 8 corners each)."""

    def box(keys: tuple[str, ...], cls: str) -> dict:
        values: dict[str, object] = {k: float(rng.uniform(-100, 100)) for k in keys}
        values.update({
            "class": cls, "state": "dynamic", "id": str(rng.integers(1000)), "type_id": "vehicle.audi.a2",
            "semantic_tags": [14], "extent": [2.4, 1.0, 0.8], "bbx_loc": [0.0, 0.0, 0.8],
            "world_cord": rng.uniform(-100, 100, (8, 3)).tolist(), "location": rng.uniform(-100, 100, 3).tolist(),
            "rotation": rng.uniform(-180, 180, 3).tolist(), "center": rng.uniform(-100, 100, 3).tolist(),
            "world2vehicle": rng.uniform(-1, 1, (4, 4)).tolist(), "world2ego": rng.uniform(-1, 1, (4, 4)).tolist(),
        })  # fmt: skip
        return {k: values[k] for k in keys}

    boxes_list = [box(EGO_KEYS, "ego_vehicle")] + [box(DYNAMIC_VEHICLE_KEYS, "vehicle") for _ in range(boxes - 1)]
    top: dict[str, object] = {k: float(rng.uniform(-100, 100)) for k in TOP_LEVEL_KEYS}
    top.update(weather={"cloudiness": 5.0, "precipitation": 0.0}, acceleration=[0.1, 0.0, 9.8],
               angular_velocity=[0.0, 0.0, 0.01], sensors={}, reverse=False, should_brake=False,
               only_ap_brake=False, bounding_boxes=boxes_list)  # fmt: skip
    return {k: top[k] for k in TOP_LEVEL_KEYS}


def synthetic_record(seed: int = 0) -> FrameRecord:
    """One full-resolution frame."""
    rng = np.random.default_rng(seed)
    cameras = {spec.folder: synthetic_camera(rng, spec.has_dense_labels) for spec in ALL_CAMERAS}
    az = rng.uniform(-np.pi, np.pi, 60_000)
    rng_m = rng.uniform(2.0, 85.0, 60_000)
    lidar = np.stack([rng_m * np.cos(az), rng_m * np.sin(az), rng.uniform(-0.2, 3.0, 60_000)], axis=1)
    radar = {r.dataset: rng.uniform([0, -0.2, -0.26, -20], [100, 0.2, 0.26, 20], (int(rng.integers(5, 40)), 4))
             for r in RADARS_V0}  # fmt: skip
    return FrameRecord(0, synthetic_anno(rng), cameras, lidar, radar, rng.normal(size=1538).astype(np.float32))


def median_ms(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``fn`` in ms after one warm-up call."""
    fn()  # warm-up
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples) * 1e3


def codec_timings(record: FrameRecord, out: Path, repeats: int) -> dict[str, float]:
    """Median ms per frame for each codec (encode + write), summed over the cameras that use it."""
    out.mkdir(parents=True, exist_ok=True)
    cams = record.cameras
    dense = [f for f in cams.values() if f.depth is not None]

    def each(fn: Callable[[int, CameraFrame], object]) -> Callable[[], object]:
        return lambda: [fn(i, f) for i, f in enumerate(dense)]

    return {
        "rgb jpeg x7": median_ms(lambda: [write_jpeg(out / f"{c}.jpg", f.rgb) for c, f in cams.items()], repeats),
        "depth png x6": median_ms(each(lambda i, f: write_depth_png(out / f"d{i}.png", f.depth)), repeats),
        "semantic png x6": median_ms(each(lambda i, f: write_semantic_png(out / f"s{i}.png", f.semantic)), repeats),
        "instance png x6": median_ms(
            each(lambda i, f: write_instance_png(out / f"i{i}.png", f.semantic, f.instance)), repeats
        ),
        "lidar laz 60k": median_ms(lambda: write_laz(out / "l.laz", record.lidar), repeats),
        "radar h5": median_ms(lambda: write_radar(out / "r.h5", record.radar), repeats),
        "anno json.gz": median_ms(lambda: write_anno(out / "a.json.gz", record.anno), repeats),
        "expert npz": median_ms(lambda: write_expert(out / "e.npz", record.expert_assessment), repeats),
    }  # fmt: skip


def _cpu_seconds(pids: list[int]) -> float:
    """User + system CPU time of processes, from /proc (Linux; 0 elsewhere)."""
    total = 0.0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return total


def time_writer(record: FrameRecord, root: Path, frames: int, workers: int, name: str) -> tuple[float, float, float]:
    """(wall, writer-process CPU, pool-process CPU) in ms per frame for ``frames`` frames, waiting for the last one.

    Wall time depends on what else runs on the machine; the CPU split shows how much encoding left the writer.
    """
    writer = ClipWriter(root, name, workers=workers)
    # One frame outside the timed region: the pool start-up is paid once per writer, not per frame.
    writer.write(dataclasses.replace(record, index=0))
    writer.flush()
    pool = getattr(writer, "_executor", None)
    pids = list(getattr(pool, "_processes", None) or {})  # the pool's worker processes (CPython internals)
    t0, c0, w0 = time.perf_counter(), time.process_time(), _cpu_seconds(pids)
    for i in range(1, frames + 1):
        writer.write(dataclasses.replace(record, index=i))
    writer.flush()
    wall, cpu, pool_cpu = time.perf_counter() - t0, time.process_time() - c0, _cpu_seconds(pids) - w0
    writer.close()
    return wall * 1e3 / frames, cpu * 1e3 / frames, pool_cpu * 1e3 / frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=8, help="frames per timed clip")
    parser.add_argument("--workers", type=int, nargs="+", default=[2], help="pool sizes to compare with workers=0")
    parser.add_argument("--repeats", type=int, default=5, help="repeats per codec timing")
    parser.add_argument("--out", type=Path, default=None, help="scratch folder (default: a temporary one)")
    args = parser.parse_args()
    cv2.setNumThreads(1)  # the same single OpenCV thread the pool workers use
    record = synthetic_record()
    with tempfile.TemporaryDirectory(dir=args.out) as scratch:
        root = Path(scratch)
        codecs = codec_timings(record, root / "codecs", args.repeats)
        sync_ms, sync_cpu, _ = time_writer(record, root, args.frames, 0, "Accident_Town03_Route1_Weather0")
        pools = {n: time_writer(record, root, args.frames, n, f"Accident_Town03_Route{10 + n}_Weather0")
                 for n in args.workers}  # fmt: skip
        size = sum(p.stat().st_size for p in (root / "Accident_Town03_Route1_Weather0").rglob("*") if p.is_file())
    total = sum(codecs.values())
    print(f"{'codec (encode + write)':<24}{'ms/frame':>10}")
    for key, ms in codecs.items():
        print(f"{key:<24}{ms:>10.1f}")
    print(f"{'sum of codecs':<24}{total:>10.1f}")
    print(f"ClipWriter workers=0: {sync_ms:6.1f} ms/frame wall, writer CPU {sync_cpu:6.1f} ms "
          f"({sync_ms / total:.2f}x the codec sum)")
    for n, (pool_ms, writer_cpu, pool_cpu) in pools.items():
        print(f"ClipWriter workers={n}: {pool_ms:6.1f} ms/frame wall, writer CPU {writer_cpu:6.1f} ms, pool CPU "
              f"{pool_cpu:6.1f} ms; speed-up vs workers=0: {sync_ms / pool_ms:.2f}x wall, "
              f"{sync_cpu / writer_cpu:.1f}x less CPU in the writer")
    print(f"clip size: {size / (args.frames * 1e6):.2f} MB/frame (synthetic content)")


if __name__ == "__main__":
    main()
