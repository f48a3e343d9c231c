"""Write one Bench2Drive clip frame by frame; the clip folder appears only once it is complete."""

from __future__ import annotations

import json
import logging
import multiprocessing
import os
import pickle
import re
import secrets
import shutil
import sys
from collections import deque
from collections.abc import Mapping
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from types import TracebackType

import numpy as np

import b2d_data
from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import validate_anno
from b2d_data.codecs.jpeg import check_jpeg_planes
from b2d_data.codecs.format_info import CameraInfo, ClipFormatInfo, write_format_info
from b2d_data.codecs.radar_h5 import RADAR_DATASETS
from b2d_data.format.names import ClipName
from b2d_data.format.record import CameraFrame, FrameRecord
from b2d_data.format.rig import ALL_CAMERAS, CAMERA_BY_FOLDER
from b2d_data.format.version import DEFAULT_FORMAT, FORMAT_FILE, FormatVersion
from b2d_data.writers.frame_jobs import CameraJob, DepthOptions, Job, MiscJob, init_worker, run_job
from b2d_data.writers.shared_frames import SharedSlot, SlotPool, packed_size

logger = logging.getLogger(__name__)

# ``.<name>.tmp-<pid>-<token>`` (clips being written, maps being copied) and ``.<name>.old-<pid>-<token>``
# (a replaced clip being removed).
_TEMP_RE = re.compile(r"^\.(?P<name>.+)\.(?:tmp|old)-(?P<pid>\d+)-[0-9a-f]+$")


class ClipWriterError(RuntimeError):
    """Writing a clip failed; the message names the clip and, where it applies, the frame."""


def _temp_name(name: str, kind: str = "tmp") -> str:
    return f".{name}.{kind}-{os.getpid()}-{secrets.token_hex(3)}"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    # A killed writer whose parent has not reaped it yet (containers without an init) still answers kill(0).
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True
    return state not in ("Z", "X")


def remove_stale_temporaries(root: str | os.PathLike[str], *, include_live: bool = False) -> list[Path]:
    """Remove leftovers of crashed writers under ``root`` and ``root/maps``; returns what was removed.

    A temporary belongs to the process id in its name; those of live processes on this machine are kept unless
    ``include_live`` (use it when no writer can be running, e.g. on a shared disk written from several hosts).
    """
    removed: list[Path] = []
    for folder in (Path(root), Path(root) / layout.MAPS_DIR):
        if not folder.is_dir():
            continue
        for entry in folder.iterdir():
            match = _TEMP_RE.match(entry.name)
            if match is None:
                continue
            if not include_live and _pid_alive(int(match["pid"])):
                continue
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)
            logger.info("removed stale temporary %s", entry)
            removed.append(entry)
    return removed


@dataclass
class _Layout:
    """What frame 0 wrote; every later frame must write the same set of files."""

    cameras: dict[str, CameraInfo]
    lidar: bool
    radar: bool
    expert: bool


@dataclass
class _InFlight:
    """One frame whose jobs are queued in the pool."""

    index: int
    futures: list[tuple[Future[int], str]]
    slot: SharedSlot | None = None
    bytes_written: int = 0


def _default_context() -> multiprocessing.context.BaseContext:
    # forkserver: workers never inherit the simulator's threads or GL contexts, and start faster than spawn.
    if sys.platform.startswith("linux"):
        return multiprocessing.get_context("forkserver")
    return multiprocessing.get_context("spawn")


