"""``b2d-collect``: drive the expert through scenario routes on the builtin simulator and write Bench2Drive clips.

Examples::

    b2d-collect --scenario Accident --n 50 --out data/
    b2d-collect --scenario HardBreakRoute --scenario ParkingExit --n 10 --workers 2 --out data/
    b2d-collect --routes bench2drive220.xml --scenario Accident --out b2d220/    # the shipped routes and towns
    b2d-collect --scenario Accident --n 50 --out data/ --resume        # after a crash or kill -9
    b2d-collect --preset base --out base/                               # Bench2Drive-base's mix, 950/50 split
    b2d-collect --preset base --n-scale 0.1 --out sample/               # a tenth of it

``--preset mini|base|full`` copies the scenario types, weathers and (where b2d-data ships them and they hold the
type) towns of Bench2Drive's official lists clip by clip, other towns replaced by the generated ones; ``uniform`` is
v0.0.4's 44 types x 25 routes. It writes ``OUT/splits/<preset>.json`` (train/val as the official split), which
``ClipDataset(OUT, split="train")`` reads.

Clips are named ``<Scenario>_<Town>_Route<id>_Weather<w>``; only routes the expert completes without infraction
(min-speed aside) become clips, unless ``--keep-failed`` (kept under ``OUT/failed/``). Every attempt is appended
to ``OUT/run_log.jsonl``; per-route Leaderboard records go to ``OUT/results/`` (``b2d-eval summary OUT/results``);
the final table is saved as ``OUT/summary.json``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from tqdm import tqdm

from b2d_data.cli.signals import restore_sigterm, stop_on_sigterm
from b2d_data.cli.ticking_bar import TickingBar
from b2d_data.format.version import DEFAULT_FORMAT, FormatVersion

if TYPE_CHECKING:  # the collection's modules load only when a collection runs (a fast --help)
    from b2d_data.collection.runner import Progress

PROG = "b2d-collect"
#: ``--params`` values (scenarios.param_ranges.PARAM_SETS, spelled out here to keep --help fast); the first is the default.
PARAM_SET_NAMES = ("training", "bench2drive220")
#: ``--preset`` values (collection.presets.PRESET_NAMES, spelled out here to keep --help fast).
PRESET_NAMES = ("mini", "base", "full", "uniform")
#: Exit status when the targets were not all met (usage errors exit with 2, like argparse).
EXIT_SHORT = 1
EXIT_USAGE = 2


class _TqdmHandler(logging.Handler):
    """Log lines printed above the progress bar instead of through it."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            tqdm.write(self.format(record), file=sys.stderr)
        except Exception:  # noqa: BLE001 - logging's own contract: report, never raise
            self.handleError(record)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``b2d-collect``."""
    p = argparse.ArgumentParser(prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    what = p.add_argument_group("what to collect")
    what.add_argument(
        "--scenario",
        action="append",
        default=[],
        metavar="NAME",
        help="scenario type (repeatable), e.g. Accident; with --routes, a filter",
    )
    what.add_argument(
        "--n", type=int, default=None, help="clips per scenario (default 1; with --routes: every selected route)"
    )
    what.add_argument(
        "--preset",
        choices=PRESET_NAMES,
        default=None,
        help="a Bench2Drive-sized corpus with its train/val split: the official mini (10), base (1000) or full "
        "(13638) lists' mix of scenarios, weathers and towns, or uniform (44 types x 25)",
    )
    what.add_argument(
        "--n-scale",
        type=float,
        default=None,
        metavar="S",
        help="with --preset: scale its clips by S (0.1: a tenth, in the same proportions)",
    )
    what.add_argument("--out", type=Path, required=False, help="corpus folder (created if needed)")
    where = what.add_mutually_exclusive_group()
    where.add_argument(
        "--town",
        metavar="TOWN",
        help="generated preset (all, urban, Town100 ...; default: the one with every layout) or a shipped CARLA town "
        "(Town01, Town04, Town06, Town07, Town10HD)",
    )
    where.add_argument(
        "--xodr",
        type=Path,
        metavar="FILE|DIR",
        help="an OpenDRIVE town (its stem is the town name), or with --routes a folder of <Town>.xodr",
    )
    what.add_argument(
        "--routes",
        type=Path,
        metavar="FILE.xml",
        help="run the routes of a Leaderboard route file (a bare shipped name such as bench2drive220.xml works)",
    )
    what.add_argument(
        "--weather",
        type=int,
        action="append",
        default=[],
        metavar="ID",
        help="weather preset id (repeatable; default: all 23 for generated routes, the file's own)",
    )
    what.add_argument("--seed", type=int, default=0, help="seed of the route list and of every route (default 0)")
    what.add_argument(
        "--params",
        choices=PARAM_SET_NAMES,
        default=None,
        help="parameter ranges of generated routes: training (LB2.0 routes_training.xml, default) or bench2drive220 "
        "(the evaluation routes' narrower ranges)",
    )
    how = p.add_argument_group("how")
    how.add_argument(
        "--workers",
        type=_workers_arg,
        default="auto",
        help="routes run in parallel processes, or auto (default): one per core with a GPU, else 1 with encoders",
    )
    how.add_argument(
        "--encode-workers",
        type=int,
        default=None,
        help="encoder processes per clip (default: several with --workers 1, else none)",
    )
    how.add_argument(
        "--ray",
        metavar="ADDRESS",
        default=None,
        help="run one Ray task per route on a cluster (auto, host:port, or local); needs b2d-data[ray]",
    )
    how.add_argument("--resume", action="store_true", help="continue the collection in --out after a stop or crash")
    how.add_argument("--keep-failed", action="store_true", help="keep the clips of failed routes under OUT/failed/")
    how.add_argument(
        "--attempts-per-clip",
        type=int,
        default=3,
        help="generated routes tried per requested clip before giving up (default 3)",
    )
    how.add_argument(
        "--no-sensors", action="store_true", help="physics only: run and score the routes, write records but no clip"
    )
    fmt = p.add_argument_group("format")
    fmt.add_argument("--width", type=int, default=1600, help="camera width in pixels (default 1600)")
    fmt.add_argument("--height", type=int, default=900, help="camera height in pixels (default 900)")
    fmt.add_argument(
        "--lidar-azimuth-steps", type=int, default=1000, help="LiDAR rays per channel and sweep (default 1000)"
    )
    fmt.add_argument(
        "--format-version",
        default=DEFAULT_FORMAT.value,
        choices=[v.value for v in FormatVersion],
        help=f"on-disk layout (default {DEFAULT_FORMAT.value})",
    )
    out = p.add_argument_group("output")
    out.add_argument("--list-scenarios", action="store_true", help="print the scenarios that can be generated")
    out.add_argument("--no-progress", action="store_true", help="no progress bar")
    out.add_argument("-v", "--verbose", action="count", default=0, help="log more (-v info, -vv debug)")
    return p


def _workers_arg(value: str) -> int | str:
    if value == "auto":
        return value
    try:
        return int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or auto, got {value!r}") from None


def _layout(args: argparse.Namespace) -> tuple[int, int | None]:
    """(route processes, encoder processes per route) from --workers / --encode-workers, resolving auto."""
    if args.workers != "auto":
        return args.workers, args.encode_workers
    if args.ray is not None:  # the cluster's CPUs decide; Ray tasks encode inline
        return 1, args.encode_workers
    from b2d_data.collection.layout import auto_layout

    layout = auto_layout()
    return layout.workers, args.encode_workers if args.encode_workers is not None else layout.encode_workers


def _config(args: argparse.Namespace):
    from b2d_data.collection.job import CollectConfig

    workers, encode_workers = _layout(args)
    return CollectConfig(
        out=args.out, scenarios=tuple(args.scenario), n=args.n, town=args.town, xodr=args.xodr,
        routes_file=args.routes, weathers=tuple(args.weather), workers=workers, seed=args.seed,
        resume=args.resume, keep_failed=args.keep_failed, width=args.width, height=args.height,
        lidar_azimuth_steps=args.lidar_azimuth_steps, format_version=FormatVersion(args.format_version),
        sensors=not args.no_sensors, encode_workers=encode_workers,
        attempts_per_clip=args.attempts_per_clip, ray_address=args.ray,
        params=args.params or PARAM_SET_NAMES[0], preset=args.preset,
        n_scale=args.n_scale if args.n_scale is not None else 1.0,
    )  # fmt: skip


def _check_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    if args.out is None:
        parser.error("--out DIR is required")
    if args.width < 16 or args.height < 16:
        parser.error("--width and --height must be at least 16 pixels")
    if args.lidar_azimuth_steps < 1:
        parser.error("--lidar-azimuth-steps must be positive")
    if args.attempts_per_clip < 1:
        parser.error("--attempts-per-clip must be at least 1")
    if args.encode_workers is not None and args.encode_workers < 0:
        parser.error("--encode-workers must be 0 or more")
    if args.params is not None and args.routes is not None:
        parser.error("--params sets the ranges of generated routes; --routes runs the file's own parameters")
    if args.n_scale is not None and args.preset is None:
        parser.error("--n-scale scales a --preset")
    if args.preset is not None:
        given = [flag for flag, value in (("--scenario", args.scenario), ("--n", args.n), ("--routes", args.routes),
                                          ("--town", args.town), ("--xodr", args.xodr), ("--weather", args.weather))
                 if value]  # fmt: skip
        if given:
            parser.error(f"--preset decides scenarios, counts, towns and weathers itself; drop {', '.join(given)}")
        if args.n_scale is not None and not args.n_scale > 0:
            parser.error(f"--n-scale must be positive, got {args.n_scale}")


def main(argv: list[str] | None = None) -> int:
    """Run ``b2d-collect``; returns the exit status (0 done, 1 targets not met, 2 usage error, 130 interrupted)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING if args.verbose == 0 else logging.INFO if args.verbose == 1 else logging.DEBUG
    handler = _TqdmHandler()
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    previous_level = root.level
    root.setLevel(level)
    previous_term = stop_on_sigterm()
    from b2d_data.collection.temp_dir import private_temp_dir

    try:
        with private_temp_dir():  # no pymp-* folder outlives a killed run
            return _run(parser, args)
    finally:
        root.removeHandler(handler)
        root.setLevel(previous_level)
        restore_sigterm(previous_term)


