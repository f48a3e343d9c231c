"""Reading the first array of an npz file, shared by the depth and expert decoders."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from b2d_data.format.errors import B2DFormatError


def first_npz_array(data: bytes | memoryview, label: Path, prefer: str | None = None) -> np.ndarray:
    """The array stored under ``prefer`` when present, else the first array of the npz; errors name ``label``."""
    if bytes(data[:2]) != b"PK":
        raise B2DFormatError(label, "not an npz file (no zip signature)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            if not npz.files:
                raise B2DFormatError(label, "npz holds no array")
            key = prefer if prefer in npz.files else npz.files[0]
            return npz[key]
    except B2DFormatError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as exc:
        raise B2DFormatError(label, f"not a readable npz file: {exc}") from exc