class ClipWriter:
    """Write a clip ``<root>/<Scenario>_<Town>_Route<id>_Weather<w>/`` in Bench2Drive's layout, one frame at a time.

    Files go to a temporary sibling ``<root>/.<clip>.tmp-<pid>-<token>`` that ``close()`` renames into place;
    ``abort()``, a failed frame, or an exception inside ``with ClipWriter(...) as w:`` removes it. Frame indices
    must run 0, 1, 2, …; frame 0 fixes which files every frame has (cameras and sizes, dense labels, LiDAR,
    radar, expert vector). With ``workers > 0`` the encoding runs in a process pool (or in ``executor`` when
    given, which the writer then does not shut down) with at most ``max_in_flight`` frames queued (default
    workers + 1, ~90 MB of shared memory each at full resolution); arrays are copied at ``write`` so the caller
    may reuse its buffers. Errors from the pool are raised by the next ``write`` or by ``close``, name the frame,
    and abort the clip. The pool starts its processes with ``forkserver`` (``spawn`` off Linux), so a script
    using ``workers > 0`` needs the usual ``if __name__ == "__main__":`` guard.
    ``expert_feature`` (JSON-able) describes the expert vectors' feature in ``b2d_format.json`` when the clip has them.
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        name: ClipName | str,
        format_version: FormatVersion = DEFAULT_FORMAT,
        hdmap: str | os.PathLike[str] | None = None,
        workers: int = 0,
        strict_anno: bool = True,
        *,
        overwrite: bool = False,
        max_in_flight: int | None = None,
        executor: Executor | None = None,
        depth_npz: DepthOptions | None = None,
        extra: Mapping[str, object] | None = None,
        expert_feature: Mapping[str, object] | None = None,
    ) -> None:
        self.name = name if isinstance(name, ClipName) else ClipName.parse(name)
        self.root = Path(root)
        self.format_version = FormatVersion(format_version)
        self.strict_anno = strict_anno
        self.overwrite = overwrite
        self.final_dir = self.root / str(self.name)
        self._extra = dict(extra or {})
        self._expert_feature = dict(expert_feature) if expert_feature is not None else None
        try:
            json.dumps([self._extra, self._expert_feature])
        except (TypeError, ValueError) as exc:
            raise TypeError(
                f"{self.name}: extra and expert_feature must be JSON-serialisable for {FORMAT_FILE}: {exc}"
            ) from exc
        # Float depth npz only where the format version has it; ``depth_npz`` only says how to store it.
        self._float_depth = (depth_npz or DepthOptions()) if self.format_version.float_depth else None
        self._hdmap = Path(hdmap) if hdmap is not None else None
        if self._hdmap is not None and not self._hdmap.is_file():
            raise FileNotFoundError(f"{self.name}: HD map {self._hdmap} does not exist")
        if self.final_dir.exists() and not overwrite:
            raise FileExistsError(f"clip {self.final_dir} already exists (pass overwrite=True to replace it)")
        if workers < 0:
            raise ValueError(f"workers must be ≥ 0, got {workers}")
        self._next_index = 0
        self._layout: _Layout | None = None
        self._bytes = 0
        self._in_flight: deque[_InFlight] = deque()
        self._slots = SlotPool()
        self._own_executor = False
        self._executor: Executor | None = executor
        if executor is None and workers > 0:
            self._executor = ProcessPoolExecutor(workers, mp_context=_default_context(), initializer=init_worker)
            self._own_executor = True
        pool_size = workers or getattr(executor, "_max_workers", 1)
        self._max_in_flight = max(1, max_in_flight if max_in_flight is not None else pool_size + 1)
        self.temp_dir = self.root / _temp_name(str(self.name))
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            self.temp_dir.mkdir()
        except BaseException:
            if self._own_executor:
                self._executor.shutdown(wait=False)  # type: ignore[union-attr]
            raise
        self._state = "open"  # open → closed | aborted

    # ------------------------------------------------------------------ public API

    @property
    def frames_written(self) -> int:
        """Number of frames accepted so far (some may still be encoding)."""
        return self._next_index

    @property
    def bytes_written(self) -> int:
        """Bytes of the frames already on disk."""
        return self._bytes

    def write(self, record: FrameRecord) -> None:
        """Validate one frame and write it (or queue it in the pool); indices must be consecutive from 0."""
        self._check_open()
        self._collect_finished()
        jobs = self._prepare(record)
        if self._executor is None:
            for job in jobs:
                try:
                    self._bytes += job.run()
                except Exception as exc:
                    self._fail(f"frame {record.index} ({job.describe()})", exc)
        else:
            self._submit(record.index, jobs)
        self._next_index += 1

    def flush(self) -> None:
        """Wait until every queued frame is on disk; raises (and aborts) on a pool error."""
        self._check_open()
        while self._in_flight:
            self._wait_oldest()

    def close(self) -> Path:
        """Finish pending frames, write ``b2d_format.json``, copy the HD map and move the clip into place."""
        if self._state == "closed":
            return self.final_dir
        self._check_open()
        if self._next_index == 0:
            self.abort()
            raise ClipWriterError(f"{self.name}: no frame was written; nothing to close")
        self.flush()
        try:
            self._finish()
        except Exception:
            self.abort()
            raise
        self._state = "closed"
        self._release_pool()
        logger.info("wrote clip %s: %d frames, %.1f MB", self.final_dir, self._next_index, self._bytes / 1e6)
        return self.final_dir

    def abort(self) -> None:
        """Drop everything written so far: no clip, no temporary folder."""
        if self._state != "open":
            return
        self._state = "aborted"
        pending = [fut for frame in self._in_flight for fut, _ in frame.futures]
        for fut in pending:
            fut.cancel()
        # Jobs already running write into the temporary folder: let them end before removing it.
        wait_futures(pending)
        for frame in self._in_flight:
            if frame.slot is not None:
                self._slots.release(frame.slot)
        self._in_flight.clear()
        shutil.rmtree(self.temp_dir, ignore_errors=True)
        self._release_pool()
        logger.info("aborted clip %s after %d frames", self.name, self._next_index)

    def __enter__(self) -> ClipWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is not None:
            self.abort()
        elif self._state == "open":
            self.close()

    # ------------------------------------------------------------------ validation and job building

    def _check_open(self) -> None:
        if self._state != "open":
            raise ClipWriterError(f"{self.name}: writer is {self._state}")

    def _prepare(self, record: FrameRecord) -> list[Job]:
        """Check one record against the format and frame 0, and turn it into encoding jobs."""
        where = f"{self.name} frame {record.index}"
        if record.index != self._next_index:
            raise ValueError(f"{where}: frame indices must be consecutive from 0; expected {self._next_index}")
        if not isinstance(record.anno, dict):
            raise TypeError(f"{where}: anno must be a dict, got {type(record.anno).__name__}")
        if self.strict_anno:
            validate_anno(record.anno, frame=where)
        cameras = {cam: _check_camera(where, cam, frame) for cam, frame in record.cameras.items()}
        lidar = _check_lidar(where, record.lidar)
        radar = _check_radar(where, record.radar)
        expert = _check_expert(where, record.expert_assessment)
        if self._float_depth is not None:
            for cam, frame in record.cameras.items():
                if frame.depth is not None and frame.depth.dtype == np.uint8:
                    raise ValueError(
                        f"{where}: camera {cam}: {self.format_version.value} writes float depth npz files, "
                        "but depth is uint8 (already rounded to whole metres); render float depth"
                    )
        current = _Layout(cameras, lidar is not None, radar is not None, expert is not None)
        if self._layout is None:
            self._layout = current
            self._make_dirs(current)
        elif current != self._layout:
            raise ValueError(f"{where}: {_layout_difference(self._layout, current)} differs from frame 0")
        clip = str(self.temp_dir)
        jobs: list[Job] = [
            CameraJob(clip, cam, record.index, f.rgb, f.depth, f.semantic, f.instance, self._float_depth, f.labels,
                      f.jpeg_planes)  # fmt: skip
            for cam, f in record.cameras.items()
        ]
        jobs.append(MiscJob(clip, record.index, record.anno, lidar, radar, expert))
        return jobs

    def _make_dirs(self, lay: _Layout) -> None:
        folders = [layout.ANNO_DIR]
        for cam, info in lay.cameras.items():
            kinds = ("rgb", "depth", "semantic", "instance") if info.dense_labels else ("rgb",)
            folders += [str(layout.camera_dir("", kind, cam)) for kind in kinds]
        folders += [layout.LIDAR_DIR] * lay.lidar + [layout.RADAR_DIR] * lay.radar + [layout.EXPERT_DIR] * lay.expert
        for folder in folders:
            (self.temp_dir / folder).mkdir(parents=True, exist_ok=True)

    # ------------------------------------------------------------------ the process pool

    def _submit(self, index: int, jobs: list[Job]) -> None:
        while len(self._in_flight) >= self._max_in_flight:
            self._wait_oldest()
        # Everything a queued job holds is copied now, so that a caller reusing its buffers (or its anno dict)
        # after write() returns cannot change a frame that is still waiting for a worker.
        arrays = _frame_arrays(jobs)
        slot = self._slots.acquire(packed_size(arrays)) if arrays else None
        if slot is not None:
            _swap_arrays(jobs, dict(zip(map(id, arrays), slot.pack(arrays))))
        else:
            _swap_arrays(jobs, {id(a): np.array(a, copy=True) for a in arrays})
        for job in jobs:
            if isinstance(job, MiscJob):
                job.anno = pickle.dumps(job.anno, protocol=pickle.HIGHEST_PROTOCOL)
        assert self._executor is not None
        queued = _InFlight(index, [], slot)
        self._in_flight.append(queued)  # from here on abort() releases the slot and waits for the jobs
        for job in jobs:
            try:
                queued.futures.append((self._executor.submit(run_job, job), job.describe()))
            except Exception as exc:  # a broken pool (a worker was killed) refuses new jobs
                self._fail(f"frame {index} ({job.describe()})", exc)

    def _wait_oldest(self) -> None:
        frame = self._in_flight[0]
        for fut, what in frame.futures:
            try:
                frame.bytes_written += fut.result()
            except Exception as exc:
                self._fail(f"frame {frame.index} ({what})", exc)
        self._in_flight.popleft()
        self._bytes += frame.bytes_written
        if frame.slot is not None:
            self._slots.release(frame.slot)

    def _collect_finished(self) -> None:
        # Surface pool errors at the next write instead of at close().
        while self._in_flight and all(fut.done() for fut, _ in self._in_flight[0].futures):
            self._wait_oldest()

    def _fail(self, what: str, exc: BaseException) -> None:
        self.abort()
        raise ClipWriterError(f"{self.name}: {what} failed: {exc!r}; the clip was aborted") from exc

    def _release_pool(self) -> None:
        if self._own_executor and self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
        self._executor = None
        self._slots.close()

    # ------------------------------------------------------------------ finishing

    def _finish(self) -> None:
        assert self._layout is not None
        info = ClipFormatInfo(
            format_version=self.format_version,
            b2d_data_version=b2d_data.__version__,
            clip=str(self.name),
            frames=self._next_index,
            cameras=self._layout.cameras,
            float_depth=self._float_depth is not None and any(c.dense_labels for c in self._layout.cameras.values()),
            lidar=self._layout.lidar,
            radar=self._layout.radar,
            expert_assessment=self._layout.expert,
            expert_feature=self._expert_feature if self._layout.expert else None,
            written_at=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            extra=self._extra,
        )
        write_format_info(self.temp_dir, info)
        if self._hdmap is not None:
            _install_hdmap(self._hdmap, self.root, self.name.town)
        if self.final_dir.exists():
            if not self.overwrite:
                raise FileExistsError(f"clip {self.final_dir} appeared while writing (pass overwrite=True)")
            old = self.root / _temp_name(str(self.name), "old")
            os.rename(self.final_dir, old)
            os.rename(self.temp_dir, self.final_dir)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(self.temp_dir, self.final_dir)


def _check_camera(where: str, cam: str, frame: CameraFrame) -> CameraInfo:
    spec = CAMERA_BY_FOLDER.get(cam)
    if spec is None:
        raise ValueError(f"{where}: unknown camera {cam!r}; expected one of {[c.folder for c in ALL_CAMERAS]}")
    rgb, planes = frame.rgb, frame.jpeg_planes
    if (rgb is None) == (planes is None):
        raise ValueError(f"{where}: camera {cam}: give either rgb or jpeg_planes")
    if planes is not None:
        try:
            check_jpeg_planes(tuple(planes))  # type: ignore[arg-type]
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{where}: camera {cam}: {exc}") from None
    elif not isinstance(rgb, np.ndarray) or rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        got = f"{rgb.dtype} {rgb.shape}" if isinstance(rgb, np.ndarray) else type(rgb).__name__
        raise ValueError(f"{where}: camera {cam}: rgb must be (H, W, 3) uint8, got {got}")
    h, w = frame.size
    dense = (frame.depth, frame.semantic, frame.instance)
    present = [a is not None for a in dense]
    if any(present) and not spec.has_dense_labels:
        raise ValueError(f"{where}: camera {cam} has no depth/semantic/instance in Bench2Drive; leave them None")
    if any(present) and not all(present):
        raise ValueError(f"{where}: camera {cam}: give depth, semantic and instance together (got {present})")
    if all(present):
        for label, arr in (("depth", frame.depth), ("semantic", frame.semantic), ("instance", frame.instance)):
            if not isinstance(arr, np.ndarray) or arr.shape != (h, w):
                got = f"{arr.dtype} {arr.shape}" if isinstance(arr, np.ndarray) else type(arr).__name__
                raise ValueError(f"{where}: camera {cam}: {label} must be ({h}, {w}) like rgb, got {got}")
        depth, semantic, ids = frame.depth, frame.semantic, frame.instance
        assert depth is not None and semantic is not None and ids is not None
        if depth.dtype.kind not in "fiu":
            raise ValueError(f"{where}: camera {cam}: depth must be numeric metres, got {depth.dtype}")
        if semantic.dtype != np.uint8:
            raise ValueError(f"{where}: camera {cam}: semantic must be uint8 tag ids, got {semantic.dtype}")
        if ids.dtype != np.uint16 and (ids.dtype.kind not in "iu" or ids.min() < 0 or ids.max() > 0xFFFF):
            raise ValueError(f"{where}: camera {cam}: instance ids must be integers in [0, 65535] (uint16)")
    packed = frame.labels
    if packed is not None and (not all(present) or not isinstance(packed, np.ndarray) or packed.dtype != np.uint8
                               or packed.shape != (h, w, 4)):  # fmt: skip
        got = f"{packed.dtype} {packed.shape}" if isinstance(packed, np.ndarray) else type(packed).__name__
        raise ValueError(f"{where}: camera {cam}: labels must be ({h}, {w}, 4) uint8 beside semantic and instance, "
                         f"got {got}")  # fmt: skip
    return CameraInfo(width=w, height=h, dense_labels=all(present))


def _check_lidar(where: str, lidar: np.ndarray | None) -> np.ndarray | None:
    if lidar is None:
        return None
    arr = np.asarray(lidar)
    if arr.ndim != 2 or arr.shape[1] < 3 or arr.dtype.kind not in "fiu":
        raise ValueError(f"{where}: lidar must be an (N, 3) array, got {arr.dtype} {arr.shape}")
    if not np.isfinite(arr[:, :3]).all():
        raise ValueError(f"{where}: lidar holds NaN or infinite coordinates")
    return arr


def _check_radar(where: str, radar: Mapping[str, np.ndarray] | None) -> dict[str, np.ndarray] | None:
    if radar is None:
        return None
    unknown = sorted(set(radar) - set(RADAR_DATASETS))
    if unknown:
        raise ValueError(f"{where}: unknown radar dataset(s) {unknown}; expected {list(RADAR_DATASETS)}")
    out = {}
    for key, value in radar.items():
        arr = np.asarray(value)
        if arr.ndim != 2 or arr.shape[1] != 4 or arr.dtype.kind not in "fiu":
            raise ValueError(f"{where}: radar {key} must be an (N, 4) array, got {arr.dtype} {arr.shape}")
        out[key] = arr
    return out


def _check_expert(where: str, vector: np.ndarray | None) -> np.ndarray | None:
    if vector is None:
        return None
    arr = np.asarray(vector)
    if arr.ndim != 1 or arr.size < 2 or arr.dtype.kind not in "fiu":
        raise ValueError(f"{where}: expert_assessment must be a 1-D vector (feature, value, action), got {arr.shape}")
    return arr


def _layout_difference(first: _Layout, now: _Layout) -> str:
    if first.cameras.keys() != now.cameras.keys():
        return f"camera set {sorted(now.cameras)} (frame 0: {sorted(first.cameras)})"
    for cam, info in now.cameras.items():
        if info != first.cameras[cam]:
            return f"camera {cam} {info} (frame 0: {first.cameras[cam]})"
    for part in ("lidar", "radar", "expert"):
        if getattr(first, part) != getattr(now, part):
            return f"presence of {part} ({getattr(now, part)})"
    return "layout"


def _frame_arrays(jobs: list[Job]) -> list[np.ndarray]:
    arrays: dict[int, np.ndarray] = {}
    for job in jobs:
        if isinstance(job, CameraJob):
            candidates = [job.rgb, job.depth, job.semantic, job.instance, job.labels, *(job.jpeg_planes or ())]
        else:
            candidates = [job.lidar, job.expert, *(job.radar or {}).values()]
        for arr in candidates:
            if isinstance(arr, np.ndarray):
                arrays.setdefault(id(arr), arr)
    return list(arrays.values())


def _swap_arrays(jobs: list[Job], by_id: dict[int, object]) -> None:
    for job in jobs:
        if isinstance(job, CameraJob):
            for attr in ("rgb", "depth", "semantic", "instance", "labels"):
                value = getattr(job, attr)
                if value is not None:
                    setattr(job, attr, by_id[id(value)])
            if job.jpeg_planes is not None:
                job.jpeg_planes = tuple(by_id[id(p)] for p in job.jpeg_planes)  # type: ignore[assignment]
        else:
            if job.lidar is not None:
                job.lidar = by_id[id(job.lidar)]  # type: ignore[assignment]
            if job.expert is not None:
                job.expert = by_id[id(job.expert)]  # type: ignore[assignment]
            if job.radar is not None:
                job.radar = {k: by_id[id(v)] for k, v in job.radar.items()}  # type: ignore[misc]


def _install_hdmap(source: Path, root: Path, town: str) -> Path:
    """Copy a town's HD map to ``<root>/maps/<Town>_HD_map.npz`` once; the copy appears atomically."""
    target = layout.hdmap_path(root, town)
    if target.exists():
        return target
    if town not in source.name:
        logger.warning("HD map %s does not name town %s; installing it as %s", source, town, target.name)
    target.parent.mkdir(parents=True, exist_ok=True)
    temp = target.parent / _temp_name(target.name)
    try:
        shutil.copyfile(source, temp)
        os.replace(temp, target)
    finally:
        temp.unlink(missing_ok=True)
    logger.info("installed HD map %s", target)
    return target
