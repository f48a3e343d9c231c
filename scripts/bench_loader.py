"""Loader throughput: full samples (6 cameras + LiDAR + boxes) per second vs the JPEG-decode bound, same workers.

Builds (or takes, with ``--root``) a corpus of full-resolution synthetic clips written by ``ClipWriter``
(1600×900 JPEG q20 with camera-like texture, 60k-point LAZ, annotations with ~45 boxes), then, alternating runs,
measures samples/s of ``ClipDataset`` through a ``DataLoader`` and of a dataset that only decodes the same six
JPEGs per frame with the same workers, batch size and collate. Also times opening a fabricated
1000-clip × 200-frame index and reports the workers' memory before/after the runs.

    python scripts/bench_loader.py [--clips 2] [--frames 20] [--workers 2] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from torch.utils.data import DataLoader, Dataset

from b2d_data import ClipDataset
from b2d_data.codecs import layout
from b2d_data.codecs.jpeg import read_jpeg
from b2d_data.format.names import ClipName
from b2d_data.loaders import collate, worker_init_fn
from b2d_data.loaders.synthetic import SURROUND, SyntheticClipSpec, fabricate_index, write_synthetic_clip

TARGET = 0.7


class JpegOnly(Dataset):
    """The six JPEGs of each frame of a ClipDataset, decoded and stacked: the decode-only bound."""

    def __init__(self, ds: ClipDataset) -> None:
        self.paths = []
        for i in range(len(ds)):
            clip, frame = ds.frame_key(i)
            clip_dir = ds.root / ds._clip_path[ds._clip_name.tolist().index(clip.encode())].decode()
            self.paths.append([str(layout.image_path(clip_dir, "rgb", cam, frame)) for cam in SURROUND])

    def __len__(self) -> int:
        return len(self.paths)

    def __getitem__(self, i: int) -> dict:
        return {"images": np.stack([read_jpeg(p) for p in self.paths[i]])}


def _children() -> list[int]:
    pids: list[int] = []
    for task in Path(f"/proc/{os.getpid()}/task").iterdir():
        pids += [int(p) for p in (task / "children").read_text().split()]
    return pids


def _cpu_seconds() -> float:
    """CPU time (user + system) used so far by this process and its live children (the DataLoader workers)."""
    tick = os.sysconf("SC_CLK_TCK")
    total = sum(os.times()[:2])
    for pid in _children():
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        total += (int(fields[11]) + int(fields[12])) / tick  # utime, stime
    return total


def _children_rss_mb() -> list[float]:
    """Resident memory (MB) of this process's children (the DataLoader workers)."""
    out = []
    for pid in _children():
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                out.append(int(line.split()[1]) / 1024)
    return out


def _rate(loader: DataLoader) -> tuple[float, float]:
    """(samples per wall-clock second, CPU seconds per sample) of one pass over the loader."""
    t0, c0 = time.perf_counter(), _cpu_seconds()
    n = sum(batch["batch_size"] for batch in loader)
    return n / (time.perf_counter() - t0), (_cpu_seconds() - c0) / n


def build_corpus(root: Path, clips: int, frames: int) -> None:
    names = ["Accident_Town03_Route156_Weather0", "ParkedObstacle_Town10HD_Route371_Weather7",
             "ControlLoss_Town11_Route401_Weather11", "HardBreakRoute_Town01_Route30_Weather3"]  # fmt: skip
    for i in range(clips):
        spec = SyntheticClipSpec(
            ClipName.parse(names[i % len(names)].replace("_Weather", f"{i}_Weather")), frames=frames, width=1600,
            height=900, dense=False, lidar_points=60_000, radar=True, expert=True, texture=40.0, traffic=40, seed=i,
        )  # fmt: skip
        write_synthetic_clip(root, spec, workers=2)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", type=Path, help="existing corpus to read (default: build a synthetic one)")
    parser.add_argument("--clips", type=int, default=2)
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--batch-size", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3, help="alternating runs of each loader (median reported)")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="b2d_bench_") as tmp:
        root = args.root
        if root is None:
            root = Path(tmp) / "corpus"
            t0 = time.perf_counter()
            build_corpus(root, args.clips, args.frames)
            seconds = time.perf_counter() - t0
            print(f"built {args.clips} clips × {args.frames} frames (1600×900 ×6, 60k points) in {seconds:.1f} s")
        full = ClipDataset(root, cameras=SURROUND, lidar=True, boxes=True)
        jpeg = JpegOnly(full)
        kw = dict(
            batch_size=args.batch_size, num_workers=args.workers, collate_fn=collate, worker_init_fn=worker_init_fn,
            persistent_workers=args.workers > 0,
        )  # fmt: skip
        loaders = {"full": DataLoader(full, **kw), "jpeg": DataLoader(jpeg, **kw)}
        rates: dict[str, list[float]] = {"full": [], "jpeg": []}
        cpu: dict[str, list[float]] = {"full": [], "jpeg": []}
        for loader in loaders.values():  # warm-up: start the workers, fill the page cache
            _rate(loader)
        rss_start = _children_rss_mb()
        for _ in range(args.repeats):
            for name in ("jpeg", "full"):
                rate, cpu_per_sample = _rate(loaders[name])
                rates[name].append(rate)
                cpu[name].append(cpu_per_sample)
        rss_end = _children_rss_mb()
        sample = full[0]
        full_rate, bound = statistics.median(rates["full"]), statistics.median(rates["jpeg"])
        ratio = full_rate / bound
        print(
            f"frames: {len(full)}; sample: 6 × {sample['images'].shape[1:]} images, {len(sample['lidar'])} LiDAR "
            f"points, {len(sample['boxes'])} boxes; DataLoader workers={args.workers} batch={args.batch_size}"
        )
        print(f"full samples/s      : {full_rate:.2f}  (runs: {', '.join(f'{r:.2f}' for r in rates['full'])})")
        print(f"JPEG-decode bound/s : {bound:.2f}  (runs: {', '.join(f'{r:.2f}' for r in rates['jpeg'])})")
        print(f"ratio               : {ratio:.2f}  (target ≥ {TARGET}: {'PASS' if ratio >= TARGET else 'FAIL'})")
        cpu_full, cpu_jpeg = statistics.median(cpu["full"]), statistics.median(cpu["jpeg"])
        load = os.getloadavg()[0]
        print(
            f"CPU ms/sample       : full {cpu_full * 1000:.0f}, JPEG-only {cpu_jpeg * 1000:.0f}; "
            f"ratio {cpu_jpeg / cpu_full:.2f} (all processes: the throughput ratio on {args.workers} otherwise idle "
            f"cores; load average now {load:.1f})"
        )
        if rss_start and rss_end:
            print(
                f"worker RSS MB       : {' '.join(f'{r:.0f}' for r in rss_start)} after warm-up → "
                f"{' '.join(f'{r:.0f}' for r in rss_end)} after {args.repeats} more epochs of each loader"
            )

        idx_root = Path(tmp) / "fabricated"
        fabricate_index(idx_root, n_clips=1000, n_frames=200)
        t0 = time.perf_counter()
        ds = ClipDataset(idx_root)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        ClipDataset(idx_root)
        warm = time.perf_counter() - t0
        print(
            f"open 1000 clips × 200 frames (index only): {cold * 1000:.0f} ms first, {warm * 1000:.0f} ms again "
            f"({len(ds)} frames; target < 1 s: {'PASS' if cold < 1.0 else 'FAIL'})"
        )
    return 0 if ratio >= TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
