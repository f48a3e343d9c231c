"""LiDAR sweeps as LAZ (format.md §2.4): LAS 1.2, point format 0, 1 mm scales, offsets = per-axis minimum."""

from __future__ import annotations

import io
import os

import laspy
import numpy as np

from b2d_data.codecs._source import Source, read_source, write_bytes
from b2d_data.format.errors import B2DFormatError

#: Quantisation step of the stored coordinates (metres); the round trip is exact to half of it.
LAZ_SCALE = 0.001


def _header(points: np.ndarray) -> laspy.LasHeader:
    header = laspy.LasHeader(point_format=0, version="1.2")
    header.scales = np.full(3, LAZ_SCALE)
    # Bench2Drive offsets each axis by the frame's minimum, so every stored integer is ≥ 0.
    header.offsets = points.min(axis=0) if len(points) else np.zeros(3)
    return header


def _check_points(points: np.ndarray) -> np.ndarray:
    arr = np.asarray(points)
    if arr.ndim != 2 or arr.shape[1] < 3 or arr.dtype.kind not in "fiu":
        raise ValueError(f"LiDAR points must be an (N, 3) numeric array, got {arr.dtype} {arr.shape}")
    xyz = np.ascontiguousarray(arr[:, :3], dtype=np.float64)
    if not np.isfinite(xyz).all():
        raise ValueError("LiDAR points contain NaN or infinite coordinates")
    return xyz


def encode_laz(points: np.ndarray) -> bytes:
    """Encode (N, 3) ego-frame points as LAZ bytes; only X/Y/Z are filled, N may be 0. Extra columns are dropped."""
    xyz = _check_points(points)
    header = _header(xyz)
    # A record of the final size: assigning into an empty one grows it by np.append (1 ms of 8 per sweep).
    las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(len(xyz), header=header))
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    bio = io.BytesIO()
    # The single-threaded lazrs backend: one sweep is one or two LAZ chunks, and the simulator needs the other core.
    las.write(bio, do_compress=True, laz_backend=laspy.LazBackend.Lazrs)
    return bio.getvalue()


def write_laz(path: str | os.PathLike[str], points: np.ndarray) -> int:
    """Write ``points`` as ``NNNNN.laz``; returns the number of bytes written."""
    return write_bytes(path, encode_laz(points))


def read_laz(
    source: Source, *, dtype: type[np.floating] | str = np.float64, name: str | os.PathLike[str] | None = None
) -> np.ndarray:
    """Decode a LAS/LAZ file (path or bytes) to (N, 3) points in the stored (ego) frame, any point format."""
    data, label = read_source(source, name)
    if bytes(data[:4]) != b"LASF":
        raise B2DFormatError(label, "not a LAS/LAZ file (missing the LASF signature)")
    try:
        # Single-threaded lazrs: laspy's default LazrsParallel starts a rayon thread pool that deadlocks any
        # process forked afterwards (e.g. DataLoader workers started after the parent decoded one sweep).
        las = laspy.read(io.BytesIO(data), laz_backend=laspy.LazBackend.Lazrs)
        raw = (las.X, las.Y, las.Z)
        scales, offsets = las.header.scales, las.header.offsets
    except Exception as exc:  # laspy/lazrs raise many types (LaspyException, LazrsError, ValueError) on bad input
        raise B2DFormatError(label, f"corrupt or truncated LAZ: {exc}") from exc
    if len(raw[0]) != las.header.point_count:
        raise B2DFormatError(label, f"truncated LAZ: {len(raw[0])} of {las.header.point_count} points")
    out = np.empty((len(raw[0]), 3), dtype)
    for axis in range(3):
        out[:, axis] = raw[axis] * scales[axis] + offsets[axis]
    return out
