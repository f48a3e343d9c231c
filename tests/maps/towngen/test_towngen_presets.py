"""Town presets: names, determinism, seeds, errors, writing files."""

from __future__ import annotations

from pathlib import Path

import pytest
from lxml import etree

from b2d_data.format.names import CARLA_TOWNS, ClipName, is_town_name
from b2d_data.maps.towngen import (
    ALL_LAYOUTS,
    DEFAULT_PRESET,
    TOWN_PRESETS,
    UnknownPresetError,
    generate_town,
    write_town,
)


def test_every_preset_has_a_clip_safe_town_name() -> None:
    towns = [p.town for p in TOWN_PRESETS.values()]
    assert len(set(towns)) == len(towns)
    for town in towns:
        assert is_town_name(town) and town not in CARLA_TOWNS
        assert ClipName.parse(f"Accident_{town}_Route1_Weather0").town == town


def test_default_preset_holds_every_layout() -> None:
    assert set(TOWN_PRESETS[DEFAULT_PRESET].layouts) == set(ALL_LAYOUTS)
    for preset in TOWN_PRESETS.values():
        assert set(preset.layouts) <= set(ALL_LAYOUTS)


@pytest.mark.parametrize("preset", sorted(TOWN_PRESETS))
def test_same_seed_same_text_other_seed_other_text(preset: str) -> None:
    first = generate_town(preset, 7)
    assert generate_town(preset, 7) == first
    assert generate_town(preset, 8) != first
    header = etree.fromstring(first.encode()).find("header")
    assert header.get("name") == TOWN_PRESETS[preset].town
    assert header.find("userData/b2dTownGen").get("seed") == "7"


def test_unknown_preset_lists_the_known_ones() -> None:
    with pytest.raises(UnknownPresetError) as err:
        generate_town("downtown", 0)
    for name in TOWN_PRESETS:
        assert name in str(err.value)


@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_bad_seed_is_refused(seed: object) -> None:
    with pytest.raises(ValueError):
        generate_town("interurban", seed)  # type: ignore[arg-type]


def test_write_town_names_the_file_after_the_town(tmp_path: Path) -> None:
    path = write_town("interurban", 3, tmp_path)
    assert path == tmp_path / f"{TOWN_PRESETS['interurban'].town}.xodr"
    assert path.read_text(encoding="utf-8") == generate_town("interurban", 3)
    explicit = write_town("interurban", 3, tmp_path / "sub" / "Town103.xodr")
    assert explicit.read_text(encoding="utf-8") == path.read_text(encoding="utf-8")
