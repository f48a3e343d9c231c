"""Fixtures for the builtin simulator tests: a flat, empty stand-in town and small worlds on it."""

from __future__ import annotations

import pytest

from b2d_data.sim.builtin.world import BuiltinSimulator


class FlatTown:
    """A town with no roads and no signals: the world is the z = 0 plane."""

    name = "Flat"
    path = None
    junctions: dict = {}

    def lane_geometry(self, resolution: float = 0.5, lane_type=None) -> list:
        return []

    def signals(self) -> list:
        return []

    def controllers(self) -> list:
        return []

    def speed_limit_signs(self) -> list:
        return []

    def get_waypoint(self, location, project_to_road: bool = True, lane_type=None):
        return None


@pytest.fixture
def flat_world():
    """A fresh world on the flat stand-in town (seed 0)."""
    world = BuiltinSimulator(FlatTown(), seed=0)
    yield world
    world.close()


@pytest.fixture
def flat_town() -> FlatTown:
    """The flat stand-in town."""
    return FlatTown()
