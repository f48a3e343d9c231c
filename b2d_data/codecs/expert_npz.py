"""Expert assessment vectors (format.md §2.8): ``np.savez(path, vector)``, stored at frame index − 1.

Frame k's vector goes to ``f"{k - 1:05}.npz"``, so frame 0 is ``-0001.npz``. The vector is a 1536-d feature, then
a value, then the discrete action index (as float; :mod:`b2d_data.format.expert_actions`). In released clips the
feature is Think2Drive's latent and the value its value estimate; in b2d-data clips they are the BEV raster and
the route progress of :mod:`b2d_data.format.expert_feature`, as the clip's ``b2d_format.json`` records.
"""

from __future__ import annotations

import io
import os
import re
from pathlib import PurePath

import numpy as np

from b2d_data.codecs._npz import first_npz_array
from b2d_data.codecs._source import Source, read_source, write_bytes
from b2d_data.format.errors import B2DFormatError

#: Key ``np.savez`` gives to a single unnamed array.
EXPERT_NPZ_KEY = "arr_0"

_NAME_RE = re.compile(r"^(-?\d+)\.npz$")


def expert_file_name(frame_index: int) -> str:
    """File name holding frame ``frame_index``'s vector: the index minus one, width 5 (frame 0 → ``-0001.npz``)."""
    return f"{frame_index - 1:05}.npz"


def expert_frame_index(file_name: str | os.PathLike[str]) -> int:
    """The frame whose vector a file holds: its number plus one (``-0001.npz`` → 0)."""
    base = PurePath(os.fspath(file_name)).name
    match = _NAME_RE.match(base)
    if match is None:
        raise ValueError(f"not an expert assessment file name: {base!r} (expected e.g. '-0001.npz' or '00041.npz')")
    return int(match.group(1)) + 1


def _check_vector(vector: np.ndarray) -> np.ndarray:
    arr = np.asarray(vector)
    if arr.ndim != 1 or arr.dtype.kind not in "fiu" or arr.size < 2:
        raise ValueError(
            f"expert assessment must be a 1-D numeric vector (feature, value, action), got {arr.dtype} {arr.shape}"
        )
    return arr


def encode_expert(vector: np.ndarray) -> bytes:
    """Encode the vector as ``np.savez`` does with one positional array (key ``arr_0``, uncompressed)."""
    bio = io.BytesIO()
    np.savez(bio, _check_vector(vector))
    return bio.getvalue()


def write_expert(path: str | os.PathLike[str], vector: np.ndarray) -> int:
    """Write an expert npz to ``path`` (name it with ``expert_file_name``); returns the number of bytes written."""
    return write_bytes(path, encode_expert(vector))


def read_expert(source: Source, *, name: str | os.PathLike[str] | None = None) -> np.ndarray:
    """Decode an expert npz to its 1-D vector (``arr_0``, else the first array) with the stored dtype."""
    data, label = read_source(source, name)
    arr = first_npz_array(data, label, prefer=EXPERT_NPZ_KEY)
    if arr.ndim != 1 or arr.dtype.kind not in "fiu":
        raise B2DFormatError(label, f"expert assessment must be a 1-D numeric vector, got {arr.dtype} {arr.shape}")
    return arr


def split_expert(vector: np.ndarray) -> tuple[np.ndarray, float, int]:
    """Split a vector into (feature, value estimate, discrete action index 0–38)."""
    arr = _check_vector(vector)
    return arr[:-2], float(arr[-2]), int(arr[-1])
