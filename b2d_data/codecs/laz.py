"""LiDAR sweeps as LAZ (format.md §2.4): LAS 1.2, point format 0, 1 mm scales, offsets = per-axis minimum."""

from __future__ import annotations

import io
import os
import struct
from datetime import date

import laspy
import lazrs
import numpy as np

from b2d_data.codecs._source import Source, read_source, write_bytes
from b2d_data.format.errors import B2DFormatError

#: Quantisation step of the stored coordinates (metres); the round trip is exact to half of it.
LAZ_SCALE = 0.001


#: LAS 1.2 public header size, and the LASzip VLR that declares the compression of point format 0.
_HEADER_SIZE = 227
_LASZIP_VLR = lazrs.LazVlr.new_for_compression(0, 0)
_LASZIP_VLR_DATA = bytes(_LASZIP_VLR.record_data())
_LASZIP_VLR_HEADER = struct.pack("<H16sHH32s", 0, b"laszip encoded", 22204, len(_LASZIP_VLR_DATA), b"http://laszip.org")
#: Point format 0 records (20 bytes): X, Y, Z as int32, then intensity, flags, class, scan angle, user data and
#: point source, all zero.
_RECORD = np.dtype([("X", "<i4"), ("Y", "<i4"), ("Z", "<i4"), ("rest", "V8")])
_SOFTWARE = b"b2d-data"
_INT32_MAX = 2**31 - 1


def _check_points(points: np.ndarray) -> np.ndarray:
    """The x, y, z columns as a (3, N) float64 array, one contiguous row per axis (column passes run on rows)."""
    arr = np.asarray(points)
    if arr.ndim != 2 or arr.shape[1] < 3 or arr.dtype.kind not in "fiu":
        raise ValueError(f"LiDAR points must be an (N, 3) numeric array, got {arr.dtype} {arr.shape}")
    columns = np.array(arr[:, :3].T, dtype=np.float64, order="C")
    if not np.isfinite(columns).all():
        raise ValueError("LiDAR points contain NaN or infinite coordinates")
    return columns


def _public_header(count: int, offsets: np.ndarray, mins: np.ndarray, maxs: np.ndarray) -> bytes:
    """The LAS 1.2 public header of a LAZ file of ``count`` format-0 points with one VLR (the LASzip one)."""
    today = date.today().timetuple()
    point_data = _HEADER_SIZE + len(_LASZIP_VLR_HEADER) + len(_LASZIP_VLR_DATA)
    bounds = [v for axis in range(3) for v in (maxs[axis], mins[axis])]  # max x, min x, max y, ...
    return struct.pack(
        "<4sHH16sBB32s32sHHHIIBHI5I3d3d6d",
        b"LASF", 0, 0, bytes(16), 1, 2, b"OTHER", _SOFTWARE, today.tm_yday, today.tm_year, _HEADER_SIZE,
        point_data, 1, 0x80, _RECORD.itemsize, count, 0, 0, 0, 0, 0, *([LAZ_SCALE] * 3), *offsets, *bounds,
    )  # fmt: skip


def _quantise(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3, N) integer steps (as float64, one row per axis) and the per-axis offsets a LAZ file stores."""
    columns = _check_points(points)
    steps = np.empty(columns.shape, np.float64)
    offsets = np.zeros(3)
    # Axis by axis on contiguous rows, in place: numpy's reductions along axis 0 of an (N, 3) array are ~15×
    # slower, and each temporary of a 60k-point sweep costs its allocation.
    for axis, name in enumerate("xyz"):
        if not columns.shape[1]:
            break
        column, row = columns[axis], steps[axis]
        # Bench2Drive offsets each axis by the frame's minimum, so every stored integer is ≥ 0.
        offsets[axis] = column.min()
        np.subtract(column, offsets[axis], out=row)
        np.divide(row, LAZ_SCALE, out=row)
        np.round(row, out=row)
        if row.max() > _INT32_MAX:  # numpy would wrap silently where laspy refused
            raise OverflowError(f"LiDAR points span {row.max() * LAZ_SCALE:.0f} m along {name}: more "
                                f"than LAS's int32 coordinates hold at {LAZ_SCALE * 1e3:g} mm steps")  # fmt: skip
    return steps, offsets


def stored_points(points: np.ndarray) -> np.ndarray:
    """(N, 3) float64: ``points`` exactly as :func:`read_laz` returns them from the file :func:`encode_laz` writes.

    Anything computed from a sweep and stored beside it (``num_points``) must use these: the 1 mm steps move
    points across a box face that the points lie on (a vehicle's mesh fills its box).
    """
    steps, offsets = _quantise(points)
    # The reader's arithmetic (integer · scale + offset; the steps are whole numbers held exactly in float64), so
    # that the values are the same to the last bit; in place on the rows, returned as an (N, 3) view.
    for axis in range(3):
        row = steps[axis]
        np.multiply(row, LAZ_SCALE, out=row)
        np.add(row, offsets[axis], out=row)
    return steps.T


def encode_laz(points: np.ndarray) -> bytes:
    """Encode (N, 3) ego-frame points as LAZ bytes; only X/Y/Z are filled, N may be 0. Extra columns are dropped.

    The file is what laspy writes for the same points (same header values but the generating software, LASzip
    VLR, integer coordinates and chunks), built here directly: laspy's record and header bookkeeping cost twice
    the compression itself.
    """
    steps, offsets = _quantise(points)
    count = steps.shape[1]
    record = np.zeros(count, _RECORD)
    for axis, name in enumerate("XYZ"):
        record[name] = steps[axis]
    if count:
        # As laspy bounds a file: the extreme stored integers, scaled back.
        mins = np.array([record[n].min() for n in "XYZ"]) * LAZ_SCALE + offsets
        maxs = np.array([record[n].max() for n in "XYZ"]) * LAZ_SCALE + offsets
    else:
        mins = maxs = np.zeros(3)
    out = io.BytesIO()
    out.write(_public_header(count, offsets, mins, maxs))
    out.write(_LASZIP_VLR_HEADER)
    out.write(_LASZIP_VLR_DATA)
    # Single-threaded: one sweep is one or two LAZ chunks, and the simulator needs the other cores.
    compressor = lazrs.LasZipCompressor(out, _LASZIP_VLR)
    compressor.compress_many(record.view(np.uint8))
    compressor.done()
    return out.getvalue()


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
