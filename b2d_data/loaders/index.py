"""The corpus index: two parquet tables under ``<root>/.b2d_index/`` so that opening a corpus never walks it.

``clips.parquet`` — one row per clip: ``clip_id``, ``name``, ``scenario``, ``town``, ``route_id``, ``weather_id``
(−1 when unknown, e.g. the truncated ``…_Weathe`` name), ``path`` (clip folder relative to the root, "" when
only archived), ``archive`` (relative, "" when none), ``archive_size`` (−1), ``sha256`` ("" when not archived),
``n_frames``, ``frame_start`` (first row of the clip in the frames table), ``first_frame``, ``format_version``
("" for released clips without ``b2d_format.json``), ``mtime_ns`` / ``archive_mtime_ns`` (change detection),
``error`` ("" unless the clip could not be indexed) and ``n_<modality>`` (frames holding that modality).

``frames.parquet`` — one row per frame, sorted by (clip_id, frame): ``clip_id``, ``frame``, ``has_<modality>``
(bool per modality, see ``clip_scan.MODALITIES``) and the ego pose columns ``ego_x, ego_y, ego_z, ego_yaw``
(exact pose from ``bounding_boxes[0].world2ego``, CARLA world, yaw in radians), ``gnss_x, gnss_y, theta``
(as stored) and ``speed`` (null → 0); NaN where the annotation could not be read.

Updating is incremental: a clip whose folder signature (largest mtime of its folder and sub-folders) and
archive size/mtime are unchanged keeps its rows; only new or changed clips are scanned, vanished ones dropped.
Both tables carry the same build id in their metadata; a mismatched pair (an interrupted write) is rebuilt.
"""

from __future__ import annotations

import logging
import os
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipName, ClipNameError
from b2d_data.loaders.clip_scan import (
    MODALITIES,
    POSE_COLUMNS,
    ClipLocation,
    ClipScan,
    discover_clips,
    folder_signature,
    is_clip_dir,
    iter_scans,
    scan_clip_dir,
)

logger = logging.getLogger(__name__)

INDEX_DIR = ".b2d_index"
CLIPS_FILE = "clips.parquet"
FRAMES_FILE = "frames.parquet"
#: 2: frame counts from the frames the modality folders agree on (a stray file no longer stretches a clip).
INDEX_VERSION = "2"
_META_BUILD = b"b2d_index_build"
_META_VERSION = b"b2d_index_version"

CLIP_STR_COLUMNS = ("name", "scenario", "town", "path", "archive", "sha256", "format_version", "error")
CLIP_INT_COLUMNS = (
    "clip_id", "route_id", "weather_id", "n_frames", "frame_start", "first_frame", "archive_size", "mtime_ns",
    "archive_mtime_ns",
)  # fmt: skip


def presence_column(modality: str) -> str:
    """Name of a frames-table presence column (``has_rgb_front``)."""
    return f"has_{modality}"


def count_column(modality: str) -> str:
    """Name of a clips-table frame-count column (``n_rgb_front``)."""
    return f"n_{modality}"


def index_dir(root: str | os.PathLike[str]) -> Path:
    """Where a corpus index lives: ``<root>/.b2d_index``."""
    return Path(root) / INDEX_DIR


def _clip_schema() -> pa.Schema:
    fields = [
        pa.field(c, pa.int32() if c in ("clip_id", "route_id", "weather_id", "n_frames", "first_frame") else pa.int64())
        for c in CLIP_INT_COLUMNS
    ]
    fields += [pa.field(c, pa.string()) for c in CLIP_STR_COLUMNS]
    fields += [pa.field(count_column(m), pa.int32()) for m in MODALITIES]
    return pa.schema(fields)


def _frame_schema() -> pa.Schema:
    fields = [pa.field("clip_id", pa.int32()), pa.field("frame", pa.int32())]
    fields += [pa.field(presence_column(m), pa.bool_()) for m in MODALITIES]
    fields += [pa.field(c, pa.float64()) for c in POSE_COLUMNS]
    return pa.schema(fields)


CLIP_SCHEMA = _clip_schema()
FRAME_SCHEMA = _frame_schema()


def _name_fields(name: str) -> tuple[str, str, int, int]:
    try:
        parsed = ClipName.parse(name)
    except ClipNameError:
        return "", "", -1, -1
    return parsed.scenario, parsed.town, parsed.route_id, -1 if parsed.weather_id is None else parsed.weather_id


