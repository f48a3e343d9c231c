"""A tiny synthetic corpus written by ClipWriter (64×36 cameras), shared by the loader tests."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from b2d_data.format.names import ClipName
from b2d_data.format.version import FormatVersion
from b2d_data.loaders.synthetic import SyntheticClipSpec, write_synthetic_clip

CLIP_A = ClipName.parse("Accident_Town03_Route1_Weather0")  # v0 layout, 12 frames
CLIP_B = ClipName.parse("HardBreakRoute_Town01_Route2_Weather3")  # v0.0.4 layout (float depth npz), 6 frames

SPEC_A = SyntheticClipSpec(CLIP_A, frames=12, seed=1)
SPEC_B = SyntheticClipSpec(CLIP_B, frames=6, seed=2, format_version=FormatVersion.V004, ego_yaw_deg=-120.0)


@pytest.fixture(scope="session")
def corpus(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A corpus root holding clips A and B (read-only for the tests: copy it before changing anything)."""
    root = tmp_path_factory.mktemp("corpus")
    write_synthetic_clip(root, SPEC_A)
    write_synthetic_clip(root, SPEC_B)
    return root


@pytest.fixture()
def corpus_copy(corpus: Path, tmp_path: Path) -> Path:
    """A private copy of the corpus (without its index) that a test may change."""
    dest = tmp_path / "corpus"
    shutil.copytree(corpus, dest, ignore=shutil.ignore_patterns(".b2d_index"))
    return dest
