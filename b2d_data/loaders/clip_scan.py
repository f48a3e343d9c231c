"""Find the clips under a corpus root and list what each holds, from a folder or a ``.tar.gz`` archive.

A scan lists each modality folder of a clip once (no per-file ``stat``), records which frames have which
files, and reads every annotation once to store the ego pose per frame (so that planning targets never need
to open other frames' annotations at training time).
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import tarfile
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import BinaryIO

import numpy as np

from b2d_data import coords
from b2d_data.codecs import anno_json
from b2d_data.codecs.anno_json import read_anno
from b2d_data.codecs.format_info import read_format_info
from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipName, ClipNameError
from b2d_data.format.rig import ALL_CAMERAS, CAMERAS
from b2d_data.format.version import FORMAT_FILE

logger = logging.getLogger(__name__)

ARCHIVE_SUFFIXES = (".tar.gz", ".tgz")
#: Folders under a corpus root that are never clips.
NON_CLIP_DIRS = frozenset({"maps", ".b2d_index", "index", "splits", "failed", "results", "routes", "towns"})

#: Modality → (folder inside the clip, file suffix). ``expert`` files are named frame − 1 (``-0001.npz``).
MODALITY_FILES: dict[str, tuple[str, str]] = {"anno": ("anno", ".json.gz")}
MODALITY_FILES.update({f"rgb_{c.folder}": (f"camera/rgb_{c.folder}", ".jpg") for c in ALL_CAMERAS})
for _kind in ("depth", "semantic", "instance"):
    MODALITY_FILES.update({f"{_kind}_{c.folder}": (f"camera/{_kind}_{c.folder}", ".png") for c in CAMERAS})
MODALITY_FILES.update({f"depth_npz_{c.folder}": (f"camera/depth_{c.folder}", ".npz") for c in CAMERAS})
MODALITY_FILES.update({"lidar": ("lidar", ".laz"), "radar": ("radar", ".h5"), "expert": ("expert_assessment", ".npz")})
MODALITIES: tuple[str, ...] = tuple(MODALITY_FILES)
_BY_DIR_SUFFIX: dict[tuple[str, str], str] = {v: k for k, v in MODALITY_FILES.items()}

#: Per-frame ego pose columns stored in the index (CARLA world; NaN when the annotation could not be read).
POSE_COLUMNS: tuple[str, ...] = ("ego_x", "ego_y", "ego_z", "ego_yaw", "gnss_x", "gnss_y", "theta", "speed")


@dataclass
class ClipScan:
    """What one clip holds: frames, per-frame modality presence and ego poses, and where it lives."""

    name: str
    path: str = ""  # folder relative to the corpus root (posix); "" when only archived
    archive: str = ""  # archive relative to the corpus root; "" when none
    frames: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    presence: dict[str, np.ndarray] = field(default_factory=dict)  # modality → (F,) bool
    poses: dict[str, np.ndarray] = field(default_factory=dict)  # POSE_COLUMNS → (F,) float64
    format_version: str = ""
    mtime_ns: int = -1
    archive_size: int = -1
    archive_mtime_ns: int = -1
    sha256: str = ""
    error: str = ""


def is_clip_dir(path: Path) -> bool:
    """A clip folder holds an ``anno/`` folder."""
    return (path / "anno").is_dir()


def archive_clip_name(file_name: str) -> str | None:
    """The clip name of an archive file name, or None when it is not an archive."""
    for suffix in ARCHIVE_SUFFIXES:
        if file_name.endswith(suffix):
            return file_name[: -len(suffix)]
    return None


@dataclass(frozen=True)
class ClipLocation:
    """A clip found under a root: its folder and/or archive (paths relative to the root)."""

    name: str
    path: str = ""
    archive: str = ""


def discover_clips(root: Path, max_depth: int = 2) -> list[ClipLocation]:
    """Clips under ``root``: folders holding ``anno/`` and ``*.tar.gz`` archives, at most ``max_depth`` deep.

    Writers' temporary folders (names starting with a dot) are ignored. A folder and an archive of the same
    clip name are one clip.
    """
    found: dict[str, dict[str, str]] = {}

    def visit(folder: Path, depth: int) -> None:
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError as exc:
            logger.warning("cannot list %s: %s", folder, exc)
            return
        for entry in entries:
            if entry.name.startswith("."):
                continue
            rel = Path(entry.path).relative_to(root).as_posix()
            if entry.is_file():
                name = archive_clip_name(entry.name)
                if name is not None:
                    found.setdefault(name, {})["archive"] = rel
            elif entry.is_dir():
                if is_clip_dir(Path(entry.path)):
                    found.setdefault(entry.name, {})["path"] = rel
                elif depth < max_depth and entry.name not in NON_CLIP_DIRS:
                    visit(Path(entry.path), depth + 1)

    visit(root, 1)
    return [ClipLocation(name, d.get("path", ""), d.get("archive", "")) for name, d in sorted(found.items())]


def folder_signature(clip_dir: Path) -> int:
    """Largest mtime (ns) of the clip folder and its sub-folders two levels down: changes when files are added."""
    best = clip_dir.stat().st_mtime_ns
    for entry in os.scandir(clip_dir):
        if entry.is_dir():
            best = max(best, entry.stat().st_mtime_ns)
            for sub in os.scandir(entry.path):
                if sub.is_dir():
                    best = max(best, sub.stat().st_mtime_ns)
    return best


def _frame_number(file_name: str, suffix: str) -> int | None:
    if not file_name.endswith(suffix):
        return None
    stem = file_name[: -len(suffix)]
    try:
        return int(stem)
    except ValueError:
        return None


def _pose_row(anno: dict) -> tuple[float, ...]:
    ego2world = coords.exact_ego_to_world(anno)
    yaw = coords.yaw_of(ego2world)
    theta = anno.get("theta")
    return (
        float(ego2world[0, 3]), float(ego2world[1, 3]), float(ego2world[2, 3]), yaw,
        float(anno.get("x", math.nan)), float(anno.get("y", math.nan)),
        math.nan if theta is None else float(theta), coords.fix_speed(anno.get("speed")),
    )  # fmt: skip


_NAN_POSE = (math.nan,) * len(POSE_COLUMNS)


def frame_span(files: dict[str, set[int]]) -> tuple[int, int] | None:
    """First and last frame of a clip: the frames most modality folders hold, widened to adjacent frames any holds.

    A clip's folders agree on its frames, so one stray file (``anno/99999.json.gz``) cannot stretch the clip: the
    span is set by the frames a majority of the folders hold, and only frames next to it (a last frame that some
    folders lack) extend it. ``expert`` is left out, as its file names are shifted by one. None without frames.
    """
    counted = [frames for modality, frames in files.items() if modality != "expert" and frames]
    if not counted:
        return None
    support = Counter(f for frames in counted for f in frames)
    agreed = [f for f, n in support.items() if 2 * n > len(counted)] or list(support)
    first, last = min(agreed), max(agreed)
    while first - 1 in support:
        first -= 1
    while last + 1 in support:
        last += 1
    return first, last


def _file_name(modality: str, frame: int) -> str:
    folder, suffix = MODALITY_FILES[modality]
    return f"{folder}/{frame - 1 if modality == 'expert' else frame:05d}{suffix}"


def _report_disagreement(label: str, files: dict[str, set[int]], first: int, last: int) -> None:
    """Warn (one line each) about files outside the clip's frames and files missing inside them."""
    stray = sorted(
        _file_name(m, f) for m, frames in files.items() if m != "expert" for f in frames if not first <= f <= last
    )
    if stray:
        logger.warning(
            "%s: %d stray file(s) outside the frames %d..%d that most modality folders hold are ignored: %s",
            label, len(stray), first, last, _some(stray),
        )  # fmt: skip
    missing = sorted(
        _file_name(m, f)
        for m, frames in files.items()
        if m != "expert" and frames
        for f in range(first, last + 1)
        if f not in frames
    )
    if missing:
        logger.warning(
            "%s: %d file(s) missing within frames %d..%d: %s", label, len(missing), first, last, _some(missing)
        )


