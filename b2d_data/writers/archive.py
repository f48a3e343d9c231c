"""Clip archives (``<clip>.tar.gz``), their sha256/size, and split lists in the official format (format.md §1.2).

Archive layout (our decision; the released one is undocumented): every member lies under one root folder
``<clip>/`` (``<clip>/anno/00000.json.gz`` …), so ``tar xzf`` in ``data/bench2drive/v1/`` gives the layout
Bench2DriveZoo expects. Members are added in sorted order with owner 0/0 and no gzip time stamp, so packing the
same folder twice gives the same bytes. ``extract_archive`` also accepts archives without the root folder.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import logging
import os
import re
import secrets
import shutil
import tarfile
import zlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import BinaryIO

from b2d_data.format.errors import B2DFormatError
from b2d_data.format.names import ClipName

logger = logging.getLogger(__name__)

_CHUNK = 1 << 20
_DRIVE_RE = re.compile(r"^[A-Za-z]:")


@dataclass(frozen=True)
class ArchiveInfo:
    """One entry of a split list: the archive's file name, sha256 (lowercase hex) and size in bytes."""

    name: str
    sha256: str
    size: int

    def to_json(self) -> dict[str, object]:
        """The value stored under the archive name in a split list."""
        return {"sha256": self.sha256, "size": self.size}


class _HashingWriter:
    """A write-only file wrapper that hashes and counts what passes through it."""

    def __init__(self, raw: BinaryIO) -> None:
        self.raw = raw
        self.hash = hashlib.sha256()
        self.size = 0

    def write(self, data: bytes) -> int:
        self.hash.update(data)
        self.size += len(data)
        return self.raw.write(data)

    def flush(self) -> None:
        self.raw.flush()


def sha256_file(path: str | os.PathLike[str]) -> str:
    """Lowercase hex sha256 of a file, read in 1 MiB chunks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            digest.update(chunk)
    return digest.hexdigest()


def archive_info(path: str | os.PathLike[str]) -> ArchiveInfo:
    """Hash an existing archive."""
    p = Path(path)
    return ArchiveInfo(p.name, sha256_file(p), p.stat().st_size)


def _tar_filter(info: tarfile.TarInfo) -> tarfile.TarInfo:
    info.uid = info.gid = 0
    info.uname = info.gname = ""
    return info


def pack_clip(
    clip_dir: str | os.PathLike[str], out_dir: str | os.PathLike[str] | None = None, *, compresslevel: int = 6
) -> ArchiveInfo:
    """Pack ``clip_dir`` as ``<out_dir>/<clip>.tar.gz`` (default: beside the clip) and return its sha256 and size.

    The archive appears atomically (written to a temporary name, then renamed). Level 6 by default: the members
    are JPEG/PNG/LAZ/gzip already, so higher levels cost time for almost nothing.
    """
    src = Path(clip_dir)
    if not src.is_dir():
        raise FileNotFoundError(f"clip folder {src} does not exist")
    clip = str(ClipName.parse(src.name))
    dest_dir = Path(out_dir) if out_dir is not None else src.parent
    dest_dir.mkdir(parents=True, exist_ok=True)
    target = dest_dir / f"{clip}.tar.gz"
    temp = dest_dir / f".{target.name}.tmp-{os.getpid()}-{secrets.token_hex(3)}"
    try:
        with open(temp, "wb") as raw:
            hashing = _HashingWriter(raw)
            # No name and a zero time stamp in the gzip header: the same folder always packs to the same bytes.
            gz = gzip.GzipFile(
                filename="", mode="wb", fileobj=hashing, compresslevel=compresslevel, mtime=0  # type: ignore[arg-type]
            )
            with gz, tarfile.open(fileobj=gz, mode="w", format=tarfile.PAX_FORMAT) as tar:
                tar.add(src, arcname=clip, recursive=False, filter=_tar_filter)
                for path in sorted(src.rglob("*")):
                    if path.is_symlink() or not (path.is_file() or path.is_dir()):
                        raise ValueError(f"{path}: only regular files and folders can be archived")
                    arcname = f"{clip}/{path.relative_to(src).as_posix()}"
                    tar.add(path, arcname=arcname, recursive=False, filter=_tar_filter)
        os.replace(temp, target)
    finally:
        temp.unlink(missing_ok=True)
    info = ArchiveInfo(target.name, hashing.hash.hexdigest(), hashing.size)
    logger.info("packed %s: %d bytes, sha256 %s", target, info.size, info.sha256)
    return info


def verify_archive(path: str | os.PathLike[str], expected: ArchiveInfo) -> None:
    """Raise ``B2DFormatError`` when the archive's size or sha256 differs from its split-list entry."""
    p = Path(path)
    if not p.is_file():
        raise B2DFormatError(p, "archive does not exist")
    size = p.stat().st_size
    if size != expected.size:
        raise B2DFormatError(p, f"size {size} differs from the split list's {expected.size} (incomplete download?)")
    digest = sha256_file(p)
    if digest != expected.sha256:
        raise B2DFormatError(p, f"sha256 {digest} differs from the split list's {expected.sha256}")


