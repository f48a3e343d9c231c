"""``b2d-verify ROOT --deep``: a freshly collected clip agrees with itself; corrupted boxes are reported.

The clip is a generated NoScenario route of the default town cut to its first 30 m, which passes a stop sign,
collected at 320×180 with a coarse LiDAR so that it takes seconds.
"""

from __future__ import annotations

import math
import shutil
import tarfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from b2d_data.cli import verify as verify_cli
from b2d_data.cli.collect import main as collect_main
from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import read_anno, write_anno
from b2d_data.codecs.labels_png import read_instance_png
from b2d_data.format.semantic import SemanticTag as T
from b2d_data.loaders.cross_check import NEAR, project_box

ROUTE_LENGTH = 30.0  # m


@pytest.fixture(scope="module")
def clean_corpus(tmp_path_factory) -> Path:
    from b2d_data.collection.towns import TownSource, load_map
    from b2d_data.scenarios import placement
    from b2d_data.scenarios.route_xml import write_routes

    folder = tmp_path_factory.mktemp("town")
    town = TownSource(preset="all").materialise(folder)
    (route,) = placement.make_routes(load_map(town), "NoScenario", 1, seed=0, params="bench2drive220")
    start = route.waypoints[0]
    keep = tuple(p for p in route.waypoints if math.hypot(p.x - start.x, p.y - start.y) <= ROUTE_LENGTH)
    write_routes([replace(route, waypoints=keep)], folder / "routes.xml")
    out = tmp_path_factory.mktemp("deep") / "data"
    args = ["--routes", str(folder / "routes.xml"), "--xodr", str(town.xodr), "--scenario", "NoScenario", "--n", "1",
            "--seed", "7", "--out", str(out), "--width", "320", "--height", "180", "--lidar-azimuth-steps", "90",
            "--encode-workers", "0", "--workers", "1", "--no-progress"]  # fmt: skip
    assert collect_main(args) == 0
    return out


def _clip(root: Path) -> Path:
    (clip,) = [p for p in root.iterdir() if (p / "anno").is_dir()]
    return clip


def _deep(root: Path, capsys, *extra: str) -> tuple[int, str]:
    rc = verify_cli.main([str(root), "--deep", "--no-progress", "--max-lines", "1000", *extra])
    return rc, capsys.readouterr().out


def test_a_collected_clip_agrees_with_itself(clean_corpus, capsys):
    rc, out = _deep(clean_corpus, capsys)
    assert rc == 0, out
    (line,) = [ln for ln in out.splitlines() if ln.startswith("OK ")]
    # Every kind of comparison ran: the LiDAR counts, the vehicles and the stop sign the route passes.
    counts = dict(part.rsplit(" ", 1) for part in line.split("; ", 1)[1].split(", "))
    assert int(counts["num_points"]) > 100 and int(counts["actor_pixels"]) > 50 and int(counts["sign_pixels"]) > 10
    assert out.rstrip().endswith("1 of 1 clips consistent; 0 with disagreements")


def _most_seen(clip: Path, tag_ok) -> tuple[int, str]:
    """(frame, box id) of the box whose object shows the most front-camera pixels of an accepted tag."""
    best = (0, -1, "")
    for path in sorted((clip / "anno").glob("*.json.gz")):
        frame = int(path.name[:5])
        anno = read_anno(path)
        tags, ids = read_instance_png(layout.image_path(clip, "instance", "front", frame))
        for box in anno["bounding_boxes"][1:]:
            n = int(np.count_nonzero((ids == int(box["id"])) & tag_ok(tags)))
            if n > best[0]:
                best = (n, frame, box["id"])
    assert best[0] > 100, best
    return best[1], best[2]


def _edit_box(clip: Path, frame: int, box_id: str, edit) -> None:
    path = layout.anno_path(clip, frame)
    anno = read_anno(path)
    (box,) = [b for b in anno["bounding_boxes"] if b["id"] == box_id]
    edit(box)
    write_anno(path, anno)


def _up(metres: float):
    def edit(box: dict) -> None:
        for key in ("location", "center"):
            box[key][2] += metres
        for key in ("world2vehicle", "world2sign"):
            if key in box:  # world → object moves down by as much: the object frame went up
                box[key][2][3] -= metres

    return edit


