"""Town presets: names, determinism, seeds, errors, writing files."""

from __future__ import annotations

import hashlib
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
from b2d_data.maps.towngen.presets import ONE_WAY


def test_every_preset_has_a_clip_safe_town_name() -> None:
    towns = [p.town for p in TOWN_PRESETS.values()]
    assert len(set(towns)) == len(towns)
    for town in towns:
        assert is_town_name(town) and town not in CARLA_TOWNS
        assert ClipName.parse(f"Accident_{town}_Route1_Weather0").town == town


def test_default_preset_holds_every_layout_but_the_one_way_street() -> None:
    # the one-way street came after Town100, whose text stays as it was (see test_first_four_towns_unchanged)
    assert set(TOWN_PRESETS[DEFAULT_PRESET].layouts) == set(ALL_LAYOUTS) - {ONE_WAY}
    assert ONE_WAY in TOWN_PRESETS["downtown"].layouts
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
        generate_town("suburb", 0)
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


#: sha256 of the seed-0 OpenDRIVE text of Town100-103, taken before one-way streets were added (commit b6e03aa):
#: the junction builder's one-way cases and the downtown preset must leave every byte of them as it was.
FIRST_FOUR = {
    "all": "32a4002bd5adbca4d4db3a8639993ca7c16fca04ef1fd292ebb2b702def40cb4",
    "urban": "d7f27e071d931c243c7c478b5f593f218506d7ec29c0d4774295282e71179e3d",
    "highway": "a8388681be7f91bb9a3b75d545d33d46ad84ab4e117785918768f6168b28e339",
    "interurban": "3d5bdd1096f89afd137e612bbd7f45040e043da91c4f4718734e373bb9938084",
}


@pytest.mark.parametrize("preset", sorted(FIRST_FOUR))
def test_first_four_towns_unchanged(preset: str) -> None:
    assert hashlib.sha256(generate_town(preset, 0).encode("utf-8")).hexdigest() == FIRST_FOUR[preset]
