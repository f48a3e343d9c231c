"""CPU cost of a frame's label PNGs (6 × depth, semantic, instance) read back as images against read back as PNG
scanlines (``Renderer(png_rows=True)``: a zero filter byte before every row, deflated where they lie).

Both layouts sit in one ~70 MB block, as a frame's read-back does, and the block is written again before every round
(a read-back leaves most of it outside the CPU caches, as here). Images are blocky label-like content; deflate costs
the same in both layouts (ISA-L, filter None against SUB), so the difference is the filtering pass and its copy.

    python scripts/bench_png_rows.py [--rounds 20] [--width 1600 --height 900]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from b2d_data.codecs.depth import encode_depth_png
from b2d_data.codecs.labels_png import encode_instance_png, encode_semantic_png
from b2d_data.codecs.png import png_rows
from b2d_data.format.label_pixels import label_views

CAMERAS = 6
BLOCK = 70 << 20


def _blocky(rng: np.random.Generator, h: int, w: int, c: int) -> np.ndarray:
    """Rectangles of constant value on a constant background, like a label image."""
    img = np.full((h, w, c), 3, np.uint8)
    for _ in range(300):
        y, x = int(rng.integers(0, h - 40)), int(rng.integers(0, w - 40))
        img[y : y + int(rng.integers(4, 120)), x : x + int(rng.integers(4, 200))] = rng.integers(0, 256, c)
    return img


def _layout(block: np.ndarray, h: int, w: int, rows: bool) -> tuple[list, list[np.ndarray]]:
    """Each camera's (depth, labels, semantic) as views of ``block``, laid out as the renderer lays them out, and the
    whole lines they lie in."""
    out, lines, offset, lead = [], [], 0, 1 if rows else 0

    def take(nbytes: int) -> np.ndarray:
        nonlocal offset
        view = block[offset : offset + nbytes]
        offset += -(-nbytes // 64) * 64
        return view

    for _ in range(CAMERAS):
        depth = take(h * (w + lead)).reshape(h, w + lead)
        labels = take(h * (4 * w + lead)).reshape(h, 4 * w + lead)
        semantic = take(h * (w + lead)).reshape(h, w + lead)
        lines += [depth, labels, semantic]
        if rows:
            out.append((depth[:, 1:], labels[:, 1:].reshape(h, w, 4), semantic[:, 1:]))
        else:
            out.append((depth, labels.reshape(h, w, 4), semantic))
    return out, lines


def _fill(layout: tuple[list, list[np.ndarray]], depth: np.ndarray, labels: np.ndarray, tags: np.ndarray,
          rows: bool) -> None:  # fmt: skip
    images, lines = layout
    for d, lab, s in images:
        d[...] = depth
        lab[...] = labels
        s[...] = tags
    if rows:  # the unpack pass writes the filter bytes
        for line in lines:
            line[:, 0] = 0


def _encode(images: list) -> int:
    written = 0
    for depth, labels, semantic in images:
        _, ids = label_views(labels)
        written += len(encode_depth_png(depth)) + len(encode_semantic_png(semantic))
        written += len(encode_instance_png(semantic, ids, packed=labels))
    return written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=900)
    args = parser.parse_args()
    h, w = args.height, args.width
    rng = np.random.default_rng(0)
    labels = _blocky(rng, h, w, 4)
    labels[..., 3] = 255
    tags, depth = np.ascontiguousarray(labels[..., 0]), _blocky(rng, h, w, 1)[..., 0]
    source = rng.integers(0, 256, BLOCK, dtype=np.uint8)
    block = np.zeros(BLOCK, np.uint8)
    layouts = {"images": _layout(block, h, w, False), "scanlines": _layout(block, h, w, True)}
    for name, layout in layouts.items():
        _fill(layout, depth, labels, tags, name == "scanlines")
    assert png_rows(layouts["scanlines"][0][0][1]) is not None and png_rows(layouts["images"][0][0][1]) is None
    cpu: dict[str, list[float]] = {name: [] for name in layouts}
    sizes: dict[str, int] = {}
    for _ in range(args.rounds):
        for name, layout in layouts.items():
            block[...] = source  # a frame's read-back passes through the caches before the encoders run
            _fill(layout, depth, labels, tags, name == "scanlines")
            start = time.process_time()
            sizes[name] = _encode(layout[0])
            cpu[name].append(time.process_time() - start)
    base = statistics.median(cpu["images"])
    print(f"{CAMERAS} cameras × (depth, semantic, instance) PNG at {w}×{h}, {args.rounds} rounds alternated:")
    for name, values in cpu.items():
        med = statistics.median(values)
        print(f"  {name:<10} {1e3 * med:6.2f} CPU ms per frame (median), {sizes[name] / 1024:7.1f} KB, "
              f"×{med / base:.2f} of images")


if __name__ == "__main__":
    main()
