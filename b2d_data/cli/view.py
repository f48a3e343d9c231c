"""``b2d-view``: look at a town or a clip.

- ``b2d-view --town Town10HD --out montage.png [--at X,Y[,YAW]] [--weather ID]``: render the sensor rig at a place
  of a town (a generated preset, a CARLA town name or an .xodr file) as a PNG montage;
- ``b2d-view --clip CLIP --frame N --out montage.png``: the same montage for a frame of a clip;
- ``b2d-view --mcap CLIP OUT.mcap``: export a clip to MCAP for Foxglove Studio.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import cv2
import numpy as np

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipNameError


def _place(text: str | None):
    """``X,Y`` or ``X,Y,YAW`` (CARLA world metres / degrees) → Location or Transform."""
    from b2d_data.format.transform import Location, Rotation, Transform

    if text is None:
        return None
    parts = [float(v) for v in text.split(",")]
    if len(parts) not in (2, 3):
        raise ValueError(f"--at wants X,Y or X,Y,YAW, got {text!r}")
    location = Location(parts[0], parts[1], 0.0)
    return Transform(location, Rotation(yaw=parts[2])) if len(parts) == 3 else location


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return int(w), int(h)


def town_montage(args: argparse.Namespace) -> np.ndarray:
    """Render the rig at a place of a town."""
    from b2d_data.format.weather import preset
    from b2d_data.maps.towns import resolve_town
    from b2d_data.viz.montage import render_town_montage

    town = resolve_town(args.town)
    kwargs = {"weather": preset(args.weather)} if args.weather is not None else {}
    return render_town_montage(town, _place(args.at), seed=args.seed, resolution=_size(args.size), **kwargs)


def clip_montage(clip: Path, frame: int) -> np.ndarray:
    """The montage of one recorded frame: its JPEGs, LiDAR and annotated boxes."""
    from b2d_data.codecs import layout
    from b2d_data.codecs.anno_json import read_anno
    from b2d_data.codecs.jpeg import read_jpeg
    from b2d_data.codecs.laz import read_laz
    from b2d_data.format.rig import CAMERAS, TOP_DOWN
    from b2d_data.viz.montage import boxes_from_anno, calibrations_from_anno, make_montage

    anno = read_anno(layout.anno_path(clip, frame))
    images = {}
    for cam in CAMERAS:
        path = layout.image_path(clip, "rgb", cam.folder, frame)
        if path.is_file():
            images[cam.folder] = read_jpeg(path)
    top_path = layout.image_path(clip, "rgb", TOP_DOWN.folder, frame)
    top = read_jpeg(top_path) if top_path.is_file() else None
    lidar_path = layout.lidar_path(clip, frame)
    lidar = read_laz(lidar_path, dtype=np.float32) if lidar_path.is_file() else np.zeros((0, 3), np.float32)
    if not images:
        raise B2DFormatError(clip, f"frame {frame} has no camera image")
    return make_montage(images, top, lidar, boxes_from_anno(anno), calibrations_from_anno(anno))


def _write_png(path: Path, rgb: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)):
        raise OSError(f"cannot write {path}")


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``b2d-view``."""
    parser = argparse.ArgumentParser(prog="b2d-view", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--town", help="a generated preset (all, urban, Town100 …), a CARLA town name or an .xodr file")
    mode.add_argument("--clip", type=Path, help="a clip folder")
    mode.add_argument("--mcap", nargs=2, type=Path, metavar=("CLIP", "OUT.mcap"),
                      help="export a clip folder to MCAP (Foxglove schemas; needs b2d-data[viz])")  # fmt: skip
    parser.add_argument("--out", type=Path, help="montage PNG to write (--town / --clip)")
    parser.add_argument("--at", help="town mode: X,Y[,YAW] in CARLA world metres/degrees (default: a busy spot)")
    parser.add_argument("--weather", type=int, help="town mode: weather preset id (default: clear noon)")
    parser.add_argument("--seed", type=int, default=0, help="town mode: seed of the placed actors")
    parser.add_argument("--size", default="800x450", help="town mode: camera resolution WxH (default 800x450)")
    parser.add_argument("--frame", type=int, default=0, help="clip mode: frame index")
    parser.add_argument("--cameras", nargs="+", help="mcap mode: camera folders to export (default: the six)")
    parser.add_argument("--no-lidar", action="store_true", help="mcap mode: leave the LiDAR point cloud out")
    parser.add_argument("--no-boxes", action="store_true", help="mcap mode: leave the 3D boxes out")
    parser.add_argument("--overwrite", action="store_true", help="mcap mode: replace OUT.mcap if it exists")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(message)s")
    if args.mcap is None and args.out is None:
        parser.error("--town and --clip need --out PNG")
    try:
        if args.mcap is not None:
            from b2d_data.writers.mcap_export import SURROUND, export_mcap

            clip, out = args.mcap
            report = export_mcap(
                clip, out, cameras=tuple(args.cameras) if args.cameras else SURROUND, lidar=not args.no_lidar,
                boxes=not args.no_boxes, overwrite=args.overwrite,
            )  # fmt: skip
            print(f"{report.path}: {report.frames} frames, {len(report.messages)} channels")
            return 0
        image = town_montage(args) if args.town else clip_montage(args.clip, args.frame)
        _write_png(args.out, image)
    except (B2DFormatError, ClipNameError, FileExistsError, KeyError, ImportError, ValueError, OSError) as exc:
        print(f"b2d-view: {exc}", file=sys.stderr)
        return 1
    print(f"{args.out}: {image.shape[1]}×{image.shape[0]} montage")
    return 0


if __name__ == "__main__":
    sys.exit(main())
