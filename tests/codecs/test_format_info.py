"""b2d_format.json and the clip layout helpers."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from b2d_data.codecs import layout
from b2d_data.codecs.format_info import CameraInfo, ClipFormatInfo, read_format_info, write_format_info
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.version import FORMAT_FILE, FormatVersion


def test_format_info_round_trip(tmp_path: Path) -> None:
    info = ClipFormatInfo(FormatVersion.V004, "0.1.0", "Accident_Town03_Route156_Weather0", 12,
                          cameras={"front": CameraInfo(64, 36, True)}, float_depth=True, extra={"seed": 3},
                          expert_assessment=True,
                          expert_feature={"name": "b2d-bev-raster", "shape": [6, 16, 16]})  # fmt: skip
    path = write_format_info(tmp_path, info)
    assert path.name == FORMAT_FILE
    assert json.loads(path.read_text())["format_version"] == "bench2drive-v0.0.4"
    assert read_format_info(tmp_path) == info
    assert read_format_info(tmp_path / "released_clip") is None
    path.write_text('{"format_version": "v9"}')
    with pytest.raises(B2DFormatError, match=FORMAT_FILE):
        read_format_info(tmp_path)


def test_layout_paths() -> None:
    clip = Path("C")
    assert layout.anno_path(clip, 3) == Path("C/anno/00003.json.gz")
    assert layout.image_path(clip, "rgb", "top_down", 12) == Path("C/camera/rgb_top_down/00012.jpg")
    assert layout.image_path(clip, "instance", "back_left", 0) == Path("C/camera/instance_back_left/00000.png")
    assert layout.depth_npz_path(clip, "front", 1) == Path("C/camera/depth_front/00001.npz")
    assert layout.lidar_path(clip, 5) == Path("C/lidar/00005.laz")
    assert layout.radar_path(clip, 5) == Path("C/radar/00005.h5")
    assert layout.expert_path(clip, 0) == Path("C/expert_assessment/-0001.npz")
    assert layout.hdmap_path("data", "Town10HD") == Path("data/maps/Town10HD_HD_map.npz")
