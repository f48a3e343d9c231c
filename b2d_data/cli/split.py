"""``b2d-split``: generate mini / base / full split manifests from a corpus, or import the official lists."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from b2d_data import splits


def _corpus_entries(root: Path) -> list[splits.SplitEntry]:
    from b2d_data.loaders.index import open_index

    clips = open_index(root).clips.to_pylist()
    bad = [c["name"] for c in clips if c["error"]]
    if bad:
        logging.getLogger(__name__).warning("leaving out %d clips that failed to index: %s", len(bad), bad[:5])
    return [
        splits.SplitEntry(c["name"], c["sha256"] or None, c["archive_size"] if c["archive_size"] >= 0 else None)
        for c in clips
        if not c["error"]
    ]


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``b2d-split generate`` and ``b2d-split import``."""
    parser = argparse.ArgumentParser(prog="b2d-split", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    gen = sub.add_parser("generate", help="generate a split manifest from an indexed corpus")
    gen.add_argument("root", type=Path, help="corpus root (indexed with b2d-index; indexed now if not)")
    gen.add_argument("--split", choices=("mini", "base", "full"), required=True)
    gen.add_argument("--seed", type=int, default=0)
    gen.add_argument("--out", type=Path, required=True, help="manifest JSON to write")
    imp = sub.add_parser("import", help="turn an official Bench2Drive file list into a manifest")
    imp.add_argument("list", type=Path, help="bench2drive_{mini_10,base_1000,full+sup_13638}.json")
    imp.add_argument("--val", type=Path, help="baseline val list (bench2drive_base_train_val_split.json)")
    imp.add_argument("--name", help="manifest name (default: the list's file stem)")
    imp.add_argument("--out", type=Path, required=True, help="manifest JSON to write")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(message)s")
    try:
        if args.command == "generate":
            manifest = splits.generate(args.split, _corpus_entries(args.root), seed=args.seed)
        else:
            manifest = splits.import_official(args.list, args.val, args.name)
    except (FileNotFoundError, ValueError) as exc:
        print(f"b2d-split: {exc}", file=sys.stderr)
        return 2
    manifest.save(args.out)
    print(f"{args.out}: {manifest.name}: {len(manifest.train)} train + {len(manifest.val)} val clips")
    return 0


if __name__ == "__main__":
    sys.exit(main())
