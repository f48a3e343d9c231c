"""The BEV feature layout: cell arithmetic by hand, vector assembly and the b2d_format.json record."""

from __future__ import annotations

import json

import numpy as np
import pytest

from b2d_data.format import expert_feature as ef


def test_cells_by_hand():
    assert ef.FEATURE_LENGTH == 1536 and ef.VECTOR_LENGTH == 1538 and ef.SHAPE == (6, 16, 16)
    # Row r covers forward (16 − 2(r + 1), 16 − 2r]; column c covers rightward [−16 + 2c, −14 + 2c).
    assert ef.cell_of(10.5, 0.3) == (2, 8)  # forward 10.5 ∈ [10, 12) → row 2; right 0.3 ∈ [0, 2) → col 8
    assert ef.cell_of(0.5, -0.5) == (7, 7)  # just ahead-left of the ego origin
    assert ef.cell_of(-15.9, 15.9) == (15, 15)  # far behind-right corner
    assert ef.cell_of(15.99, -16.0) == (0, 0)  # far ahead-left corner
    assert ef.cell_of(16.0, 0.0) == (0, 8) and ef.cell_of(0.0, 0.0) == (8, 8)  # forward edges belong to the row below
    assert ef.cell_of(-16.0, 0.0) is None and ef.cell_of(0.0, 16.0) is None


def test_vector_assembly_and_unflatten():
    raster = np.zeros(ef.SHAPE, np.float32)
    raster[ef.VEHICLES, 2, 8] = 1.0
    raster[ef.SPEED] = 0.2
    vec = ef.assemble_vector(raster, 0.25, 17)
    assert vec.dtype == np.float32 and vec.shape == (1538,)
    # C order: channel 2, row 2, col 8 → 2·256 + 2·16 + 8 = 552.
    assert vec[552] == 1.0 and vec[:512].sum() == 0.0
    assert vec[-2] == 0.25 and vec[-1] == 17.0
    assert np.array_equal(ef.unflatten(vec[:-2]), raster)
    with pytest.raises(ValueError):
        ef.unflatten(vec)
    with pytest.raises(ValueError):
        ef.assemble_vector(raster[:5], 0.0, 0)


def test_layout_record_identifies_the_raster():
    record = json.loads(json.dumps(ef.layout_record()))  # as stored in b2d_format.json
    assert ef.is_bev_record(record)
    assert record["channels"] == ["drivable", "route", "vehicles", "walkers", "stop", "speed"]
    assert not ef.is_bev_record(None) and not ef.is_bev_record({})
    assert not ef.is_bev_record({**record, "version": ef.FEATURE_VERSION + 1})