def _member_parts(member: tarfile.TarInfo, archive: Path) -> tuple[str, ...]:
    name = member.name
    if name.startswith(("/", "\\")) or _DRIVE_RE.match(name):
        raise B2DFormatError(archive, f"unsafe member {name!r}: absolute path")
    parts = tuple(p for p in PurePosixPath(name).parts if p not in ("", "."))
    if ".." in parts or any("\\" in p for p in parts):
        raise B2DFormatError(archive, f"unsafe member {member.name!r}: leaves the extraction folder")
    if not (member.isfile() or member.isdir()):
        raise B2DFormatError(archive, f"unsupported member {member.name!r}: only regular files and folders")
    return parts


def _extract_members(src: Path, clip: str, temp: Path) -> None:
    try:
        with tarfile.open(src, mode="r:*") as tar:
            members = tar.getmembers()
            parts = [_member_parts(m, src) for m in members]
            roots = {p[0] for p in parts if p}
            rooted = roots == {clip}
            if clip in roots and not rooted:
                raise B2DFormatError(src, f"members both inside and outside the root folder {clip}/")
            if rooted and any(len(p) == 1 and not m.isdir() for p, m in zip(parts, members)):
                raise B2DFormatError(src, f"the root {clip} must be a folder")
            for member, member_parts in zip(members, parts):
                rel = member_parts[1:] if rooted else member_parts
                if not rel:
                    continue
                target = temp.joinpath(*rel)
                if member.isdir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                fileobj = tar.extractfile(member)
                assert fileobj is not None  # regular files always have data
                with fileobj, open(target, "wb") as out:
                    shutil.copyfileobj(fileobj, out, _CHUNK)
                os.utime(target, (member.mtime, member.mtime))
    except (tarfile.TarError, EOFError, zlib.error, gzip.BadGzipFile) as exc:
        raise B2DFormatError(src, f"corrupt or truncated archive: {exc}") from exc


def extract_archive(
    archive: str | os.PathLike[str], dest: str | os.PathLike[str], *, overwrite: bool = False
) -> Path:
    """Extract ``<clip>.tar.gz`` into ``dest`` and return ``dest/<clip>``; the clip folder appears atomically.

    Refuses (``B2DFormatError``) absolute paths, ``..``, links, devices and members outside a single ``<clip>/``
    root; an archive whose members have no root folder is extracted into ``dest/<clip>`` as well.
    """
    src = Path(archive)
    if not src.is_file():
        raise B2DFormatError(src, "archive does not exist")
    clip = str(ClipName.parse(src.name))
    dest_dir = Path(dest)
    final = dest_dir / clip
    if final.exists() and not overwrite:
        raise FileExistsError(f"clip {final} already exists (pass overwrite=True to replace it)")
    dest_dir.mkdir(parents=True, exist_ok=True)
    temp = dest_dir / f".{clip}.tmp-{os.getpid()}-{secrets.token_hex(3)}"
    temp.mkdir()
    try:
        _extract_members(src, clip, temp)
        if final.exists():
            old = dest_dir / f".{clip}.old-{os.getpid()}-{secrets.token_hex(3)}"
            os.rename(final, old)
            os.rename(temp, final)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(temp, final)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    return final


def split_list_text(entries: Iterable[ArchiveInfo] | Mapping[str, ArchiveInfo]) -> str:
    """The official split-list text: ``{"<clip>.tar.gz": {"sha256", "size"}}``, 4-space indent, keys sorted."""
    items = entries.values() if isinstance(entries, Mapping) else entries
    data: dict[str, dict[str, object]] = {}
    for info in items:
        if info.name in data:
            raise ValueError(f"archive {info.name} listed twice")
        data[info.name] = info.to_json()
    # sort_keys sorts in plain string order (``AccidentTwoWays_…`` before ``Accident_…``) and puts "sha256"
    # before "size" inside each entry, as in the released files; those end without a newline.
    return json.dumps(data, indent=4, sort_keys=True)


def write_split_list(
    path: str | os.PathLike[str], entries: Iterable[ArchiveInfo] | Mapping[str, ArchiveInfo]
) -> Path:
    """Write a split list (atomically) and return its path."""
    target = Path(path)
    text = split_list_text(entries)
    temp = target.parent / f".{target.name}.tmp-{os.getpid()}-{secrets.token_hex(3)}"
    try:
        temp.write_text(text, encoding="utf-8")
        os.replace(temp, target)
    finally:
        temp.unlink(missing_ok=True)
    return target


def read_split_list(path: str | os.PathLike[str]) -> dict[str, ArchiveInfo]:
    """Read an official or our own split list into {archive name: ArchiveInfo}, in file order."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise B2DFormatError(p, "split list does not exist") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise B2DFormatError(p, f"invalid JSON: {exc}") from exc
    if not isinstance(data, dict):
        raise B2DFormatError(p, "a split list must be a JSON object keyed by archive name")
    out: dict[str, ArchiveInfo] = {}
    for name, entry in data.items():
        sha, size = (entry.get("sha256"), entry.get("size")) if isinstance(entry, dict) else (None, None)
        if not isinstance(sha, str) or len(sha) != 64 or not isinstance(size, int) or isinstance(size, bool):
            raise B2DFormatError(p, f"entry {name!r} must be {{'sha256': 64 hex chars, 'size': int}}, got {entry!r}")
        out[name] = ArchiveInfo(name, sha.lower(), size)
    return out
