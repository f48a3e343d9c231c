"""``b2d-view``: look at a clip; ``--mcap CLIP OUT.mcap`` exports it for Foxglove Studio."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipNameError


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``b2d-view``."""
    parser = argparse.ArgumentParser(prog="b2d-view", description=__doc__)
    parser.add_argument("--mcap", nargs=2, type=Path, metavar=("CLIP", "OUT.mcap"),
                        help="export a clip folder to MCAP (Foxglove schemas; needs b2d-data[viz])")  # fmt: skip
    parser.add_argument("--cameras", nargs="+", help="camera folders to export (default: the six surround cameras)")
    parser.add_argument("--no-lidar", action="store_true", help="leave the LiDAR point cloud out")
    parser.add_argument("--no-boxes", action="store_true", help="leave the 3D boxes out")
    parser.add_argument("--overwrite", action="store_true", help="replace OUT.mcap if it exists")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(message)s")
    if args.mcap is None:
        parser.error("choose a mode: --mcap CLIP OUT.mcap")
    from b2d_data.writers.mcap_export import SURROUND, export_mcap

    clip, out = args.mcap
    try:
        report = export_mcap(
            clip, out, cameras=tuple(args.cameras) if args.cameras else SURROUND, lidar=not args.no_lidar,
            boxes=not args.no_boxes, overwrite=args.overwrite,
        )  # fmt: skip
    except (B2DFormatError, ClipNameError, FileExistsError, KeyError, ImportError) as exc:
        print(f"b2d-view: {exc}", file=sys.stderr)
        return 1
    print(f"{report.path}: {report.frames} frames, {len(report.messages)} channels")
    return 0


if __name__ == "__main__":
    sys.exit(main())
