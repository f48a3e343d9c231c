"""Shared fixtures: where the real Bench2Drive / CARLA files live."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` beside the checkout (real route, split and result files; CARLA town maps)."""
    if not SHARED_DATA.is_dir():
        raise FileNotFoundError(f"{SHARED_DATA} is missing: tests read the real Bench2Drive files from ../shared/data")
    return SHARED_DATA


@pytest.fixture(scope="session")
def b2d_data_dir(shared_data: Path) -> Path:
    """``../shared/data/bench2drive``."""
    return shared_data / "bench2drive"


@pytest.fixture(scope="session")
def carla_maps_dir(shared_data: Path) -> Path:
    """``../shared/data/carla_maps`` (Town01/04/06/07/10HD .xodr)."""
    return shared_data / "carla_maps"
