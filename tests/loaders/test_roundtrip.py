"""A corpus written by ClipWriter round-trips through ClipDataset: every modality, every frame conversion."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from b2d_data import ClipDataset
from b2d_data.codecs import layout
from b2d_data.codecs.depth import depth_to_png_pixels
from b2d_data.codecs.jpeg import read_jpeg
from b2d_data.format.rig import camera
from b2d_data.loaders import BOX_CLASSES, collate, worker_init_fn
from b2d_data.loaders.sample import project_points
from b2d_data.loaders.synthetic import project_world_point, scene_anno, synthetic_record
from b2d_data.splits import SplitEntry, SplitManifest

from .conftest import CLIP_A, CLIP_B, SPEC_A, SPEC_B


@pytest.fixture(scope="module")
def dataset(corpus: Path) -> ClipDataset:
    return ClipDataset(corpus, radar=True, depth=True, semantic=True, instance=True, expert=True)


def _sample(ds: ClipDataset, clip: str, frame: int) -> dict:
    for i in range(len(ds)):
        if ds.frame_key(i) == (clip, frame):
            return ds[i]
    raise AssertionError(f"{clip} frame {frame} not in the dataset")


def test_lengths_and_filters(corpus: Path, tmp_path: Path) -> None:
    assert len(ClipDataset(corpus, cameras=())) == 12 + 6
    assert ClipDataset(corpus, scenarios=["HardBreakRoute"], cameras=()).clip_names == [str(CLIP_B)]
    assert ClipDataset(corpus, towns=["Town03"], cameras=()).clip_names == [str(CLIP_A)]
    assert len(ClipDataset(corpus, weathers=[3], cameras=())) == 6
    assert len(ClipDataset(corpus, frame_stride=5, cameras=())) == 3 + 2  # frames 0, 5, 10 and 0, 5
    # A split manifest (object or JSON file) selects its part; XML type names select their clip prefix.
    manifest = SplitManifest("tiny", train=(SplitEntry(str(CLIP_A)),), val=(SplitEntry(str(CLIP_B)),))
    assert ClipDataset(corpus, split=manifest, part="val", cameras=()).clip_names == [str(CLIP_B)]
    path = manifest.save(tmp_path / "tiny.json")
    assert ClipDataset(corpus, split=path, part="train", cameras=()).clip_names == [str(CLIP_A)]
    assert ClipDataset(corpus, scenarios=["SequentialLaneChange"], cameras=()).clip_names == []
    # A single clip folder can be opened directly.
    assert len(ClipDataset(corpus / str(CLIP_B), cameras=())) == 6


def test_images_and_dense_labels_decode_to_what_was_written(corpus: Path, dataset: ClipDataset) -> None:
    for spec, clip in ((SPEC_A, CLIP_A), (SPEC_B, CLIP_B)):
        s = _sample(dataset, str(clip), 3)
        rec = synthetic_record(spec, 3)
        assert s["images"].shape == (6, 36, 64, 3) and s["images"].dtype == np.uint8
        for c, cam in enumerate(s["camera_names"]):
            written = rec.cameras[cam]
            # The loader returns exactly the decoded JPEG, which is the written image within JPEG q20 error.
            assert np.array_equal(s["images"][c], read_jpeg(layout.image_path(corpus / str(clip), "rgb", cam, 3)))
            assert np.abs(s["images"][c].astype(int) - written.rgb.astype(int)).mean() < 6.0
            assert np.array_equal(s["semantic"][c], written.semantic)
            assert np.array_equal(s["instance"][c], written.instance)
            if spec is SPEC_B:  # v0.0.4: float depth npz, exact
                assert np.array_equal(s["depth"][c], written.depth)
            else:  # v0: uint8 metres PNG, i.e. clip(round(depth), 0, 255); the 1000 m sky row reads 255
                assert np.array_equal(s["depth"][c], depth_to_png_pixels(written.depth).astype(np.float32))
                assert (s["depth"][c][0] == 255).all()


def test_lidar_radar_expert(dataset: ClipDataset) -> None:
    s = _sample(dataset, str(CLIP_A), 4)
    rec = synthetic_record(SPEC_A, 4)
    # LAZ keeps 1 mm steps; the ISO frame negates y.
    expected = rec.lidar * np.array([1.0, -1.0, 1.0])
    assert s["lidar"].dtype == np.float32 and np.abs(s["lidar"] - expected).max() <= 0.0005 + 1e-4
    # Radar: 4 radars × 3 detections (radar_back_left holds none). RADAR_FRONT sits at (2.27, 0, 0.48), yaw 0:
    # a detection (d, alt, az) is CARLA ego (2.27 + d·cos alt·cos az, d·cos alt·sin az, 0.48 + d·sin alt);
    # ISO negates y.
    assert len(s["radar"]) == 12 and bool(s["radar_valid"])
    front = rec.radar["radar_front"].astype(np.float64)
    d, alt, az = front[:, 0], front[:, 1], front[:, 2]
    hand = np.stack([2.27 + d * np.cos(alt) * np.cos(az), -d * np.cos(alt) * np.sin(az), 0.48 + d * np.sin(alt)], 1)
    assert np.allclose(s["radar"][s["radar_sensor"] == 0], hand, atol=1e-4)
    assert np.allclose(s["radar_velocity"][s["radar_sensor"] == 0], front[:, 3])
    assert np.array_equal(s["expert_feature"], rec.expert_assessment[:-2])
    assert s["expert_value"] == pytest.approx(4.5) and int(s["expert_action"]) == 4


def test_boxes_ego_and_targets_in_the_iso_frame(dataset: ClipDataset) -> None:
    f = 2
    s = _sample(dataset, str(CLIP_A), f)
    names = [BOX_CLASSES[c] for c in s["box_classes"]]
    assert names == ["vehicle", "walker", "vehicle", "traffic_light", "traffic_sign", "traffic_sign"]
    boxes = s["boxes"]
    # Lead vehicle: 12 m ahead, centre 0.75 m up, half extents (2.4, 1.0, 0.75) ⇒ 4.8 × 2.0 × 1.5, same heading,
    # moving at the ego's 5 m/s.
    assert boxes[0] == pytest.approx([12.0, 0.0, 0.75, 4.8, 2.0, 1.5, 0.0], abs=1e-4)
    assert s["box_velocity"][0] == pytest.approx([5.0, 0.0], abs=1e-4)
    # Walker: starts 8 m ahead and 4 m to the left (CARLA y = −4), walks right at 1.5 m/s; the ego drives 0.5 m per
    # frame. At frame 2: x = 8 − 1.0 = 7.0, ISO y = 4 − 0.3 = 3.7; yaw +90° CARLA ⇒ −π/2; stored speed 0 ⇒ the
    # finite difference gives ISO velocity (0, −1.5).
    assert boxes[1] == pytest.approx([7.0, 3.7, 0.9, 0.6, 0.6, 1.8, -math.pi / 2], abs=1e-4)
    assert s["box_velocity"][1] == pytest.approx([0.0, -1.5], abs=1e-3)
    # Static vehicle: placed 20 m ahead, 3.5 m right, yaw +90°; its prop rotation says 0° but world2vehicle wins.
    assert boxes[2] == pytest.approx([19.0, -3.5, 0.8, 4.4, 1.9, 1.6, -math.pi / 2], abs=1e-4)
    # Dirt debris: stored half extents (0.5, 2.0, 0.05) are swapped ⇒ 4.0 × 1.0 × 0.1.
    assert boxes[5][3:6] == pytest.approx([4.0, 1.0, 0.1])
    # Trigger volumes of the light and the stop sign (half extents 1.5, 2.0, 1.0 ⇒ 3 × 4 × 2, yaw +90° ⇒ −π/2).
    assert s["trigger_volumes"][:, 3:] == pytest.approx(np.array([[3.0, 4.0, 2.0, -math.pi / 2]] * 2), abs=1e-4)
    assert s["trigger_types"].tolist() == [0, 1] and s["trigger_affects_ego"].tolist() == [True, False]
    # Ego: CARLA yaw 30° ⇒ compass yaw in ISO −30°; IMU vectors: acceleration (0.5, 0.25, 9.81) ⇒ (0.5, −0.25, 9.81),
    # angular velocity (0.01, 0.02, 0.03) ⇒ (−0.01, 0.02, −0.03); size 2·(2.451, 1.064, 0.755).
    assert float(s["ego_compass_yaw"]) == pytest.approx(-math.radians(30), abs=1e-6)
    assert s["ego_accel"] == pytest.approx([0.5, -0.25, 9.81])
    assert s["ego_angular_velocity"] == pytest.approx([-0.01, 0.02, -0.03])
    assert s["ego_size"] == pytest.approx([4.902, 2.128, 1.51])
    # Route targets are 10 / 20 / 50 m straight ahead of the exact pose; the GNSS fix is 1.4 m behind.
    assert s["target_point"] == pytest.approx([10.0, 0.0], abs=1e-4)
    assert s["command_near_xy"] == pytest.approx([20.0, 0.0], abs=1e-4)
    assert s["command_far_xy"] == pytest.approx([50.0, 0.0], abs=1e-4)
    assert s["ego_gnss_xy"] == pytest.approx([-1.4, 0.0], abs=1e-4)
    assert int(s["command"]) == 4 and s["control"] == pytest.approx([0.5, 0.1, 0.0, 0.0])


def test_waypoints(dataset: ClipDataset) -> None:
    # 5 m/s, stride 5 frames (0.5 s) ⇒ 2.5 m per waypoint straight ahead. Clip A has frames 0..11.
    s = _sample(dataset, str(CLIP_A), 1)
    assert s["future_waypoints"][:2] == pytest.approx(np.array([[2.5, 0.0], [5.0, 0.0]]), abs=1e-4)
    assert s["future_valid"].tolist() == [True, True, False, False, False, False]  # frames 6, 11 exist; 16 does not
    s = _sample(dataset, str(CLIP_A), 11)
    # Past waypoints (oldest first) at frames −9, −4, 1, 6 ⇒ only 1 and 6 exist: −5 m and −2.5 m.
    assert s["past_valid"].tolist() == [False, False, True, True]
    assert s["past_waypoints"][2:] == pytest.approx(np.array([[-5.0, 0.0], [-2.5, 0.0]]), abs=1e-4)
    # The same holds for clip B, driving at yaw −120°: waypoints are relative to the current ego.
    s = _sample(dataset, str(CLIP_B), 0)
    assert s["future_waypoints"][0] == pytest.approx([2.5, 0.0], abs=1e-4) and s["future_yaw"][0] == pytest.approx(0)


def test_projected_boxes_land_on_the_marked_pixels(dataset: ClipDataset) -> None:
    hits = 0
    for spec, clip in ((SPEC_A, CLIP_A), (SPEC_B, CLIP_B)):
        for f in (0, 4):
            s = _sample(dataset, str(clip), f)
            anno = scene_anno(spec, f)
            for c, cam in enumerate(s["camera_names"]):
                uv, depth = project_points(s["boxes"][:, :3], s["cam2ego"][c], s["intrinsics"][c])
                for m, box in enumerate(anno["bounding_boxes"][1:]):
                    # The fixture drew a marker where tools/utils.py's world2cam + K projection puts the box centre.
                    u, v, d = project_world_point(anno, camera(cam).sensor_id, np.asarray(box["center"]))
                    if not (d > 0.5 and 0 <= u < 64 and 0 <= v < 36):
                        continue
                    assert depth[m] == pytest.approx(d, abs=1e-3)
                    assert uv[m] == pytest.approx([u, v], abs=1e-2)
                    assert s["images"][c][int(round(v)), int(round(u))].mean() > 200  # the marker is there
                    hits += 1
    assert hits >= 10


def test_carla_frame_keeps_raw_values(corpus: Path) -> None:
    ds = ClipDataset(corpus, clips=[str(CLIP_A)], frame="carla", cameras=("front",))
    s = ds[2]
    rec = synthetic_record(SPEC_A, 2)
    assert np.abs(s["lidar"] - rec.lidar).max() <= 0.0006
    # Walker in CARLA's left-handed ego: y = −3.7 (left is negative), yaw +π/2 (clockwise).
    assert s["boxes"][1] == pytest.approx([7.0, -3.7, 0.9, 0.6, 0.6, 1.8, math.pi / 2], abs=1e-4)
    # cam2ego still maps OpenCV camera axes: the front camera's optical axis is CARLA ego +x.
    assert s["cam2ego"][0][:3, 2] == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)


def test_gnss_pose_source(corpus: Path) -> None:
    ds = ClipDataset(corpus, clips=[str(CLIP_A)], pose_source="gnss", cameras=(), lidar=False)
    s = ds[3]
    # Seen from the GNSS fix (1.4 m behind the exact pose) the target is 11.4 m ahead; waypoints are unchanged
    # because every GNSS fix is offset the same way.
    assert s["target_point"] == pytest.approx([11.4, 0.0], abs=1e-4)
    assert s["future_waypoints"][0] == pytest.approx([2.5, 0.0], abs=1e-4)


def test_dataloader_with_workers(corpus: Path) -> None:
    ds = ClipDataset(corpus, cameras=("front", "back"))
    loader = DataLoader(ds, batch_size=4, num_workers=2, collate_fn=collate, worker_init_fn=worker_init_fn)
    seen = 0
    for batch in loader:
        assert batch["images"].dtype == torch.uint8 and batch["images"].shape[1:] == (2, 36, 64, 3)
        assert isinstance(batch["lidar"], list) and batch["lidar"][0].shape[1] == 3
        seen += batch["batch_size"]
    assert seen == len(ds) == 18
    padded = functools.partial(collate, pad=True)([ds[0], ds[1]])
    assert padded["boxes"].shape == (2, 6, 7) and padded["boxes_mask"].all()


def test_plain_dataloader_with_default_collate(corpus: Path) -> None:
    # Issue 10: torch's default collate used to stack the variable-size LiDAR and boxes and crash in the workers
    # ("Trying to resize storage that is not resizable"); now they come back as per-sample lists.
    ds = ClipDataset(corpus, cameras=("front",), keep_anno=True)
    singles = [ds[i] for i in range(4)]
    batch = next(iter(DataLoader(ds, batch_size=4, num_workers=2)))
    assert batch["images"].shape == (4, 1, 36, 64, 3)
    assert [t.shape[0] for t in batch["lidar"]] == [len(s["lidar"]) for s in singles]
    assert torch.equal(batch["boxes"][2], torch.from_numpy(np.asarray(singles[2]["boxes"])))
    assert batch["frame"].tolist() == [s["frame"] for s in singles]
    assert [a["bounding_boxes"][0]["id"] for a in batch["anno"]] == [s["anno"]["bounding_boxes"][0]["id"] for s in singles]
    # Samples are still plain numpy to anyone indexing the dataset.
    assert isinstance(singles[0]["lidar"], np.ndarray) and singles[0]["lidar"].shape[1] == 3


def test_loader_helper_pads_ragged_fields(corpus: Path) -> None:
    ds = ClipDataset(corpus, clips=[str(CLIP_A)], cameras=(), lidar=False)
    batches = list(ds.loader(batch_size=5, num_workers=0, pad=True))
    assert [b["batch_size"] for b in batches] == [5, 5, 2]  # clip A has 12 frames
    first = batches[0]
    n = [len(ds[i]["boxes"]) for i in range(5)]
    assert first["boxes"].shape == (5, max(n), 7)
    assert first["boxes_mask"].sum(dim=1).tolist() == n
