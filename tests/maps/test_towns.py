"""Towns resolve by name: generated presets, and the CARLA towns shipped with the package."""

from __future__ import annotations

import pytest

from b2d_data.maps.towns import CARLA_MAPS_ENV, UnknownTownError, resolve_town


def test_carla_town_names_resolve_from_the_package(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(CARLA_MAPS_ENV, raising=False)
    town = resolve_town("Town01")
    assert town.name == "Town01"
    assert len(town.data.roads) == 122  # the real Town01.xodr holds 122 <road> elements


def test_unknown_town_lists_presets_and_shipped_towns() -> None:
    with pytest.raises(UnknownTownError, match=r"unknown town 'Town99'.*Town10HD"):
        resolve_town("Town99")
