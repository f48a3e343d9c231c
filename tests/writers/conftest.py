"""Small synthetic frames for the writer tests (64×36 cameras, a few LiDAR points and radar detections)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from b2d_data.format.anno_schema import EGO_KEYS, TOP_LEVEL_KEYS
from b2d_data.format.record import CameraFrame, FrameRecord
from b2d_data.format.rig import ALL_CAMERAS

W, H = 64, 36


def make_anno(index: int) -> dict:
    """A minimal annotation in Bench2Drive's key order (ego box only, NaN theta on odd frames)."""
    values: dict[str, object] = {key: 0.0 for key in TOP_LEVEL_KEYS}
    values.update(x=100.0 + index, y=-20.5, reverse=False, theta=float("nan") if index % 2 else 1.25, speed=None,
                  command_far=4, command_near=4, next_command=4, should_brake=False, only_ap_brake=False,
                  weather={"cloudiness": 5.0}, acceleration=[0.0, 0.1, 9.8], angular_velocity=[0.0, 0.0, 0.01],
                  sensors={})  # fmt: skip
    ego = {key: None for key in EGO_KEYS}
    ego.update({"class": "ego_vehicle", "id": "1", "extent": [2.451, 1.064, 0.755]})
    values["bounding_boxes"] = [ego]
    return {key: values[key] for key in TOP_LEVEL_KEYS}


def make_record(index: int, *, seed: int = 0, expert: bool = True, radar: bool = True) -> FrameRecord:
    """A full frame: 7 cameras (dense labels on the 6 surround ones), 200 LiDAR points, 5 radars."""
    rng = np.random.default_rng(seed * 1000 + index)
    cameras = {}
    for spec in ALL_CAMERAS:
        # Smooth ramps with a random phase per camera keep JPEG q20 errors small enough for a tight bound.
        v, u = np.mgrid[0:H, 0:W]
        phase = rng.uniform(0, 2 * np.pi, 3)
        rgb = np.stack([127.5 + 100 * np.sin(u / 24.0 + v / 36.0 + p) for p in phase], axis=-1).astype(np.uint8)
        frame = CameraFrame(rgb=rgb)
        if spec.has_dense_labels:
            frame.depth = rng.uniform(0.0, 300.0, (H, W)).astype(np.float32)
            frame.semantic = rng.integers(0, 29, (H, W)).astype(np.uint8)
            frame.instance = rng.integers(0, 65536, (H, W)).astype(np.uint16)
        cameras[spec.folder] = frame
    detections = {name: rng.uniform(-1, 50, (n, 4)) for name, n in
                  zip(("radar_front", "radar_front_left", "radar_front_right", "radar_back_left", "radar_back_right"),
                      (5, 0, 3, 1, 2))}  # fmt: skip
    return FrameRecord(
        index=index,
        anno=make_anno(index),
        cameras=cameras,
        lidar=rng.uniform(-80.0, 80.0, (200, 3)),
        radar=detections if radar else None,
        expert_assessment=rng.normal(size=1538).astype(np.float32) if expert else None,
    )


@pytest.fixture
def record_factory() -> Callable[..., FrameRecord]:
    """``record_factory(index, seed=0, expert=True, radar=True)`` → a synthetic FrameRecord."""
    return make_record
