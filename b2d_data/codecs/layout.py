"""Where each file of a clip lives (format.md §1.3): ``<clip>/anno/NNNNN.json.gz``, ``camera/rgb_front/…``."""

from __future__ import annotations

import os
from pathlib import Path

from b2d_data.codecs.expert_npz import expert_file_name

ANNO_DIR = "anno"
CAMERA_DIR = "camera"
LIDAR_DIR = "lidar"
RADAR_DIR = "radar"
EXPERT_DIR = "expert_assessment"
MAPS_DIR = "maps"  # sibling of the clips: ``<root>/maps/<Town>_HD_map.npz``

#: Image kinds and their file suffix inside ``camera/<kind>_<cam>/``.
IMAGE_SUFFIX: dict[str, str] = {"rgb": ".jpg", "depth": ".png", "semantic": ".png", "instance": ".png"}


def frame_stem(index: int) -> str:
    """Five-digit zero-padded frame name (``00042``)."""
    if index < 0:
        raise ValueError(f"frame index must be ≥ 0, got {index}")
    return f"{index:05d}"


def camera_dir(clip_dir: str | os.PathLike[str], kind: str, cam: str) -> Path:
    """``<clip>/camera/<kind>_<cam>`` for kind ∈ rgb, depth, semantic, instance and a camera folder name."""
    if kind not in IMAGE_SUFFIX:
        raise ValueError(f"unknown image kind {kind!r}; expected one of {sorted(IMAGE_SUFFIX)}")
    return Path(clip_dir) / CAMERA_DIR / f"{kind}_{cam}"


def anno_path(clip_dir: str | os.PathLike[str], index: int) -> Path:
    """``<clip>/anno/NNNNN.json.gz``."""
    return Path(clip_dir) / ANNO_DIR / f"{frame_stem(index)}.json.gz"


def image_path(clip_dir: str | os.PathLike[str], kind: str, cam: str, index: int) -> Path:
    """``<clip>/camera/<kind>_<cam>/NNNNN.jpg|png``."""
    return camera_dir(clip_dir, kind, cam) / f"{frame_stem(index)}{IMAGE_SUFFIX[kind]}"


def depth_npz_path(clip_dir: str | os.PathLike[str], cam: str, index: int) -> Path:
    """``<clip>/camera/depth_<cam>/NNNNN.npz`` (float depth, format v0.0.4)."""
    return camera_dir(clip_dir, "depth", cam) / f"{frame_stem(index)}.npz"


def lidar_path(clip_dir: str | os.PathLike[str], index: int) -> Path:
    """``<clip>/lidar/NNNNN.laz``."""
    return Path(clip_dir) / LIDAR_DIR / f"{frame_stem(index)}.laz"


def radar_path(clip_dir: str | os.PathLike[str], index: int) -> Path:
    """``<clip>/radar/NNNNN.h5``."""
    return Path(clip_dir) / RADAR_DIR / f"{frame_stem(index)}.h5"


def expert_path(clip_dir: str | os.PathLike[str], index: int) -> Path:
    """``<clip>/expert_assessment/<index − 1>.npz`` holding frame ``index``'s vector (frame 0 → ``-0001.npz``)."""
    return Path(clip_dir) / EXPERT_DIR / expert_file_name(index)


def hdmap_path(root: str | os.PathLike[str], town: str) -> Path:
    """``<root>/maps/<Town>_HD_map.npz``, where Bench2DriveZoo looks for a town's HD map."""
    return Path(root) / MAPS_DIR / f"{town}_HD_map.npz"
