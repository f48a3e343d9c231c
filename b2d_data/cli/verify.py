"""``b2d-verify ROOT --list FILE.json``: check clip archives against the sha256 and size of a split list.

``b2d-verify ROOT --deep``: check every clip's annotations against its own sensors (``num_points`` against the
LAZ files; vehicle, walker, light and sign boxes against the cameras' instance and depth images), per clip.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from b2d_data.loaders.clip_scan import discover_clips, sha256_file
from b2d_data.splits import SplitEntry, SplitManifest


@dataclass(frozen=True)
class Problem:
    """One archive that does not match the list."""

    archive: str
    kind: str  # missing | size | sha256
    detail: str


def find_archives(root: Path, entries: list[SplitEntry]) -> dict[str, Path]:
    """Where each listed archive lies: ``ROOT/<name>.tar.gz``, else anywhere two levels down."""
    found: dict[str, Path] = {}
    others: dict[str, Path] | None = None
    for e in entries:
        direct = root / e.archive_name
        if direct.is_file():
            found[e.clip] = direct
            continue
        if others is None:
            others = {loc.name: root / loc.archive for loc in discover_clips(root) if loc.archive}
        if e.clip in others:
            found[e.clip] = others[e.clip]
    return found


def verify(root: Path, entries: list[SplitEntry], size_only: bool = False, progress: bool = True) -> list[Problem]:
    """Every missing archive and every size or sha256 mismatch, in list order."""
    problems: list[Problem] = []
    paths = find_archives(root, entries)
    to_hash: list[tuple[SplitEntry, Path]] = []
    for e in entries:
        path = paths.get(e.clip)
        if path is None:
            problems.append(Problem(e.archive_name, "missing", f"not found under {root}"))
            continue
        size = path.stat().st_size
        if e.size is not None and size != e.size:
            problems.append(Problem(e.archive_name, "size", f"{path}: {size} bytes, list says {e.size}"))
            continue
        if not size_only and e.sha256:
            to_hash.append((e, path))
    total = sum(p.stat().st_size for _, p in to_hash)
    with tqdm(total=total, unit="B", unit_scale=True, desc="sha256", disable=not progress or not to_hash) as bar:
        for e, path in to_hash:
            digest = sha256_file(path, progress=bar)
            if digest != (e.sha256 or "").lower():
                problems.append(Problem(e.archive_name, "sha256", f"{path}: {digest}, list says {e.sha256}"))
    return problems


def deep_verify(root: Path, every: int, names: set[str] | None, max_lines: int, progress: bool) -> int:
    """Print the cross-sensor check of every clip under ``root``; returns the number of clips that disagree or
    that were asked for and are missing."""
    from b2d_data.loaders.cross_check import iter_checks

    bad = total = 0
    for check in tqdm(iter_checks(root, every, names), desc="clips", unit="clip", disable=not progress):
        total += 1
        checked = ", ".join(f"{kind} {n}" for kind, n in sorted(check.checked.items())) or "nothing to compare"
        if check.ok:
            print(f"OK       {check.clip}: {check.frames} frames; {checked}")
            continue
        bad += 1
        kinds = Counter(d.kind for d in check.disagreements)
        summary = ", ".join(f"{kind} {n}" for kind, n in sorted(kinds.items()))
        print(f"DISAGREE {check.clip}: {check.frames} frames; {checked}; disagreements: {summary}")
        for d in check.disagreements[:max_lines]:
            where = " ".join(x for x in (f"frame {d.frame:05d}", d.box_id and f"box {d.box_id}", d.sensor) if x)
            print(f"  {d.kind:12s} {where}: {d.detail}")
        if len(check.disagreements) > max_lines:
            print(f"  ... {len(check.disagreements) - max_lines} more (--max-lines)")
    missing = sorted(names - {c.name for c in discover_clips(root)}) if names else []
    for name in missing:
        print(f"MISSING  {name}: no such clip under {root}")
    tail = f"; {len(missing)} missing" if missing else ""
    print(f"{total - bad} of {total} clips consistent; {bad} with disagreements{tail}")
    return bad + len(missing)


def main(argv: list[str] | None = None) -> int:
    """Verify archives and/or clip contents; exit code 1 when anything is missing or differs, 2 on unusable
    arguments."""
    parser = argparse.ArgumentParser(prog="b2d-verify", description=__doc__)
    parser.add_argument("root", type=Path, help="corpus folder (the <clip>.tar.gz archives and/or clip folders)")
    parser.add_argument("--list", dest="list_file", type=Path,
                        help="official list (bench2drive_*.json) or a b2d-split manifest")  # fmt: skip
    parser.add_argument("--part", choices=("train", "val", "all"), default="all", help="manifest part to check")
    parser.add_argument("--size-only", action="store_true", help="compare sizes only (no hashing)")
    parser.add_argument("--deep", action="store_true",
                        help="check each clip's boxes against its LiDAR and camera labels")  # fmt: skip
    parser.add_argument("--every", type=int, default=1, help="--deep: check every N-th frame (default 1: all)")
    parser.add_argument("--clip", action="append", default=None, metavar="NAME", help="--deep: only this clip")
    parser.add_argument("--max-lines", type=int, default=20, help="--deep: disagreements printed per clip")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if not args.root.is_dir():
        print(f"b2d-verify: {args.root}: not a folder", file=sys.stderr)
        return 2
    if args.list_file is None and not args.deep:
        print("b2d-verify: nothing to check: pass --list FILE.json and/or --deep", file=sys.stderr)
        return 2
    if args.every < 1:
        print(f"b2d-verify: --every must be at least 1, got {args.every}", file=sys.stderr)
        return 2
    failed = False
    if args.list_file is not None:
        try:
            entries = list(SplitManifest.load(args.list_file).entries(args.part))
        except (FileNotFoundError, ValueError) as exc:
            print(f"b2d-verify: {exc}", file=sys.stderr)
            return 2
        problems = verify(args.root, entries, size_only=args.size_only, progress=not args.no_progress)
        for p in problems:
            print(f"{p.kind.upper():8s} {p.archive}: {p.detail}")
        ok = len(entries) - len(problems)
        print(f"{ok} of {len(entries)} archives match {args.list_file.name}; {len(problems)} problem(s)")
        failed = bool(problems)
    if args.deep:
        names = set(args.clip) if args.clip else None
        failed |= deep_verify(args.root, args.every, names, max(0, args.max_lines), not args.no_progress) > 0
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
