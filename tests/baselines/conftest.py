"""A tiny synthetic corpus (two 30-frame clips at 64x36) for the baseline tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from b2d_data.format.names import ClipName
from b2d_data.loaders.synthetic import SyntheticClipSpec, write_synthetic_clip

#: Straight drives at constant speed: every future waypoint k is k * 0.5 s * speed ahead (a hand-checkable target).
SPECS = (
    SyntheticClipSpec(ClipName.parse("HardBreakRoute_Town100_Route1_Weather0"), frames=30, seed=1, speed=5.0,
                      lidar_points=16, cameras=("front",)),
    SyntheticClipSpec(ClipName.parse("NoScenario_Town100_Route2_Weather1"), frames=30, seed=2, speed=8.0,
                      ego_yaw_deg=-120.0, lidar_points=16, cameras=("front",)),
)  # fmt: skip


@pytest.fixture(scope="session")
def corpus(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A corpus root holding the two clips (tests copy it before writing into it)."""
    root = tmp_path_factory.mktemp("baselines_corpus")
    for spec in SPECS:
        write_synthetic_clip(root, spec)
    return root
