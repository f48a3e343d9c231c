"""LAZ codec: header bytes (LAS 1.2, format 0, 1 mm, offsets = mins), round trip, empty and corrupt files."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import laspy
import numpy as np
import pytest

from b2d_data.codecs.laz import encode_laz, read_laz, stored_points, write_laz
from b2d_data.format.errors import B2DFormatError


def points(n: int = 500) -> np.ndarray:
    rng = np.random.default_rng(3)
    return rng.uniform([-80.0, -60.0, -2.0], [85.0, 70.0, 8.0], (n, 3))


def test_header_bytes(tmp_path: Path) -> None:
    pts = points()
    path = tmp_path / "00000.laz"
    write_laz(path, pts)
    raw = path.read_bytes()
    assert raw[:4] == b"LASF"
    assert (raw[24], raw[25]) == (1, 2)  # LAS 1.2
    assert raw[104] & 0x3F == 0 and raw[104] & 0x80  # point format 0, LAZ-compressed bit
    assert struct.unpack("<H", raw[105:107])[0] == 20  # format 0 record length
    assert struct.unpack("<I", raw[107:111])[0] == len(pts)
    scales = struct.unpack("<3d", raw[131:155])
    offsets = struct.unpack("<3d", raw[155:179])
    assert scales == (0.001, 0.001, 0.001)
    assert np.array_equal(offsets, pts.min(axis=0))


def test_stored_points_are_what_a_reader_gets_to_the_last_bit() -> None:
    pts = np.array([[1.0, 2.0, -3.0], [1.0014, 2.0026, -2.9996]])
    # Offsets are the minima (1, 2, −3); steps round(1.4) = 1, round(2.6) = 3, round(0.4) = 0.
    np.testing.assert_allclose(stored_points(pts), [[1.0, 2.0, -3.0], [1.001, 2.003, -3.0]], atol=1e-12)
    for cloud in (pts, points(), points(0), points().astype(np.float32)):
        assert np.array_equal(stored_points(cloud), read_laz(encode_laz(cloud)))
    # Storing stored points again changes nothing.
    assert encode_laz(stored_points(points()))[227:] == encode_laz(points())[227:]


def test_stored_points_bit_for_bit_on_sweep_like_clouds() -> None:
    """Half-millimetre ties, float32 sweeps, int and extra or Fortran-ordered columns: the reader's values exactly."""
    rng = np.random.default_rng(8)
    ties = np.round(rng.uniform(-50, 50, (3000, 3)), 3) + 0.0005  # every coordinate on a rounding tie
    sweep = (rng.uniform(-80, 80, (60_000, 3)) * [1, 1, 0.05]).astype(np.float32)
    for cloud in (ties, sweep, rng.integers(-100, 100, (40, 3)), rng.uniform(-5, 5, (200, 5)),
                  np.asfortranarray(rng.uniform(-5, 5, (200, 3))), points(1)):  # fmt: skip
        stored = stored_points(cloud)
        assert stored.shape == (len(cloud), 3) and stored.dtype == np.float64
        back = read_laz(encode_laz(cloud))
        assert np.array_equal(stored.view(np.uint64) if stored.flags.c_contiguous else stored.copy().view(np.uint64),
                              back.view(np.uint64))  # fmt: skip
        # The rule itself, written out on (N, 3): steps of 1 mm from each axis' minimum, rounded half to even.
        xyz = np.asarray(cloud, dtype=np.float64)[:, :3]
        offsets = xyz.min(axis=0)
        assert np.array_equal(stored, np.round((xyz - offsets) / 0.001) * 0.001 + offsets)


def test_round_trip_within_half_a_millimetre() -> None:
    pts = points()
    back = read_laz(encode_laz(pts))
    assert back.shape == pts.shape and back.dtype == np.float64
    assert np.abs(back - pts).max() <= 0.0005 + 1e-9
    assert read_laz(encode_laz(pts), dtype=np.float32).dtype == np.float32


def test_only_xyz_are_filled() -> None:
    las = laspy.read(io.BytesIO(encode_laz(points(50))))
    for dim in ("intensity", "return_number", "classification", "scan_angle_rank", "user_data", "point_source_id"):
        assert not np.asarray(las[dim]).any(), dim


@pytest.mark.parametrize("n", [0, 1, 500, 70_000])  # 70 000 points: two 50 000-point LAZ chunks
def test_bytes_as_laspys_plain_assignment(n: int) -> None:
    # The file is the one laspy writes when x, y, z are assigned to an empty LasData (how sweeps were encoded
    # before the encoder wrote the records itself): the same header values, points and compressed bytes.
    pts = points(n)
    header = laspy.LasHeader(point_format=0, version="1.2")
    header.scales = np.full(3, 0.001)
    header.offsets = pts.min(axis=0) if n else np.zeros(3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
    bio = io.BytesIO()
    las.write(bio, do_compress=True, laz_backend=laspy.LazBackend.Lazrs)
    ours, theirs = encode_laz(pts), bio.getvalue()
    # Byte for byte, but for the 32-byte "generating software" field of the header (bytes 58-89).
    assert ours[58:90] == b"b2d-data".ljust(32, b"\0")
    assert theirs[58:90].startswith(b"laspy")
    assert len(ours) == len(theirs) and ours[:58] == theirs[:58] and ours[90:] == theirs[90:]


def test_empty_cloud() -> None:
    back = read_laz(encode_laz(np.zeros((0, 3))))
    assert back.shape == (0, 3)


def test_corrupt_laz_names_the_file(tmp_path: Path) -> None:
    data = encode_laz(points())
    cases = {"garbage.laz": b"garbage" * 40, "half.laz": data[: len(data) // 2], "header.laz": data[:100]}
    for name, content in cases.items():
        (tmp_path / name).write_bytes(content)
        with pytest.raises(B2DFormatError, match=name):
            read_laz(tmp_path / name)
    with pytest.raises(ValueError):
        encode_laz(np.array([[0.0, np.nan, 1.0]]))


def test_decoding_stays_usable_in_a_forked_child(tmp_path):
    # A process forked after the parent decoded one sweep (a DataLoader worker started after `ds[0]`) must
    # still decode: laspy's parallel lazrs backend left a rayon pool behind that hung such children forever.
    import multiprocessing

    import numpy as np

    from b2d_data.codecs.laz import read_laz, write_laz

    path = tmp_path / "00000.laz"
    write_laz(path, np.random.default_rng(0).uniform(-50, 50, (20000, 3)))
    parent = read_laz(path)
    ctx = multiprocessing.get_context("fork")
    child = ctx.Process(target=read_laz, args=(path,))
    child.start()
    child.join(timeout=30)
    alive = child.is_alive()
    if alive:
        child.kill()
    assert not alive and child.exitcode == 0
    assert parent.shape == (20000, 3)
