"""The files shipped as package data: present, licensed, and found by name."""

from __future__ import annotations

import pytest

from b2d_data import data


def test_shipped_towns_and_files_carry_their_licences() -> None:
    assert data.shipped_towns() == ["Town01", "Town04", "Town06", "Town07", "Town10HD"]
    assert "MIT" in (data.carla_maps_dir() / "LICENSE.txt").read_text()
    assert "Apache License" in (data.bench2drive_dir() / "LICENSE.txt").read_text()
    assert "Thinklab-SJTU" in (data.bench2drive_dir() / "SOURCE.txt").read_text()
    assert data.bench2drive_file("bench2drive220.xml").stat().st_size > 600_000


def test_unknown_shipped_file_names_what_ships() -> None:
    with pytest.raises(FileNotFoundError, match=r"nothing\.xml.*bench2drive220\.xml"):
        data.bench2drive_file("nothing.xml")