def test_corrupted_boxes_are_reported(clean_corpus, tmp_path, capsys):
    root = tmp_path / "data"
    shutil.copytree(_clip(clean_corpus), root / _clip(clean_corpus).name)
    clip = _clip(root)
    car_frame, car = _most_seen(clip, lambda tags: (tags >= T.CAR) & (tags <= T.BICYCLE))
    sign_frame, sign = _most_seen(clip, lambda tags: tags == T.TRAFFIC_SIGN)
    # The best-seen car and the stop sign moved 2 m up (the car's body and the plate are < 2 m tall: none of their
    # pixels stays in the moved box); one more car's num_points off by one.
    _edit_box(clip, car_frame, car, _up(2.0))
    _edit_box(clip, sign_frame, sign, _up(2.0))
    other_frame, other = next(
        (frame, box) for frame in range(100) for box in read_anno(layout.anno_path(clip, frame))["bounding_boxes"][1:]
        if box.get("num_points", 0) > 0 and frame not in (car_frame, sign_frame)
    )  # fmt: skip
    _edit_box(clip, other_frame, other["id"], lambda b: b.update(num_points=b["num_points"] + 1))
    rc, out = _deep(root, capsys)
    assert rc == 1
    assert out.splitlines()[0].startswith(f"DISAGREE {clip.name}:")
    lines = [ln.strip() for ln in out.splitlines() if ln.startswith("  ")]
    assert any(ln.startswith(f"actor_pixels frame {car_frame:05d} box {car} CAM_FRONT:") for ln in lines), out
    assert any(ln.startswith(f"sign_pixels  frame {sign_frame:05d} box {sign} CAM_FRONT:") for ln in lines), out
    expected = f"num_points   frame {other_frame:05d} box {other['id']} LIDAR_TOP: num_points " \
               f"{other['num_points'] + 1}, the LAZ file gives {other['num_points']}"  # fmt: skip
    assert expected in lines, out
    # Nothing else disagrees: the moved boxes only in the frames they were moved in (the car's LiDAR count too).
    for ln in lines:
        assert f"frame {car_frame:05d} box {car} " in ln or f"frame {sign_frame:05d} box {sign} " in ln \
            or ln == expected, ln  # fmt: skip
    assert out.rstrip().endswith("0 of 1 clips consistent; 1 with disagreements")


def test_archived_clips_are_checked_too(clean_corpus, tmp_path, capsys):
    clip = _clip(clean_corpus)
    with tarfile.open(tmp_path / f"{clip.name}.tar.gz", "w:gz") as tar:
        tar.add(clip, arcname=clip.name)
    rc, out = _deep(tmp_path, capsys)
    assert rc == 0 and out.startswith(f"OK       {clip.name}: "), out


def test_deep_needs_a_clip_that_exists_and_something_to_check(clean_corpus, capsys):
    rc, out = _deep(clean_corpus, capsys, "--clip", "Accident_Town100_Route9_Weather1")
    assert rc == 1 and "MISSING  Accident_Town100_Route9_Weather1" in out
    assert verify_cli.main([str(clean_corpus), "--no-progress"]) == 2
    assert "pass --list FILE.json and/or --deep" in capsys.readouterr().err


def test_box_projection_by_hand():
    k = np.array([[100.0, 0.0, 50.0], [0.0, 100.0, 50.0], [0.0, 0.0, 1.0]])
    # A 2 m cube 9…11 m in front of the camera: its near face spans u, v = 50 ± 100 · 1 / 9 = 38.9 … 61.1.
    cube = np.array([(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (9.0, 11.0)])
    region = project_box(cube, k, 100, 100)
    ys, xs = np.nonzero(region.mask)
    assert (xs.min() + region.x0, xs.max() + region.x0) == (39, 61)
    assert (ys.min() + region.y0, ys.max() + region.y0) == (39, 61)
    assert region.near == 9.0 and region.in_image == pytest.approx(1.0, abs=0.1)
    # Behind the camera: no region. Around it (x, y ±0.5, z −1…1): clipped at NEAR, its corners there project to
    # 50 ± 100 · 0.5 / 0.1 = −450 … 550 (kept within −4 W … 5 W = −400 … 500), so it covers the whole image, which
    # holds 100² / 900² of that outline.
    assert project_box(cube - [0.0, 0.0, 20.0], k, 100, 100) is None
    around = project_box(cube * [0.5, 0.5, 1.0] - [0.0, 0.0, 10.0], k, 100, 100)
    assert around.near == pytest.approx(NEAR) and around.mask.shape == (100, 100) and around.mask.all()
    assert around.in_image == pytest.approx(100**2 / 900**2)


def test_slack_reaches_into_the_image_from_a_box_just_beyond_its_edge():
    k = np.array([[100.0, 0.0, 50.0], [0.0, 100.0, 50.0], [0.0, 0.0, 1.0]])
    # A thin box 10 m ahead from x 4.97 m on: u = 50 + 100 · 4.97 / 10 = 99.7, just right of the last pixel
    # centre (99) of a 100 px image; v = 50 ± 100 · 1 / 10 = 40 … 60. None of it covers a pixel of the image, but
    # the 1 px slack reaches column 99, rows 39 … 61 (as for a box inside the image).
    edge = np.array([(x, y, z) for x in (4.97, 7.0) for y in (-1.0, 1.0) for z in (10.0, 10.001)])
    region = project_box(edge, k, 100, 100)
    assert region is not None and not region.mask.any()
    rows, cols = np.nonzero(region.grown)
    assert set((cols + region.x0).tolist()) == {99}
    assert (rows.min() + region.y0, rows.max() + region.y0) == (39, 61)