class ProgressLine(TickingBar):
    """The progress bar: clips over the target, attempts, the running routes' frames, elapsed time and ETA.

    The collection reports at least every second while routes run; the ticker also redraws every second (counting
    the ETA down from the last report) so that the clock moves through a route's slow set-up too.
    """

    BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} clips, {elapsed} elapsed{postfix}"

    def __init__(self, enabled: bool, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(PROG, enabled, clock)
        self.failures = 0
        self._last: Progress | None = None

    def __call__(self, p: Progress) -> None:
        """The collection's progress callback."""
        if p.resumed is not None:
            self.write(p.resumed.describe())
        if p.result is not None and p.result.status != "clip":
            self.failures += 1
            if self.enabled:
                self.write(f"route {p.result.route_id} ({p.result.scenario}): {p.result.status} - {p.result.reason}")
        with self._lock:
            self._last = p
            self.reported(p.requested)

    def count(self) -> int:
        """Clips made."""
        return self._last.clips if self._last is not None else 0

    def text(self) -> str:
        """The part after the clock: attempts, failures, running routes' frames, ETA (counted down since the
        last report)."""
        p = self._last
        if p is None:
            return ""
        eta = None if p.eta is None else max(p.eta - self.since_report(), 0.0)
        return f"{p.attempts} attempts, {self.failures} failed | {replace(p, eta=eta).describe()}"


def _run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    from b2d_data.collection.disk_space import is_disk_full
    from b2d_data.collection.plan import CollectError, implemented_scenarios
    from b2d_data.collection.runner import collect, summary_table
    from b2d_data.collection.towns import TownError
    from b2d_data.format.errors import B2DFormatError

    if args.list_scenarios:
        print("\n".join(implemented_scenarios()))
        return 0
    _check_args(parser, args)
    line = ProgressLine(enabled=not args.no_progress)
    try:
        summary = collect(_config(args), line)
    except (CollectError, TownError, B2DFormatError) as exc:
        line.close()
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        line.close()
        print(f"{PROG}: interrupted; run the same command with --resume to finish", file=sys.stderr)
        return 130
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        line.close()  # the driver's own files (run log, summary) hit the full disk
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{PROG}: error: {where}no space left on device; free space, then run the same command with --resume",
              file=sys.stderr)  # fmt: skip
        return EXIT_SHORT
    line.close()
    print(summary_table(summary))
    per_clip = summary.seconds_per_clip
    timing = f", {per_clip:.1f} s per clip" if per_clip is not None else ""
    kind = "records" if not summary.sensors else "clips"
    lost = f" (+{summary.lost_this_run} lost)" if summary.lost_this_run else ""  # the table says what lost is
    print(
        f"{summary.clips_this_run} {kind} from {summary.attempts_this_run} attempts{lost} in "
        f"{summary.wall_seconds:.1f} s{timing}; summary in {Path(summary.out) / 'summary.json'}"
    )
    if summary.manifest is not None:
        train, val = summary.manifest_clips
        print(f"split manifest {summary.manifest}: {train} train + {val} val clips")
    if summary.left_out:
        what = ", ".join(f"{reason} x{n}" for reason, n in summary.left_out.items())
        print(f"left out {sum(summary.left_out.values())} clip(s) of the official list: {what}")
    if summary.skipped_routes:
        print(f"skipped {len(summary.skipped_routes)} route(s) without a map: {', '.join(summary.skipped_routes[:10])}")
    if not summary.complete:
        short = [f"{s.scenario} {s.clips}/{s.requested}" for s in summary.scenarios if not s.complete]
        if summary.disk_full is not None:
            print(f"{PROG}: targets not met: {', '.join(short)}: {summary.disk_full.describe()}", file=sys.stderr)
            return EXIT_SHORT
        # a route file's routes are fixed: only generated collections can try other routes
        hint = (f"why each route failed: {Path(summary.out) / 'run_log.jsonl'}" if args.routes is not None
                else "raise --attempts-per-clip or use another --seed")  # fmt: skip
        print(f"{PROG}: targets not met: {', '.join(short)} ({hint})", file=sys.stderr)
        return EXIT_SHORT
    return 0


if __name__ == "__main__":
    sys.exit(main())
