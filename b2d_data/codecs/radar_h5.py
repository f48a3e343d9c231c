"""Radar detections as h5 (format.md §2.5): 5 float16 (N, 4) datasets, gzip level 9, auto chunks."""

from __future__ import annotations

import io
import itertools
import logging
import os
import threading
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

from b2d_data.codecs._source import Source, is_data, read_source, source_name, write_bytes
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.rig import RADARS_V0

logger = logging.getLogger(__name__)

#: Dataset names in file order; columns are [depth m, altitude rad, azimuth rad, velocity m/s].
RADAR_DATASETS: tuple[str, ...] = tuple(r.dataset for r in RADARS_V0)
RADAR_COLUMNS: tuple[str, ...] = ("depth", "altitude", "azimuth", "velocity")


def _prepared(radar: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    unknown = sorted(set(radar) - set(RADAR_DATASETS))
    if unknown:
        raise ValueError(f"unknown radar dataset(s) {unknown}; expected names from {list(RADAR_DATASETS)}")
    out: dict[str, np.ndarray] = {}
    for key in RADAR_DATASETS:
        arr = radar.get(key)
        if arr is None:
            # A radar with no entry saw nothing this frame: the released files always hold all 5 datasets.
            out[key] = np.zeros((0, 4), dtype=np.float16)
            continue
        arr = np.asarray(arr)
        if arr.ndim != 2 or arr.shape[1] != 4 or arr.dtype.kind not in "fiu":
            raise ValueError(f"radar {key} must be an (N, 4) numeric array, got {arr.dtype} {arr.shape}")
        out[key] = arr.astype(np.float16)
    return out


#: Names of the in-memory HDF5 files: HDF5 looks for the name once (absent, so nothing on disk is read or changed);
#: each file gets its own, since HDF5 shares an open file by name between threads.
_IN_MEMORY_NAMES = itertools.count()


def encode_radar(radar: Mapping[str, np.ndarray]) -> bytes:
    """Encode a dict of (N, 4) detections keyed by dataset name as h5 bytes; absent radars are stored empty.

    Built by HDF5's in-memory driver: the bytes h5py writes to a file path (the file-object driver of h5py lays the
    file out differently), in one buffer instead of a dozen writes to the file.
    """
    prepared = _prepared(radar)
    name = f"/nonexistent-b2d-data/{os.getpid()}-{threading.get_ident()}-{next(_IN_MEMORY_NAMES)}.h5"
    with h5py.File(name, "w", driver="core", backing_store=False) as f:
        for key, arr in prepared.items():
            f.create_dataset(key, data=arr, compression="gzip", compression_opts=9, chunks=True)
        f.flush()
        return bytes(f.id.get_file_image())


def write_radar(path: str | os.PathLike[str], radar: Mapping[str, np.ndarray]) -> int:
    """Write ``radar/NNNNN.h5``; returns the number of bytes written."""
    return write_bytes(path, encode_radar(radar))


def read_radar(
    source: Source,
    *,
    missing_ok: bool = False,
    dtype: type[np.floating] | str = np.float32,
    name: str | os.PathLike[str] | None = None,
) -> dict[str, np.ndarray]:
    """Decode a radar h5 to {dataset name: (N, 4) array}, converted to ``dtype`` (float16 keeps the stored values).

    With ``missing_ok`` a missing file gives ``{}`` and missing datasets are left out of the dict (released clips
    may lack radar); without it both raise ``B2DFormatError``. Unexpected extra datasets are ignored.
    """
    label = source_name(source, name)
    if not is_data(source) and not Path(os.fspath(source)).exists():  # type: ignore[arg-type]
        if missing_ok:
            return {}
        raise B2DFormatError(label, "file does not exist")
    data, _ = read_source(source, name)
    if bytes(data[:8]) != b"\x89HDF\r\n\x1a\n":
        raise B2DFormatError(label, "not an HDF5 file (missing the HDF5 signature)")
    out: dict[str, np.ndarray] = {}
    try:
        with h5py.File(io.BytesIO(data), "r") as f:
            for key in RADAR_DATASETS:
                if key not in f:
                    if missing_ok:
                        continue
                    raise B2DFormatError(label, f"missing dataset {key!r} (has {sorted(f.keys())})")
                dset = f[key]
                if not isinstance(dset, h5py.Dataset) or dset.ndim != 2 or dset.shape[1] != 4:
                    raise B2DFormatError(label, f"dataset {key!r} must be (N, 4), got {getattr(dset, 'shape', dset)}")
                out[key] = dset[()].astype(dtype, copy=False)
    except B2DFormatError:
        raise
    except Exception as exc:  # h5py reports truncation and corruption as OSError/KeyError/RuntimeError
        raise B2DFormatError(label, f"corrupt or truncated h5: {exc}") from exc
    return out
