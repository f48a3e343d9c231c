"""Where a collection's frames went: frames of the attempts that made a clip and of those that did not.

A route that stands until Bench2Drive's 4000-tick limit runs 2001 frames (10 Hz) and makes no clip, about nine
ordinary routes' worth of rendering. This prints, for one or more run logs, the frames of each kind, the share spent
on attempts without a clip, and the longest of those with their reasons. A physics-only run (``--no-sensors``) counts
its recorded ticks as frames (``progress.frames_of``), so a quick sample serves:

    b2d-collect --preset base --n-scale 0.25 --no-sensors --out DIR
    python scripts/run_log_frames.py DIR/run_log.jsonl
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from b2d_data.collection import run_log as rl  # noqa: E402
from b2d_data.collection.job import STATUS_CLIP  # noqa: E402
from b2d_data.collection.progress import frames_of  # noqa: E402
from b2d_data.collection.runner import is_lost  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("logs", nargs="+", type=Path, help="run_log.jsonl files")
    parser.add_argument("--longest", type=int, default=5, help="failed attempts listed, longest first")
    args = parser.parse_args()
    for path in args.logs:
        finals = [r for r in rl.read_run_log(path) if r.get("event") == rl.EVENT_ATTEMPT and not is_lost(r)]
        frames = [(frames_of(int(r.get("ticks") or 0), int(r.get("frames") or 0)), r) for r in finals]
        clip = sum(f for f, r in frames if r.get("status") == STATUS_CLIP)
        failed = sorted(((f, r) for f, r in frames if r.get("status") != STATUS_CLIP), key=lambda fr: -fr[0])
        lost = sum(f for f, _ in failed)
        total = clip + lost
        share = lost / total if total else 0.0
        print(f"{path}: {len(finals)} attempts, {total} frames; {len(finals) - len(failed)} clips {clip} frames, "
              f"{len(failed)} without a clip {lost} frames ({share:.1%})")  # fmt: skip
        for f, r in failed[: args.longest]:
            print(f"  {f:5d} frames  route {r.get('route_id')} {r.get('scenario')} on {r.get('town')}: "
                  f"{r.get('reason') or r.get('status')}")  # fmt: skip


if __name__ == "__main__":
    main()