def _frames_table(scan: ClipScan) -> pa.Table:
    n = len(scan.frames)
    cols: dict[str, pa.Array] = {
        "clip_id": pa.array(np.zeros(n, np.int32)),
        "frame": pa.array(scan.frames.astype(np.int32)),
    }
    for m in MODALITIES:
        cols[presence_column(m)] = pa.array(scan.presence.get(m, np.zeros(n, bool)))
    for c in POSE_COLUMNS:
        cols[c] = pa.array(scan.poses.get(c, np.full(n, np.nan)).astype(np.float64))
    return pa.table(cols, schema=FRAME_SCHEMA)


def _clip_row(scan: ClipScan) -> dict:
    scenario, town, route, weather = _name_fields(scan.name)
    row = {
        "name": scan.name, "scenario": scenario, "town": town, "route_id": route, "weather_id": weather,
        "path": scan.path, "archive": scan.archive, "sha256": scan.sha256, "format_version": scan.format_version,
        "error": scan.error, "archive_size": scan.archive_size, "mtime_ns": scan.mtime_ns,
        "archive_mtime_ns": scan.archive_mtime_ns, "n_frames": len(scan.frames),
        "first_frame": int(scan.frames[0]) if len(scan.frames) else 0,
    }  # fmt: skip
    for m in MODALITIES:
        row[count_column(m)] = int(scan.presence[m].sum()) if m in scan.presence else 0
    return row


@dataclass
class BuildReport:
    """What an index build did."""

    scanned: list[str] = field(default_factory=list)
    reused: int = 0
    removed: list[str] = field(default_factory=list)
    errors: dict[str, str] = field(default_factory=dict)
    seconds: float = 0.0


@dataclass
class CorpusIndex:
    """The clips and frames tables of a corpus (pyarrow tables; columns are documented in the module)."""

    root: Path
    clips: pa.Table
    frames: pa.Table

    @property
    def num_clips(self) -> int:
        """Number of clips (including those that failed to index; see the ``error`` column)."""
        return self.clips.num_rows

    @property
    def num_frames(self) -> int:
        """Number of frame rows."""
        return self.frames.num_rows

    def clip_names(self) -> list[str]:
        """Clip names in clip_id order."""
        return self.clips.column("name").to_pylist()

    # ------------------------------------------------------------------------------------------- loading

    @classmethod
    def load(cls, root: str | os.PathLike[str], frame_columns: list[str] | None = None) -> CorpusIndex | None:
        """Read ``<root>/.b2d_index``; None when absent or when the two tables do not belong together."""
        root = Path(root)
        folder = index_dir(root)
        clips_path, frames_path = folder / CLIPS_FILE, folder / FRAMES_FILE
        if not (clips_path.is_file() and frames_path.is_file()):
            return None
        clips = pq.read_table(clips_path, memory_map=True)
        frames = pq.read_table(frames_path, columns=frame_columns, memory_map=True)
        meta_c, meta_f = clips.schema.metadata or {}, frames.schema.metadata or {}
        if meta_c.get(_META_BUILD) != meta_f.get(_META_BUILD) or meta_c.get(_META_VERSION) != INDEX_VERSION.encode():
            logger.warning("%s: clips and frames tables do not match (interrupted write or old version)", folder)
            return None
        return cls(root, clips, frames)

    # ------------------------------------------------------------------------------------------ building

    @classmethod
    def from_scans(cls, root: str | os.PathLike[str], parts: list[tuple[dict, pa.Table]]) -> CorpusIndex:
        """Assemble tables from (clip row, frames table) pairs; clip ids follow the order of ``parts``."""
        parts = sorted(parts, key=lambda p: p[0]["name"])
        rows, frame_tables, start = [], [], 0
        for clip_id, (row, frames) in enumerate(parts):
            row = dict(row, clip_id=clip_id, frame_start=start, n_frames=frames.num_rows)
            frames = frames.set_column(0, "clip_id", pa.array(np.full(frames.num_rows, clip_id, np.int32)))
            rows.append(row)
            frame_tables.append(frames.cast(FRAME_SCHEMA))
            start += frames.num_rows
        clips = pa.Table.from_pylist(rows, schema=CLIP_SCHEMA) if rows else CLIP_SCHEMA.empty_table()
        frames = pa.concat_tables(frame_tables) if frame_tables else FRAME_SCHEMA.empty_table()
        return cls(Path(root), clips, frames)

    @classmethod
    def for_clip(cls, clip_dir: str | os.PathLike[str]) -> CorpusIndex:
        """An in-memory index of a single clip folder (nothing is written); its root is the clip's parent."""
        clip_dir = Path(clip_dir).resolve()
        if not is_clip_dir(clip_dir):
            raise FileNotFoundError(f"{clip_dir}: not a clip folder (no anno/ folder inside)")
        try:
            ClipName.parse(clip_dir.name)
        except ClipNameError as exc:
            raise B2DFormatError(clip_dir, str(exc)) from exc
        scan = scan_clip_dir(clip_dir.parent, clip_dir.name)
        return cls.from_scans(clip_dir.parent, [(_clip_row(scan), _frames_table(scan))])

    @classmethod
    def build(
        cls,
        root: str | os.PathLike[str],
        *,
        update: bool = True,
        workers: int = 0,
        hash_archives: bool = True,
        write: bool = True,
    ) -> tuple[CorpusIndex, BuildReport]:
        """Index ``root`` (incrementally when ``update`` and an index exists) and write it unless ``write=False``."""
        t0 = time.perf_counter()
        root = Path(root)
        if not root.is_dir():
            raise FileNotFoundError(f"{root}: corpus root does not exist")
        old = cls.load(root) if update else None
        report = BuildReport()
        reusable: dict[str, tuple[dict, pa.Table]] = {}
        if old is not None:
            for row in old.clips.to_pylist():
                frames = old.frames.slice(row["frame_start"], row["n_frames"])
                reusable[row["name"]] = (row, frames)
        locations = discover_clips(root)
        parts: list[tuple[dict, pa.Table]] = []
        to_scan: list[ClipLocation] = []
        for loc in locations:
            prev = reusable.pop(loc.name, None)
            if prev is not None and _unchanged(root, loc, prev[0], hash_archives):
                parts.append(prev)
                report.reused += 1
            else:
                to_scan.append(loc)
        report.removed = sorted(reusable)
        for scan in iter_scans(root, to_scan, workers=workers, hash_archives=hash_archives):
            parts.append((_clip_row(scan), _frames_table(scan)))
            report.scanned.append(scan.name)
            if scan.error:
                report.errors[scan.name] = scan.error
        index = cls.from_scans(root, parts)
        if write:
            index.save()
        report.seconds = time.perf_counter() - t0
        logger.info(
            "indexed %s: %d clips (%d scanned, %d unchanged, %d removed), %d frames in %.1f s",
            root, index.num_clips, len(report.scanned), report.reused, len(report.removed), index.num_frames,
            report.seconds,
        )  # fmt: skip
        return index, report

    def save(self) -> Path:
        """Write both tables under ``<root>/.b2d_index`` (each replaced atomically; a shared build id pairs them)."""
        folder = index_dir(self.root)
        folder.mkdir(parents=True, exist_ok=True)
        meta = {_META_BUILD: uuid.uuid4().hex.encode(), _META_VERSION: INDEX_VERSION.encode()}
        for table, file_name in ((self.frames, FRAMES_FILE), (self.clips, CLIPS_FILE)):
            table = table.replace_schema_metadata(meta)
            tmp = folder / f".{file_name}.tmp-{os.getpid()}"
            pq.write_table(table, tmp, compression="zstd")
            os.replace(tmp, folder / file_name)
        return folder