def _some(names: list[str], shown: int = 5) -> str:
    return ", ".join(names[:shown]) + (f" (+{len(names) - shown} more)" if len(names) > shown else "")


def _assemble(scan: ClipScan, files: dict[str, set[int]], poses: dict[int, tuple[float, ...]], label: str) -> None:
    # Frames run from the first to the last frame of the span, so a missing frame shows up as a row without files
    # (and loading it names the missing file) instead of silently shifting the timeline.
    span = frame_span(files)
    if span is None:
        scan.frames = np.zeros(0, np.int32)
        scan.presence = {m: np.zeros(0, bool) for m in MODALITIES}
        scan.poses = {c: np.zeros(0) for c in POSE_COLUMNS}
        return
    _report_disagreement(label, files, *span)
    frames = np.arange(span[0], span[1] + 1, dtype=np.int32)
    scan.frames = frames
    scan.presence = {m: np.isin(frames, np.fromiter(files.get(m, ()), np.int64)) for m in MODALITIES}
    table = np.array([poses.get(int(f), _NAN_POSE) for f in frames], dtype=np.float64).reshape(-1, len(POSE_COLUMNS))
    scan.poses = {c: table[:, i] for i, c in enumerate(POSE_COLUMNS)}


def scan_clip_dir(root: Path, rel: str, read_poses: bool = True) -> ClipScan:
    """Scan one clip folder (``rel`` relative to ``root``): file presence per frame and ego poses."""
    clip_dir = root / rel
    scan = ClipScan(name=clip_dir.name, path=rel)
    scan.mtime_ns = folder_signature(clip_dir)
    files: dict[str, set[int]] = {}
    by_dir: dict[str, list[tuple[str, str]]] = {}
    for modality, (folder, suffix) in MODALITY_FILES.items():
        by_dir.setdefault(folder, []).append((modality, suffix))
    for folder, wanted in by_dir.items():
        path = clip_dir / folder
        if not path.is_dir():
            continue
        names = [e.name for e in os.scandir(path)]
        for modality, suffix in wanted:
            nums = {n for n in (_frame_number(name, suffix) for name in names) if n is not None}
            if modality == "expert":
                nums = {n + 1 for n in nums}  # file −0001 holds frame 0
            files[modality] = nums
    poses: dict[int, tuple[float, ...]] = {}
    span = frame_span(files)
    if read_poses and span is not None:
        for frame in sorted(f for f in files.get("anno", ()) if span[0] <= f <= span[1]):
            path = clip_dir / "anno" / f"{frame:05d}.json.gz"
            try:
                poses[frame] = _pose_row(read_anno(path))
            except (B2DFormatError, KeyError, TypeError, ValueError, IndexError) as exc:
                # Indexing goes on: the broken frame is reported (and raised or skipped) when it is loaded.
                logger.warning("%s: cannot read the ego pose: %s", path, exc)
    try:
        info = read_format_info(clip_dir)
        scan.format_version = info.format_version.value if info else ""
    except B2DFormatError as exc:
        logger.warning("%s", exc)
    _assemble(scan, files, poses, str(clip_dir))
    return scan


