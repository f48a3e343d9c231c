"""MCAP export: read back with the ``mcap`` reader — channels, Foxglove schemas, counts and key values."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from b2d_data.codecs import layout
from b2d_data.format.names import ClipName
from b2d_data.loaders.synthetic import SyntheticClipSpec, synthetic_record, write_synthetic_clip
from b2d_data.writers.mcap_export import export_mcap

pytest.importorskip("foxglove")

FRAMES = 4
SPEC = SyntheticClipSpec(ClipName.parse("ParkingExit_Town05_Route7_Weather1"), frames=FRAMES, dense=False,
                         lidar_points=50, radar=False, expert=False, ego_yaw_deg=0.0)  # fmt: skip
CAMS = ("front", "front_left", "front_right", "back", "back_left", "back_right")


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("mcap")
    clip = write_synthetic_clip(root, SPEC)
    out = root / "clip.mcap"
    report = export_mcap(clip, out)
    assert report.frames == FRAMES
    return clip, out


def _read(path: Path) -> tuple[dict[str, str], dict[str, int], dict[str, list[bytes]]]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        counts = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
        data: dict[str, list[bytes]] = {}
        for _, channel, message in reader.iter_messages():
            data.setdefault(channel.topic, []).append(message.data)
    return schemas, counts, data


def test_channels_schemas_and_counts(exported: tuple[Path, Path]) -> None:
    _, out = exported
    schemas, counts, _ = _read(out)
    expected = {f"/camera/{c}/image": "foxglove.CompressedImage" for c in CAMS}
    expected |= {f"/camera/{c}/calibration": "foxglove.CameraCalibration" for c in CAMS}
    expected |= {"/lidar": "foxglove.PointCloud", "/boxes": "foxglove.SceneUpdate", "/tf": "foxglove.FrameTransforms"}
    assert schemas == expected
    assert counts == {topic: FRAMES for topic in expected}  # one message per frame on every channel


def test_message_contents(exported: tuple[Path, Path]) -> None:
    clip, out = exported
    _, _, data = _read(out)
    # JPEG bytes go in untouched (no re-encoding).
    for frame in range(FRAMES):
        assert layout.image_path(clip, "rgb", "front", frame).read_bytes() in data["/camera/front/image"][frame]
    # The point cloud holds the LAZ points as little-endian float32 x, y, z with y negated (right-handed ego):
    # 50 points × 12 bytes, and the first one equals the written point within the 1 mm LAZ step.
    stored = np.frombuffer(data["/lidar"][2][-600:], dtype="<f4").reshape(50, 3)
    assert np.abs(stored - synthetic_record(SPEC, 2).lidar * [1, -1, 1]).max() < 0.0006
    # World → ego at frame 0: the ego stands at CARLA (100, 200) ⇒ right-handed world (100, −200); doubles.
    assert struct.pack("<d", 100.0) in data["/tf"][0] and struct.pack("<d", -200.0) in data["/tf"][0]
    # Boxes carry full sizes: the lead vehicle's half extents (2.4, 1.0, 0.75) ⇒ 4.8 × 2.0 × 1.5.
    assert struct.pack("<d", 4.8) in data["/boxes"][0] and struct.pack("<d", 1.5) in data["/boxes"][0]
    # Calibration K of the 64-pixel-wide front camera: f = 64 / (2·tan 35°) = 45.7012…
    focal = 64 / (2 * np.tan(np.radians(35)))
    assert struct.pack("<d", focal) in data["/camera/front/calibration"][0]


def test_existing_output_is_not_overwritten(exported: tuple[Path, Path]) -> None:
    clip, out = exported
    with pytest.raises(FileExistsError):
        export_mcap(clip, out)
