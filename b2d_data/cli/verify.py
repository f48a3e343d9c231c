"""``b2d-verify ROOT --list FILE.json``: check clip archives against the sha256 and size of a split list."""

from __future__ import annotations

import argparse
import sys
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


def main(argv: list[str] | None = None) -> int:
    """Verify archives; exit code 1 when anything is missing or differs, 2 on unusable arguments."""
    parser = argparse.ArgumentParser(prog="b2d-verify", description=__doc__)
    parser.add_argument("root", type=Path, help="folder holding the <clip>.tar.gz archives")
    parser.add_argument("--list", dest="list_file", type=Path, required=True,
                        help="official list (bench2drive_*.json) or a b2d-split manifest")  # fmt: skip
    parser.add_argument("--part", choices=("train", "val", "all"), default="all", help="manifest part to check")
    parser.add_argument("--size-only", action="store_true", help="compare sizes only (no hashing)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if not args.root.is_dir():
        print(f"b2d-verify: {args.root}: not a folder", file=sys.stderr)
        return 2
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
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
