"""``ClipDataset``: per-frame training samples over a Bench2Drive corpus (ours or the released clips)."""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from torch.utils.data import DataLoader, Dataset
from torch.utils.data._utils.collate import default_collate_fn_map

from b2d_data import coords
from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import read_anno
from b2d_data.codecs.depth import read_depth_npz, read_depth_png
from b2d_data.codecs.expert_npz import read_expert, split_expert
from b2d_data.codecs.format_info import read_format_info
from b2d_data.codecs.jpeg import read_jpeg
from b2d_data.codecs.labels_png import read_instance_png, read_semantic_png
from b2d_data.codecs.laz import read_laz
from b2d_data.codecs.radar_h5 import RADAR_DATASETS, read_radar
from b2d_data.format import expert_feature
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.expert_actions import action_control
from b2d_data.format.version import FORMAT_FILE
from b2d_data.format.names import canonical_clip_prefix
from b2d_data.format.rig import RADARS_V0, camera
from b2d_data.loaders.collate import Sample, collate, collate_samples, mark_variable_fields
from b2d_data.loaders.hdmap import find_hdmap, load_hdmap_cached
from b2d_data.loaders.index import CorpusIndex, open_index, presence_column
from b2d_data.loaders.sample import (
    OnError,
    SampleOptions,
    box_fields,
    command_fields,
    ego_fields,
    pose_track,
    reference_world2ego,
    waypoint_fields,
)
from b2d_data.splits import PARTS, SplitManifest, corpus_manifest

logger = logging.getLogger(__name__)

_RADAR_SENSOR = {r.dataset: r.sensor_id for r in RADARS_V0}
_EXPECTED_ERRORS = (B2DFormatError, OSError, ValueError, KeyError, TypeError, IndexError, AttributeError)


@dataclass(frozen=True)
class BadFrame:
    """A frame that could not be loaded (``on_error="skip"``): what the dataset returns in its place."""

    index: int
    clip: str
    frame: int
    error: str


# A batch whose first item is a skipped frame must reach the same collate as one that starts with a sample.
default_collate_fn_map[BadFrame] = collate_samples


def worker_init_fn(worker_id: int) -> None:
    """DataLoader ``worker_init_fn``: one thread per worker for OpenCV and torch (the workers are the parallelism)."""
    cv2.setNumThreads(0)
    import torch

    torch.set_num_threads(1)