class _HashingReader:
    """A read-only file wrapper that feeds every byte read into a sha256."""

    def __init__(self, raw: BinaryIO) -> None:
        self.raw = raw
        self.sha = hashlib.sha256()

    def read(self, n: int = -1) -> bytes:
        data = self.raw.read(n)
        self.sha.update(data)
        return data

    def drain(self, chunk: int = 1 << 20) -> None:
        while self.read(chunk):
            pass


def sha256_file(path: Path, chunk: int = 1 << 20, progress: object | None = None) -> str:
    """Streaming sha256 of a file (``progress`` may be a tqdm bar updated with bytes read)."""
    sha = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            data = f.read(chunk)
            if not data:
                break
            sha.update(data)
            if progress is not None:
                progress.update(len(data))  # type: ignore[attr-defined]
    return sha.hexdigest()


def _member_parts(member: str, clip: str) -> tuple[str, ...]:
    parts = PurePosixPath(member).parts
    # Archives hold ``<clip>/...`` (or ``v1/<clip>/...``): keep what follows the clip folder.
    if clip in parts:
        return parts[parts.index(clip) + 1 :]
    return parts


def scan_archive(root: Path, rel: str, list_members: bool = True) -> ClipScan:
    """Hash an archive; with ``list_members`` also list its frames and read its annotations in the same pass."""
    path = root / rel
    name = archive_clip_name(path.name) or path.name
    stat = path.stat()
    scan = ClipScan(name=name, archive=rel, archive_size=stat.st_size, archive_mtime_ns=stat.st_mtime_ns)
    if not list_members:
        scan.sha256 = sha256_file(path)
        return scan
    files: dict[str, set[int]] = {}
    poses: dict[int, tuple[float, ...]] = {}
    with open(path, "rb") as raw:
        reader = _HashingReader(raw)
        try:
            with tarfile.open(fileobj=reader, mode="r|gz") as tar:  # type: ignore[call-overload]
                for member in tar:
                    if not member.isfile():
                        continue
                    parts = _member_parts(member.name, name)
                    if len(parts) < 2:
                        if parts and parts[-1] == FORMAT_FILE:
                            scan.format_version = "b2d-data"
                        continue
                    folder, file_name = "/".join(parts[:-1]), parts[-1]
                    for suffix in (".json.gz", ".jpg", ".png", ".npz", ".laz", ".h5"):
                        modality = _BY_DIR_SUFFIX.get((folder, suffix))
                        num = _frame_number(file_name, suffix) if modality else None
                        if modality is None or num is None:
                            continue
                        files.setdefault(modality, set()).add(num + 1 if modality == "expert" else num)
                        if modality == "anno":
                            if member.size > anno_json.MAX_ANNO_BYTES:
                                # Not read into memory: a compressed annotation is far smaller than its text.
                                logger.warning(
                                    "%s: cannot read the ego pose: %s is %d bytes, more than an annotation may be",
                                    path, member.name, member.size,
                                )  # fmt: skip
                                break
                            fobj = tar.extractfile(member)
                            data = fobj.read() if fobj is not None else b""
                            try:
                                poses[num] = _pose_row(read_anno(data, name=f"{path}:{member.name}"))
                            except (B2DFormatError, KeyError, TypeError, ValueError, IndexError) as exc:
                                logger.warning("%s: cannot read the ego pose: %s", path, exc)
                        break
        except (tarfile.TarError, EOFError, OSError, ValueError) as exc:
            raise B2DFormatError(path, f"not a readable tar.gz archive: {exc}") from exc
        reader.drain()
    scan.sha256 = reader.sha.hexdigest()
    _assemble(scan, files, poses, str(path))
    return scan


