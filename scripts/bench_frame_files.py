"""Time the file system side of writing frames: small synthetic frames (all 29 files of a Bench2Drive frame at 64×36)
through ``ClipWriter(workers=0)``, so that encoding is cheap and the open / write / close calls dominate.

    python scripts/bench_frame_files.py [--frames 200] [--out DIR]
    strace -f -c -e trace=%file,%desc python scripts/bench_frame_files.py --frames 50   # system calls per frame

Compare two checkouts on the same machine and folder (``PYTHONPATH=<checkout>``): the files are the same.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "writers"))

from conftest import make_record  # noqa: E402  (the writer tests' synthetic frames)

from b2d_data.format.names import ClipName  # noqa: E402
from b2d_data.writers import ClipWriter  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--out", type=Path, default=None, help="folder to write in (default: a temporary one)")
    args = parser.parse_args()
    records = [make_record(i) for i in range(min(args.frames, 10))]
    with tempfile.TemporaryDirectory(dir=args.out) as root:
        writer = ClipWriter(Path(root), ClipName.parse("Accident_Town03_Route156_Weather0"), workers=0)
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(args.frames):
            record = records[i % len(records)]
            record.index = i
            writer.write(record)
        writer.close()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    n = max(args.frames, 1)
    print(f"{args.frames} frames: {1e3 * wall / n:.2f} ms wall, {1e3 * cpu / n:.2f} ms CPU per frame (writer, "
          f"encoding included)")  # fmt: skip


if __name__ == "__main__":
    main()