class ClipDataset(Dataset):
    """Per-frame samples from a corpus root (indexed by ``b2d-index``) or from one clip folder.

    Filters: ``split`` (a :class:`SplitManifest` or a manifest / official list JSON) with ``part``
    (``train``, ``val``, ``all``), or ``split="train"`` / ``"val"`` for that part of the corpus's own manifest
    (the one JSON in ``<root>/splits/``, as ``b2d-collect --preset`` writes), ``scenarios`` (clip prefixes or XML types), ``towns``, ``weathers`` (ids), ``clips``
    (names); ``frame_stride`` keeps every n-th frame. What a sample holds is set by :class:`SampleOptions`
    (pass ``options=`` or its fields as keywords, e.g. ``cameras=("front",), radar=True``).

    Keys of a sample (numpy; ``b2d_data.loaders.collate`` batches them). Frame = ``iso`` (right-handed
    ISO 8855 ego: x forward, y left, z up, yaw counter-clockwise) unless ``frame="carla"``:

    - ``clip``, ``frame``, ``index``, ``scenario``, ``town``, ``weather_id`` (−1 unknown)
    - ``images`` (C, H, W, 3) uint8 RGB, ``intrinsics`` (C, 3, 3), ``cam2ego`` (C, 4, 4) OpenCV camera → ego,
      ``camera_names`` (folder names) — cameras of different sizes give a list instead of one array
    - ``lidar`` (N, 3) float32 ego frame
    - ``radar`` (R, 3) ego frame, ``radar_velocity`` (R,), ``radar_sensor`` (R,) index into RADAR_DATASETS,
      ``radar_valid`` (False when the clip has no radar file for the frame, as in some released clips)
    - ``boxes`` (M, 7) [x, y, z, l, w, h, yaw] full sizes, ``box_classes`` (index into BOX_CLASSES),
      ``box_ids``, ``box_velocity`` (M, 2) ground velocity in ego axes, ``box_num_points``,
      ``box_light_state`` (−1 unless a light), ``box_static``; ``trigger_volumes`` (T, 7), ``trigger_types``
      (index into TRIGGER_TYPES), ``trigger_light_state``, ``trigger_affects_ego``
    - ``ego_pose`` (4, 4) exact ego → world (iso world = CARLA world with y negated), ``ego_speed``,
      ``ego_accel`` (3,), ``ego_angular_velocity`` (3,), ``ego_size`` (l, w, h), ``ego_compass_yaw`` (NaN → π
      fixed), ``ego_gnss_xy`` (where the GNSS fix lies in the exact ego frame)
    - ``control`` [throttle, steer (CARLA sign: + = right), brake, reverse], ``should_brake``, ``only_ap_brake``
    - ``command`` (RoadOption of the target), ``target_point`` (2,), ``command_near``/``command_far`` and
      ``command_near_xy``/``command_far_xy`` — points in the ego frame of ``pose_source``
    - ``future_waypoints`` / ``past_waypoints`` (K, 2), ``future_yaw`` / ``past_yaw`` (K,), ``future_valid`` /
      ``past_valid`` (K,) — ego poses every ``waypoint_stride`` frames, in the current ego frame
    - optional: ``depth`` (C, H, W) float32 m, ``semantic`` (C, H, W) uint8 tags, ``instance`` (C, H, W) uint16
      ids, ``map_polylines`` (list of (n, 3)) with ``map_types`` (index into MAP_TYPES), ``anno`` (raw dict)
    - with ``expert=True``: ``expert_feature`` (1536,) float32 (Think2Drive's latent in released clips, the BEV
      raster of :mod:`b2d_data.format.expert_feature` in ours), ``expert_value``, ``expert_action`` (0–38) and
      ``expert_control`` [throttle, steer, brake, reverse] that action decodes to (format.md §2.8 table). With
      ``expert_bev=True`` (implies ``expert``) ``expert_feature`` is the (6, 16, 16) raster instead; a clip whose
      ``b2d_format.json`` does not record that layout (any released Bench2Drive clip) raises ``B2DFormatError``.

    ``index``: ``auto`` reads ``<root>/.b2d_index`` (building it once when absent), ``update`` rescans new or
    changed clips first, ``memory`` never writes, or pass a :class:`CorpusIndex`. HD maps are looked up in
    ``maps_dir``, ``<root>/maps`` and ``<root>/../maps`` (Bench2Drive's separate maps folder).

    Ego pose choice: boxes, LiDAR and the map are relative to the exact ego pose (``bounding_boxes[0].world2ego``);
    waypoints and route targets use ``pose_source`` (``exact`` by default; ``gnss`` reproduces what an agent sees
    at test time: GNSS x, y and compass). With ``on_error="skip"`` a frame that fails to load is logged, appended
    to ``bad_frames`` (and to ``error_log`` as JSON lines, which also works from DataLoader workers) and its
    :class:`BadFrame` record is returned instead of a sample; ``collate`` drops and counts it, also as torch's
    default collate of a plain ``DataLoader(dataset, batch_size=...)``.
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        *,
        split: SplitManifest | str | os.PathLike[str] | None = None,
        part: str = "all",
        scenarios: Iterable[str] | None = None,
        towns: Iterable[str] | None = None,
        weathers: Iterable[int] | None = None,
        clips: Iterable[str] | None = None,
        frame_stride: int = 1,
        options: SampleOptions | None = None,
        on_error: OnError = "raise",
        error_log: str | os.PathLike[str] | None = None,
        index: str | CorpusIndex = "auto",
        maps_dir: str | os.PathLike[str] | None = None,
        **option_overrides: Any,
    ) -> None:
        opts = options or SampleOptions()
        if option_overrides:
            unknown = set(option_overrides) - {f.name for f in dataclasses.fields(SampleOptions)}
            if unknown:
                raise TypeError(f"unknown ClipDataset option(s) {sorted(unknown)}")
            if "cameras" in option_overrides:
                option_overrides["cameras"] = tuple(option_overrides["cameras"])
            opts = dataclasses.replace(opts, **option_overrides)
        if on_error not in ("raise", "skip"):
            raise ValueError(f"on_error must be 'raise' or 'skip', got {on_error!r}")
        self.options = opts
        self.on_error = on_error
        self.error_log = Path(error_log) if error_log is not None else None
        self.bad_frames: list[BadFrame] = []
        self._cameras = opts.camera_folders()
        self._sensor_ids = tuple(camera(c).sensor_id for c in self._cameras)

        root = Path(root)
        presence = ["anno", "radar"] + [f"depth_npz_{c}" for c in self._cameras if c != "top_down"]
        pose_cols = ["ego_x", "ego_y", "ego_yaw"] if opts.pose_source == "exact" else ["gnss_x", "gnss_y", "theta"]
        wanted_cols = ["clip_id", "frame"] + [presence_column(m) for m in presence] + pose_cols
        idx = index if isinstance(index, CorpusIndex) else open_index(root, index, frame_columns=wanted_cols)
        self.root = idx.root
        self._map_dirs = [Path(maps_dir)] if maps_dir is not None else []
        self._map_dirs += [self.root / layout.MAPS_DIR, self.root.parent / layout.MAPS_DIR]

        clips_t = idx.clips
        names = clips_t.column("name").to_pylist()
        keep = self._select_clips(clips_t, names, split, part, scenarios, towns, weathers, clips)
        # Per-clip metadata as fixed-width numpy arrays: no per-item Python objects for workers to copy-on-write.
        self._clip_name = np.array([n.encode() for n in names] or [b""])
        self._clip_path = np.array([p.encode() for p in clips_t.column("path").to_pylist()] or [b""])
        self._clip_scenario = np.array([s.encode() for s in clips_t.column("scenario").to_pylist()] or [b""])
        self._clip_town = np.array([s.encode() for s in clips_t.column("town").to_pylist()] or [b""])
        self._clip_weather = clips_t.column("weather_id").to_numpy().astype(np.int32)
        self._clip_start = clips_t.column("frame_start").to_numpy().astype(np.int64)
        self._clip_len = clips_t.column("n_frames").to_numpy().astype(np.int64)

        frames_t = idx.frames.select(wanted_cols).combine_chunks()
        self._frame_clip = frames_t.column("clip_id").to_numpy().astype(np.int32)
        self._frame_num = frames_t.column("frame").to_numpy().astype(np.int32)
        self._has = {
            m: frames_t.column(presence_column(m)).to_numpy(zero_copy_only=False).astype(bool) for m in presence
        }
        poses = {c: frames_t.column(c).to_numpy() for c in pose_cols}
        self._track = np.ascontiguousarray(pose_track(poses, opts.pose_source), dtype=np.float64)

        rows = [
            np.arange(self._clip_start[c], self._clip_start[c] + self._clip_len[c], max(1, frame_stride)) for c in keep
        ]
        self._rows = np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64)
        self._clip_ids = np.array(sorted(keep), dtype=np.int32)
        self._cv_pid = -1
        self._expert_bev: dict[int, bool] = {}  # clip → its b2d_format.json records the BEV raster layout

    # ------------------------------------------------------------------------------------------ selection

    def _select_clips(
        self,
        clips_t: Any,
        names: list[str],
        split: SplitManifest | str | os.PathLike[str] | None,
        part: str,
        scenarios: Iterable[str] | None,
        towns: Iterable[str] | None,
        weathers: Iterable[int] | None,
        clips: Iterable[str] | None,
    ) -> list[int]:
        wanted: set[str] | None = None
        if isinstance(split, str) and split in PARTS:
            # split="train": that part of the corpus's own manifest (<root>/splits/, written by b2d-collect --preset)
            if part not in ("all", split):
                raise ValueError(f"split={split!r} selects a part already; part={part!r} contradicts it")
            split, part = corpus_manifest(self.root), split
        if split is not None:
            manifest = split if isinstance(split, SplitManifest) else SplitManifest.load(split)
            wanted = set(manifest.clips(part))  # type: ignore[arg-type]
            missing = sorted(wanted - set(names))
            if missing:
                logger.warning(
                    "%d clips of split %s (%s) are not in %s, e.g. %s",
                    len(missing),
                    manifest.name,
                    part,
                    self.root,
                    missing[:3],
                )
        if clips is not None:
            wanted = set(clips) if wanted is None else wanted & set(clips)
        # XML type names (SequentialLaneChange, T_Junction) select their clip prefixes too.
        scen = {canonical_clip_prefix(s) for s in scenarios} if scenarios is not None else None
        town = set(towns) if towns is not None else None
        weather = {int(w) for w in weathers} if weathers is not None else None
        paths = clips_t.column("path").to_pylist()
        errors = clips_t.column("error").to_pylist()
        scen_col = clips_t.column("scenario").to_pylist()
        town_col = clips_t.column("town").to_pylist()
        weather_col = clips_t.column("weather_id").to_pylist()
        keep: list[int] = []
        for i, name in enumerate(names):
            if wanted is not None and name not in wanted:
                continue
            if (scen is not None and scen_col[i] not in scen) or (town is not None and town_col[i] not in town):
                continue
            if weather is not None and weather_col[i] not in weather:
                continue
            if errors[i]:
                logger.warning("skipping clip %s: %s", name, errors[i])
                continue
            if not paths[i]:
                logger.warning("skipping clip %s: only its archive is present; extract it under %s", name, self.root)
                continue
            keep.append(i)
        return keep

    # ---------------------------------------------------------------------------------------- public API

    def __len__(self) -> int:
        return len(self._rows)

    def loader(
        self, batch_size: int = 1, *, num_workers: int = 0, shuffle: bool = False, pad: bool = False, **kwargs: Any
    ) -> DataLoader:
        """A DataLoader with this dataset's :func:`collate` (drops skipped frames; ``pad=True`` pads ragged fields).

        A plain ``DataLoader(dataset, batch_size=...)`` gives the same batches (torch's default collate hands
        samples to :func:`collate`: variable-size fields as lists, skipped frames dropped); this one also pads on
        request and gives each worker one OpenCV / torch thread. ``kwargs`` go to ``DataLoader``.
        """
        kwargs.setdefault("worker_init_fn", worker_init_fn if num_workers else None)
        kwargs.setdefault("persistent_workers", num_workers > 0)
        return DataLoader(
            self,
            batch_size=batch_size,
            shuffle=shuffle,
            num_workers=num_workers,
            collate_fn=functools.partial(collate, pad=pad),
            **kwargs,
        )

    @property
    def clip_names(self) -> list[str]:
        """Names of the clips this dataset draws frames from."""
        return [self._clip_name[c].decode() for c in self._clip_ids]

    def frame_key(self, index: int) -> tuple[str, int]:
        """(clip name, frame number) of sample ``index`` without loading it."""
        row = int(self._rows[index])
        return self._clip_name[self._frame_clip[row]].decode(), int(self._frame_num[row])

    def __getitem__(self, index: int) -> Sample | BadFrame:
        if self._cv_pid != os.getpid():
            # Decoding parallelism comes from DataLoader workers; OpenCV's own threads would oversubscribe.
            cv2.setNumThreads(0)
            self._cv_pid = os.getpid()
        row = int(self._rows[index])
        try:
            return Sample(mark_variable_fields(self._load(index, row)))
        except _EXPECTED_ERRORS as exc:
            clip = int(self._frame_clip[row])
            err = (
                exc
                if isinstance(exc, B2DFormatError)
                else B2DFormatError(
                    layout.anno_path(self._clip_dir(clip), int(self._frame_num[row])), f"{type(exc).__name__}: {exc}"
                )
            )
            if self.on_error == "raise":
                if err is exc:
                    raise
                raise err from exc
            return self._report(index, row, err)

    # -------------------------------------------------------------------------------------------- loading

    def _clip_dir(self, clip: int) -> Path:
        return self.root / self._clip_path[clip].decode()

    def _report(self, index: int, row: int, err: Exception) -> BadFrame:
        bad = BadFrame(index, self._clip_name[self._frame_clip[row]].decode(), int(self._frame_num[row]), str(err))
        logger.warning("skipping frame %s/%05d: %s", bad.clip, bad.frame, bad.error)
        self.bad_frames.append(bad)
        if self.error_log is not None:
            with open(self.error_log, "a", encoding="utf-8") as f:
                f.write(json.dumps(dataclasses.asdict(bad)) + "\n")
        return bad

    def _load(self, index: int, row: int) -> dict[str, Any]:
        opts, frame_conv = self.options, self.options.frame
        clip = int(self._frame_clip[row])
        frame = int(self._frame_num[row])
        clip_dir = self._clip_dir(clip)
        anno = read_anno(layout.anno_path(clip_dir, frame))
        world2ego = np.asarray(anno["bounding_boxes"][0]["world2ego"], dtype=np.float64)
        sample: dict[str, Any] = {
            "clip": self._clip_name[clip].decode(),
            "frame": frame,
            "index": index,
            "scenario": self._clip_scenario[clip].decode(),
            "town": self._clip_town[clip].decode(),
            "weather_id": int(self._clip_weather[clip]),
        }
        sample.update(ego_fields(anno, frame_conv))
        ref = world2ego if opts.pose_source == "exact" else reference_world2ego(anno, opts.pose_source)
        sample.update(command_fields(anno, ref, frame_conv))
        start, length = int(self._clip_start[clip]), int(self._clip_len[clip])
        sample.update(waypoint_fields(self._clip_track(clip_dir, start, length, row - start), row - start, opts))
        if self._cameras:
            self._load_cameras(sample, anno, clip_dir, frame, row)
        if opts.lidar:
            sample["lidar"] = coords.to_frame_points(read_laz(layout.lidar_path(clip_dir, frame), dtype=np.float32), frame_conv)
        if opts.radar:
            self._load_radar(sample, anno, clip_dir, frame, row)
        if opts.boxes:
            neighbour, dt = self._neighbour(anno, clip_dir, row, start, length)
            sample.update(box_fields(anno, world2ego, opts, neighbour, dt))
        if opts.expert or opts.expert_bev:
            sample.update(self._load_expert(clip, clip_dir, frame))
        if opts.map_radius is not None:
            self._load_map(sample, world2ego, sample["town"])
        if opts.keep_anno:
            sample["anno"] = anno
        return sample

    def _load_expert(self, clip: int, clip_dir: Path, frame: int) -> dict[str, Any]:
        path = layout.expert_path(clip_dir, frame)
        feature, value, action = split_expert(read_expert(path))
        try:
            control = action_control(action).as_array()
        except ValueError as exc:
            raise B2DFormatError(path, str(exc)) from exc
        feature = feature.astype(np.float32)
        if self.options.expert_bev:
            if clip not in self._expert_bev:
                info = read_format_info(clip_dir)
                self._expert_bev[clip] = info is not None and expert_feature.is_bev_record(info.expert_feature)
            if not self._expert_bev[clip]:
                raise B2DFormatError(
                    clip_dir / FORMAT_FILE,
                    f"expert_bev=True but the clip does not record the {expert_feature.FEATURE_NAME} "
                    f"v{expert_feature.FEATURE_VERSION} layout (released Bench2Drive clips hold Think2Drive's latent)",
                )
            try:
                feature = expert_feature.unflatten(feature)
            except ValueError as exc:
                raise B2DFormatError(path, str(exc)) from exc
        return {
            "expert_feature": feature,
            "expert_value": np.float32(value),
            "expert_action": np.int64(action),
            "expert_control": control,
        }

    def _clip_track(self, clip_dir: Path, start: int, length: int, pos: int) -> np.ndarray:
        track = self._track[start : start + length]
        stride = self.options.waypoint_stride
        needed = [pos + k * stride for k in range(-self.options.past_steps, self.options.future_steps + 1)]
        needed = [p for p in needed if 0 <= p < length and not np.isfinite(track[p]).all()]
        if not needed:
            return track
        # The index lacks some poses (an annotation failed to decode while indexing): read them now.
        track = track.copy()
        first = int(self._frame_num[start])
        for p in needed:
            try:
                anno = read_anno(layout.anno_path(clip_dir, first + p))
            except B2DFormatError:
                continue  # stays NaN ⇒ that waypoint is flagged invalid
            m = coords.ego_to_world(anno, self.options.pose_source)
            track[p] = (m[0, 3], m[1, 3], coords.yaw_of(m))
        return track

    def _neighbour(self, anno: dict, clip_dir: Path, row: int, start: int, length: int) -> tuple[dict | None, float]:
        if not self.options.walker_velocity or not any(b.get("class") == "walker" for b in anno["bounding_boxes"]):
            return None, coords.FRAME_DT
        pos = row - start
        for other, dt in ((pos - 1, coords.FRAME_DT), (pos + 1, -coords.FRAME_DT)):
            if 0 <= other < length and self._has["anno"][start + other]:
                try:
                    return read_anno(layout.anno_path(clip_dir, int(self._frame_num[start + other]))), dt
                except B2DFormatError as exc:
                    logger.debug("no walker velocity from %s: %s", clip_dir, exc)
        return None, coords.FRAME_DT

    def _load_cameras(self, sample: dict, anno: dict, clip_dir: Path, frame: int, row: int) -> None:
        opts = self.options
        images, intrinsics, cam2ego = [], [], []
        depth, semantic, instance = [], [], []
        for cam, sensor_id in zip(self._cameras, self._sensor_ids, strict=True):
            img = read_jpeg(layout.image_path(clip_dir, "rgb", cam, frame))
            k = coords.camera_intrinsic(anno, sensor_id, img.shape[1], img.shape[0])
            stored = (anno.get("sensors") or {}).get(sensor_id) or {}
            sx, sy = stored.get("image_size_x"), stored.get("image_size_y")
            if sx and sy and (int(sx), int(sy)) != (img.shape[1], img.shape[0]):
                # Images resized after collection: scale K to the pixels actually stored.
                k = np.diag([img.shape[1] / float(sx), img.shape[0] / float(sy), 1.0]) @ k
            images.append(img)
            intrinsics.append(k)
            cam2ego.append(coords.camera_cam2ego(anno, sensor_id, opts.frame))
            if cam == "top_down":
                continue
            if opts.depth:
                has_npz = self._has.get(f"depth_npz_{cam}")
                if opts.float_depth and has_npz is not None and has_npz[row]:
                    depth.append(read_depth_npz(layout.depth_npz_path(clip_dir, cam, frame)))
                else:
                    depth.append(read_depth_png(layout.image_path(clip_dir, "depth", cam, frame)))
            if opts.semantic:
                semantic.append(read_semantic_png(layout.image_path(clip_dir, "semantic", cam, frame)))
            if opts.instance:
                instance.append(read_instance_png(layout.image_path(clip_dir, "instance", cam, frame))[1])
        same = len({im.shape for im in images}) == 1
        sample["images"] = np.stack(images) if same else images
        sample["intrinsics"] = np.stack(intrinsics).astype(np.float32)
        sample["cam2ego"] = np.stack(cam2ego).astype(np.float32)
        sample["camera_names"] = list(self._cameras)
        for key, arrays in (("depth", depth), ("semantic", semantic), ("instance", instance)):
            if getattr(opts, key):
                sample[key] = np.stack(arrays) if arrays and len({a.shape for a in arrays}) == 1 else arrays

    def _load_radar(self, sample: dict, anno: dict, clip_dir: Path, frame: int, row: int) -> None:
        frame_conv = self.options.frame
        detections: dict[str, np.ndarray] = {}
        valid = bool(self._has["radar"][row])
        if valid:
            detections = read_radar(layout.radar_path(clip_dir, frame), missing_ok=True)
        pts, vel, sensor = [], [], []
        for i, name in enumerate(RADAR_DATASETS):
            det = detections.get(name)
            if det is None or len(det) == 0:
                continue
            m = coords.radar_to_ego_matrix(anno, _RADAR_SENSOR[name])
            pts.append(coords.radar_detections_to_ego(det, m, frame_conv))
            vel.append(np.asarray(det, np.float64)[:, 3])
            sensor.append(np.full(len(det), i, np.int8))
        sample["radar"] = (np.concatenate(pts) if pts else np.zeros((0, 3))).astype(np.float32)
        sample["radar_velocity"] = (np.concatenate(vel) if vel else np.zeros(0)).astype(np.float32)
        sample["radar_sensor"] = np.concatenate(sensor) if sensor else np.zeros(0, np.int8)
        sample["radar_valid"] = np.bool_(valid)

    def _load_map(self, sample: dict, world2ego: np.ndarray, town: str) -> None:
        path = find_hdmap(town, self._map_dirs)
        if path is None:
            raise B2DFormatError(self._map_dirs[0] / f"{town}_HD_map.npz", "HD map not found (pass maps_dir=)")
        hdmap = load_hdmap_cached(str(path))
        ego_xy = np.linalg.inv(world2ego)[:2, 3]
        lines, types = [], []
        for pts, kind in hdmap.query(ego_xy, float(self.options.map_radius or 0.0)):
            lines.append(coords.world_points_to_ego(pts, world2ego, self.options.frame).astype(np.float32))
            types.append(kind)
        sample["map_polylines"] = lines
        sample["map_types"] = np.array(types, np.int64)