def scan_location(root: Path, loc: ClipLocation, hash_archives: bool = True) -> ClipScan:
    """Scan a discovered clip: its folder when present (plus the archive's hash), else the archive's members."""
    try:
        ClipName.parse(loc.name)
    except ClipNameError as exc:
        where = root / (loc.path or loc.archive)
        return ClipScan(name=loc.name, path=loc.path, archive=loc.archive, error=str(B2DFormatError(where, str(exc))))
    try:
        if loc.path:
            scan = scan_clip_dir(root, loc.path)
            if loc.archive:
                stat = (root / loc.archive).stat()
                scan.archive, scan.archive_size, scan.archive_mtime_ns = loc.archive, stat.st_size, stat.st_mtime_ns
                if hash_archives:
                    scan.sha256 = sha256_file(root / loc.archive)
            return scan
        return scan_archive(root, loc.archive, list_members=True)
    except (B2DFormatError, OSError) as exc:
        logger.warning("cannot index %s: %s", loc.name, exc)
        return ClipScan(name=loc.name, path=loc.path, archive=loc.archive, error=str(exc))


def iter_scans(
    root: Path, locations: list[ClipLocation], workers: int = 0, hash_archives: bool = True
) -> Iterator[ClipScan]:
    """Scan several clips, in a process pool when ``workers > 0`` (results in input order)."""
    if workers <= 0 or len(locations) <= 1:
        for loc in locations:
            yield scan_location(root, loc, hash_archives)
        return
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(workers) as pool:
        yield from pool.map(scan_location, [root] * len(locations), locations, [hash_archives] * len(locations))
