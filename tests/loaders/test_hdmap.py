"""Map elements near the ego, from an HD-map npz built by hand in Bench2Drive's layout (format.md §6)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from b2d_data import ClipDataset
from b2d_data.format.errors import B2DFormatError
from b2d_data.loaders import MAP_TYPES, HDMap

from .conftest import CLIP_A


def _lane(points: list[tuple[float, float]], kind: str, centre: bool) -> dict:
    pts = [((x, y, 0.0), (0.0, 0.0, 0.0), False) if centre else ((x, y, 0.0), (0.0, 0.0, 0.0)) for x, y in points]
    element = {"Points": pts, "Type": kind, "Color": "White", "Topology": [(2, -1)]}
    if centre:
        element.update(TopologyType="Normal", Left=(None, None), Right=(None, None))
    return element


def write_town03_map(folder: Path) -> Path:
    """Road 1: a centre line and a broken boundary along y = 200 for x = 50..150 (1 m steps) and a stop-sign
    trigger volume around (105, 195); road 2: a solid line 1 km away."""
    xs = np.arange(50.0, 151.0)
    roads = {
        1: {
            -1: [_lane([(x, 200.0) for x in xs], "Center", True), _lane([(x, 201.75) for x in xs], "Broken", False)],
            "Trigger_Volumes": [
                {
                    "Points": [
                        [104.0, 194.0, 0.0],
                        [106.0, 194.0, 0.0],
                        [106.0, 195.0, 0.0],
                        [106.0, 196.0, 0.0],
                        [104.0, 196.0, 0.0],
                    ],
                    "Type": "StopSign",
                    "ParentActor_Location": [107.0, 193.0, 0.0],
                },
            ],  # fmt: skip
        },
        2: {1: [_lane([(1100.0 + x, 0.0) for x in range(10)], "Solid", False)]},
    }
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "Town03_HD_map.npz"
    arr = np.empty((len(roads), 2), dtype=object)
    for i, item in enumerate(roads.items()):
        arr[i, 0], arr[i, 1] = item
    np.savez_compressed(path, arr=arr)
    return path


def test_hdmap_load_and_query(tmp_path: Path) -> None:
    hdmap = HDMap.load(write_town03_map(tmp_path))
    assert hdmap.num_polylines == 4 and hdmap.town == "Town03"
    near = hdmap.query(np.array([100.0, 200.0]), 20.0)
    kinds = sorted(MAP_TYPES[k] for _, k in near)
    assert kinds == ["Broken", "Center", "StopSign"]
    centre = next(p for p, k in near if MAP_TYPES[k] == "Center")
    assert len(centre) == 41 and centre[0, 0] == 80.0 and centre[-1, 0] == 120.0  # |x − 100| ≤ 20 on y = 200
    stop = next(p for p, k in near if MAP_TYPES[k] == "StopSign")
    assert len(stop) == 6 and np.array_equal(stop[0], stop[-1])  # 5 corners, closed


def test_map_elements_in_the_ego_frame(corpus_copy: Path) -> None:
    write_town03_map(corpus_copy / "maps")
    ds = ClipDataset(corpus_copy, clips=[str(CLIP_A)], cameras=(), lidar=False, map_radius=20.0)
    s = ds[0]
    lines = {MAP_TYPES[k]: p for p, k in zip(s["map_polylines"], s["map_types"], strict=True)}
    assert set(lines) == {"Center", "Broken", "StopSign"}
    # Ego at (100, 200), CARLA yaw 30°. World point (110, 200): offset (10, 0) ⇒ CARLA ego
    # (10·cos 30°, −10·sin 30°) = (8.660, −5.0) ⇒ ISO (8.660, +5.0): ahead and to the left.
    centre = lines["Center"]
    i = int(np.argmin(np.abs(centre[:, 0] - 8.660) + np.abs(centre[:, 1] - 5.0)))
    assert centre[i] == pytest.approx([10 * math.cos(math.radians(30)), 5.0, 0.0], abs=1e-4)
    assert (np.hypot(centre[:, 0], centre[:, 1]) <= 20.0 + 1e-6).all()


def test_missing_map_names_the_expected_file(corpus_copy: Path) -> None:
    ds = ClipDataset(corpus_copy, clips=[str(CLIP_A)], cameras=(), lidar=False, map_radius=20.0)
    with pytest.raises(B2DFormatError, match="Town03_HD_map.npz"):
        ds[0]


class _RunsCode:
    """Pickles as a call of ``func(*args)``: what a malicious map would hold."""

    def __init__(self, func, *args) -> None:
        self.func, self.args = func, args

    def __reduce__(self):
        return self.func, self.args


def _hostile_map(path: Path, payload: object) -> Path:
    arr = np.empty((1, 2), dtype=object)
    arr[0, 0], arr[0, 1] = 1, {-1: [payload]}
    np.savez_compressed(path, arr=arr)
    return path


@pytest.mark.parametrize("kind", ["eval", "system"])
def test_hostile_map_is_refused_and_runs_nothing(tmp_path: Path, kind: str) -> None:
    import builtins
    import os

    marker = tmp_path / "pwned"
    if kind == "eval":
        payload, refused = _RunsCode(builtins.eval, f"open({str(marker)!r}, 'w').close()"), "builtins.eval"
    else:
        payload, refused = _RunsCode(os.system, f"touch '{marker}'"), f"{os.system.__module__}.system"  # posix.system
    path = _hostile_map(tmp_path / "Town03_HD_map.npz", payload)
    with pytest.raises(B2DFormatError, match=f"Town03_HD_map.npz: refused to unpickle '{refused}'"):
        HDMap.load(path)
    assert not marker.exists()  # the old np.load(allow_pickle=True) created it before failing on the layout


def test_hostile_map_through_the_dataset_runs_nothing(corpus_copy: Path) -> None:
    import builtins

    marker = corpus_copy / "pwned"
    (corpus_copy / "maps").mkdir()
    _hostile_map(corpus_copy / "maps" / "Town03_HD_map.npz", _RunsCode(builtins.exec, f"open({str(marker)!r}, 'w')"))
    ds = ClipDataset(corpus_copy, clips=[str(CLIP_A)], cameras=(), lidar=False, map_radius=20.0)
    with pytest.raises(B2DFormatError, match="refused to unpickle 'builtins.exec'"):
        ds[0]
    assert not marker.exists()


def test_safe_reader_reads_what_numpy_reads(tmp_path: Path) -> None:
    from b2d_data.codecs.object_npz import load_object_npz

    path = write_town03_map(tmp_path)
    with np.load(path, allow_pickle=True) as npz:  # our own file: the trusted reference
        expected = npz["arr"]
    got = load_object_npz(path, "arr")
    assert got.dtype == object and got.shape == (2, 2)
    # Same road ids and road dicts, element by element (the numpy float64 x values included).
    assert got[:, 0].tolist() == [1, 2] and got.tolist() == expected.tolist()
    assert type(got[0, 1][-1][0]["Points"][0][0][0]) is np.float64


def test_plain_npz_array_reads_without_pickle(tmp_path: Path) -> None:
    from b2d_data.codecs.object_npz import load_object_npz

    np.savez(tmp_path / "x.npz", arr=np.arange(6, dtype=np.int16).reshape(2, 3))
    got = load_object_npz(tmp_path / "x.npz", "arr")
    assert got.dtype == np.int16 and got.tolist() == [[0, 1, 2], [3, 4, 5]]