def _unchanged(root: Path, loc: ClipLocation, row: dict, hash_archives: bool) -> bool:
    if row.get("error") or row["path"] != loc.path or row["archive"] != loc.archive:
        return False
    try:
        if loc.path and folder_signature(root / loc.path) != row["mtime_ns"]:
            return False
        if loc.archive:
            stat = (root / loc.archive).stat()
            if stat.st_size != row["archive_size"] or stat.st_mtime_ns != row["archive_mtime_ns"]:
                return False
            if hash_archives and not row["sha256"]:
                return False
    except OSError:
        return False
    return True


def open_index(
    root: str | os.PathLike[str], mode: str = "auto", workers: int = 0, frame_columns: list[str] | None = None
) -> CorpusIndex:
    """The index of a corpus root or of one clip folder.

    ``mode``: ``auto`` reads ``<root>/.b2d_index`` and builds it only when absent; ``update`` rescans new or
    changed clips; ``rebuild`` scans everything; ``memory`` builds without writing. A clip folder (holding
    ``anno/``) always gets an in-memory index. ``frame_columns`` limits the frames columns read from disk
    (reading only what is needed is what keeps opening a 1000-clip corpus well under a second).
    """
    root = Path(root)
    if is_clip_dir(root):
        return CorpusIndex.for_clip(root)
    if mode == "auto":
        index = CorpusIndex.load(root, frame_columns)
        if index is not None:
            return index
        logger.info("%s has no index yet: building it (once; later opens read it)", root)
        return CorpusIndex.build(root, workers=workers)[0]
    if mode in ("update", "rebuild"):
        return CorpusIndex.build(root, update=mode == "update", workers=workers)[0]
    if mode == "memory":
        return CorpusIndex.build(root, update=False, workers=workers, write=False)[0]
    raise ValueError(f"unknown index mode {mode!r}; use auto, update, rebuild or memory")
