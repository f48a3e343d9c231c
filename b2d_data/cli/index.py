"""``b2d-index ROOT``: build or update the parquet index of a corpus (``<ROOT>/.b2d_index``)."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from b2d_data.loaders.index import CorpusIndex, index_dir


def main(argv: list[str] | None = None) -> int:
    """Index the clips (folders and ``.tar.gz`` archives) under ROOT; only new or changed clips are scanned."""
    parser = argparse.ArgumentParser(prog="b2d-index", description=__doc__)
    parser.add_argument("root", type=Path, help="corpus root holding <clip>/ folders and/or <clip>.tar.gz archives")
    parser.add_argument("--rebuild", action="store_true", help="scan every clip again instead of updating")
    parser.add_argument("--workers", type=int, default=0, help="scan clips in this many processes (default 0: inline)")
    parser.add_argument("--no-hash", action="store_true", help="do not compute sha256 of archives next to clip folders")
    parser.add_argument("-v", "--verbose", action="store_true", help="log every step")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    if not args.root.is_dir():
        print(f"b2d-index: {args.root}: not a folder", file=sys.stderr)
        return 2
    index, report = CorpusIndex.build(
        args.root, update=not args.rebuild, workers=args.workers, hash_archives=not args.no_hash
    )
    print(
        f"{index_dir(args.root)}: {index.num_clips} clips, {index.num_frames} frames "
        f"({len(report.scanned)} scanned, {report.reused} unchanged, {len(report.removed)} removed) "
        f"in {report.seconds:.1f} s"
    )
    for name in report.removed:
        print(f"  removed: {name}")
    for name, error in sorted(report.errors.items()):
        print(f"  ERROR {name}: {error}", file=sys.stderr)
    return 1 if report.errors else 0


if __name__ == "__main__":
    sys.exit(main())
