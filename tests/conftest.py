"""Shared fixtures: the real Bench2Drive / CARLA files the package ships (b2d_data/data)."""

from __future__ import annotations

from pathlib import Path

import pytest

from b2d_data import data


@pytest.fixture(scope="session")
def b2d_data_dir() -> Path:
    """The shipped Bench2Drive files: route XML, weather.xml, split lists, VAD's merged result."""
    return data.bench2drive_dir()


@pytest.fixture(scope="session")
def carla_maps_dir() -> Path:
    """The shipped CARLA towns (Town01/04/06/07/10HD .xodr)."""
    return data.carla_maps_dir()
