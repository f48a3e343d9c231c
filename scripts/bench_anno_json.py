"""CPU time of the annotation text (``anno_text``) against ``json.dumps(indent=4)``, measured in the same run.

Reads collected annotations (``anno/*.json.gz`` under the given folders), checks that the fast writer's text equals
json's for every one of them, then times both (best of ``--repeat`` passes over all frames, process CPU time) and
the full ``encode_anno`` (text + gzip level 9)::

    b2d-collect --scenario Accident --n 1 --out /tmp/clip --width 160 --height 90
    python scripts/bench_anno_json.py /tmp/clip
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

from b2d_data.codecs import anno_json
from b2d_data.codecs.anno_json import dumps_indent4, encode_anno, read_anno


def best_ms(fn: Callable[[dict], object], annos: list[dict], repeat: int) -> float:
    """Best per-frame CPU milliseconds of ``fn`` over ``repeat`` passes through every annotation."""
    best = float("inf")
    for _ in range(repeat):
        start = time.process_time()
        for anno in annos:
            fn(anno)
        best = min(best, time.process_time() - start)
    return 1e3 * best / len(annos)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folders", nargs="+", type=Path, help="corpus or clip folders holding anno/*.json.gz")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--max-frames", type=int, default=400)
    args = parser.parse_args()
    files = sorted(f for folder in args.folders for f in folder.rglob("anno/*.json.gz"))[: args.max_frames]
    if not files:
        raise SystemExit("no anno/*.json.gz under the given folders")
    annos = [read_anno(f) for f in files]
    mismatches = [f for f, anno in zip(files, annos) if dumps_indent4(anno) != json.dumps(anno, indent=4)]
    if mismatches:
        raise SystemExit(f"fast writer differs from json.dumps on {len(mismatches)} frames, e.g. {mismatches[0]}")
    mean_kb = sum(len(json.dumps(a, indent=4)) for a in annos) / len(annos) / 1e3
    print(f"{len(annos)} frames, {mean_kb:.0f} KB of text each; texts identical to json.dumps(indent=4)")
    # Alternated so that both see the same machine load.
    reference = best_ms(lambda a: json.dumps(a, indent=4), annos, args.repeat)
    fast = best_ms(dumps_indent4, annos, args.repeat)
    reference = min(reference, best_ms(lambda a: json.dumps(a, indent=4), annos, args.repeat))
    fast = min(fast, best_ms(dumps_indent4, annos, args.repeat))
    encoded = best_ms(encode_anno, annos, args.repeat)
    # encode_anno as it was, its text from json.dumps (the writer swapped out for the measurement only).
    writer = anno_json.dumps_indent4
    anno_json.dumps_indent4 = lambda obj: json.dumps(obj, indent=4)
    try:
        encoded_before = best_ms(encode_anno, annos, args.repeat)
    finally:
        anno_json.dumps_indent4 = writer
    encoded = min(encoded, best_ms(encode_anno, annos, args.repeat))
    print(f"json.dumps(indent=4)  {reference:6.3f} ms/frame")
    print(f"dumps_indent4         {fast:6.3f} ms/frame  (x{fast / reference:.2f} of json.dumps)")
    print(f"encode_anno (+gzip 9) {encoded:6.3f} ms/frame  (x{encoded / encoded_before:.2f} of "
          f"{encoded_before:.3f} with json.dumps)")  # fmt: skip


if __name__ == "__main__":
    main()
