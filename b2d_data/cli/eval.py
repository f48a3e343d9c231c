"""``b2d-eval``: closed-loop evaluation of Leaderboard agents and Bench2Drive metrics of result files.

``b2d-eval run --agent AGENT.py --routes FILE.xml --out DIR [...]`` evaluates an agent (``cli/eval_run.py``).

``b2d-eval summary RESULTS... [--routes XML] [--metric-dir DIR] [--maps-dir DIR] [--num-routes N]
[--out PATH.json] [--names NAME...] [--strict] [--corrected-smoothness] [--merge]``

Each RESULT is one result set, shown as one column: a result JSON file (per-process checkpoint or
merged.json), a directory of per-process files (every ``*.json`` but merged.json), the output folder of
``b2d-eval run`` (its records, route file, route count and metric_info are used), or several files
joined with ``+`` (``eval_0.json+eval_1.json``). ``--merge`` makes all RESULTS one set instead (handy
with a shell glob). The table goes to stdout, every figure to the JSON file, and, when the routes are
known, a bar chart of the abilities to ``<out stem>_abilities.png`` beside the JSON. Without ``--out`` the JSON
goes beside the first RESULT: ``<RESULT>_summary.json`` (``OUT/results`` → ``OUT/results_summary.json``),
``<folder>/summary.json`` for a ``b2d-eval run`` folder, and the current folder only for a file the package ships.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

from b2d_data.data import shipped_or_given
from b2d_data.eval.junctions import MapJunctionProvider
from b2d_data.eval.report import format_table, plot_abilities
from b2d_data.eval.results import expand_result_argument, load_result_argument, load_result_set
from b2d_data.eval.summary import EvalSettings, SetSummary, evaluate, summary_json
from b2d_data.format.errors import B2DFormatError
from b2d_data.scenarios.route_xml import read_routes

PROG = "b2d-eval"
#: What the summary JSON is called beside a result set (``<name>_summary.json``).
SUMMARY_SUFFIX = "_summary.json"


def _argument_problem(args: argparse.Namespace) -> str | None:
    """What is inconsistent between the arguments, or None."""
    n_sets = 1 if args.merge else len(args.results)
    if args.names is not None and len(args.names) != n_sets:
        return f"--names gives {len(args.names)} label(s) for {n_sets} result set(s)"
    if len(args.metric_dir) not in (0, 1, n_sets):
        return f"--metric-dir is given {len(args.metric_dir)} times for {n_sets} result sets (give it 1 or {n_sets})"
    if args.num_routes is not None and args.num_routes < 1:
        return f"--num-routes must be at least 1, got {args.num_routes}"
    if args.maps_dir is not None and not args.maps_dir.is_dir():
        return f"--maps-dir {args.maps_dir} is not a directory"
    return None


def _collection_of(results_file: Path) -> tuple[Path, int] | None:
    """The b2d-collect corpus of a record file and its finished routes (the collection code loads only if asked)."""
    from b2d_data.collection.corpus import collection_of

    return collection_of(results_file)


def _eval_folders(args: argparse.Namespace) -> None:
    """Make ``b2d-eval run`` folders among RESULTS usable as they are: their records, and (unless given) their
    route file, route count and metric_info folder."""
    from b2d_data.closed_loop.evaluator import RECORDS_DIR, ROUTES_FILE, read_settings
    from b2d_data.closed_loop.route_process import METRIC_DIR

    folders = [Path(a) for a in args.results if "+" not in a and read_settings(Path(a)) is not None]
    if not folders:
        return
    original = list(args.results)
    args.results = [str(Path(a) / RECORDS_DIR) if Path(a) in folders else a for a in args.results]
    first = folders[0]
    settings = read_settings(first) or {}
    if args.routes is None and (first / ROUTES_FILE).is_file():
        args.routes = first / ROUTES_FILE
    if args.num_routes is None and isinstance(settings.get("expected_routes"), int):
        args.num_routes = settings["expected_routes"]
        reps = settings.get("repetitions", 1)
        args.num_routes_reason = (f"the routes of the b2d-eval run in {first} ({first / ROUTES_FILE}"
                                  f"{f' × {reps} repetitions' if reps != 1 else ''})")  # fmt: skip
    if args.names is None and not args.merge:
        args.names = [Path(a).name for a in original]
    if not args.metric_dir and all((f / METRIC_DIR).is_dir() for f in folders):
        args.metric_dir = [f / METRIC_DIR for f in folders]
        if args.merge or len(folders) != len(args.results):
            args.metric_dir = args.metric_dir[:1]


def default_out(result: str) -> Path:
    """Where the summary of RESULT goes without ``--out``: beside it, never into the current folder by surprise."""
    from b2d_data.closed_loop.evaluator import read_settings
    from b2d_data.data import bench2drive_dir

    first = Path(result.split("+")[0])
    if first.is_dir() and read_settings(first) is not None:
        return first / "summary.json"  # what b2d-eval run writes at its end
    resolved = shipped_or_given(first)
    if resolved.resolve().parent == bench2drive_dir().resolve():
        return Path(first.stem + SUMMARY_SUFFIX)  # not into the installed package: the folder the user is in
    if first.is_dir():
        return first.absolute().with_name(first.absolute().name + SUMMARY_SUFFIX)
    return first.with_name(first.stem + SUMMARY_SUFFIX)


def _abilities_hint(summaries: Sequence[SetSummary]) -> str:
    """What to pass for the abilities, when no route XML was given."""
    roots = [root for s in summaries if s.route_count is not None for root in s.route_count.collections]
    if not roots or any(s.route_count is None or not s.route_count.collections for s in summaries):
        return "No abilities (and no bar chart): pass --routes with the route XML the agent ran"
    from b2d_data.collection.plan import PLANNED_ROUTES_DIR

    files = sorted((roots[0] / PLANNED_ROUTES_DIR).glob("*.xml"))
    stays = "the driving score stays over the routes the collection ran"
    if len(roots) == 1 and len(files) == 1:
        return f"No abilities (and no bar chart): add --routes {files[0]} for them ({stays})"
    # --routes takes one file; a collection of several scenarios has one route file each.
    return f"No abilities (and no bar chart): --routes with one XML holding all their routes adds them ({stays})"


def summarise_eval_folder(folder: Path) -> None:
    """Print the Bench2Drive summary of a ``b2d-eval run`` folder and save it as ``<folder>/summary.json``."""
    args = _summary_parser(argparse.ArgumentParser().add_subparsers()).parse_args(
        [str(folder), "--out", str(Path(folder) / "summary.json")]
    )
    _run_summary(args)


def _run_summary(args: argparse.Namespace) -> int:
    if args.out is None:
        args.out = default_out(args.results[0])
    _eval_folders(args)
    n_sets = 1 if args.merge else len(args.results)
    # Bare names of shipped files (bench2drive220.xml, VAD_merged_results.json) work from any folder.
    args.results = [str(shipped_or_given(Path(a))) if "+" not in a else a for a in args.results]
    if args.routes is not None:
        args.routes = shipped_or_given(args.routes)

    if args.merge:
        files: list[Path] = []
        from_directory = False
        for argument in args.results:
            found, from_dir = expand_result_argument(argument)
            files += found
            from_directory |= from_dir
        name = args.names[0] if args.names else Path(args.results[0]).stem
        result_sets = [load_result_set(files, name, strict=args.strict, skip_unreadable=from_directory)]
    else:
        names = args.names or [None] * n_sets
        result_sets = [load_result_argument(a, n, strict=args.strict) for a, n in zip(args.results, names)]

    routes = read_routes(args.routes) if args.routes is not None else None
    settings = EvalSettings(
        num_routes=args.num_routes,
        num_routes_reason=getattr(args, "num_routes_reason", None),
        routes=routes,
        routes_file=args.routes,
        corrected_smoothness=args.corrected_smoothness,
        junctions=MapJunctionProvider(args.maps_dir) if args.maps_dir is not None else None,
        maps_dir=args.maps_dir,
        strict=args.strict,
        collections=_collection_of,
    )
    metric_dirs: list[Path | None] = [None] * n_sets
    if len(args.metric_dir) == 1:
        metric_dirs = [args.metric_dir[0]] * n_sets
    elif args.metric_dir:
        metric_dirs = list(args.metric_dir)
    summaries = [evaluate(rs, settings, metric_dir=md) for rs, md in zip(result_sets, metric_dirs)]

    out: Path = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary_json(summaries, settings), indent=2), encoding="utf-8")
    print(format_table(summaries))
    print()
    print(f"Wrote {out}")
    if routes is not None:
        png = out.with_name(f"{out.stem}_abilities.png")
        plot_abilities(summaries, png)
        print(f"Wrote {png}")
    else:
        print(_abilities_hint(summaries))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``b2d-eval``; returns the exit code (1 with a one-line message on bad input)."""
    parser = argparse.ArgumentParser(prog=PROG, description="Bench2Drive metrics of Leaderboard result files.")
    sub = parser.add_subparsers(dest="command", required=True)
    _summary_parser(sub)
    from b2d_data.cli import eval_run

    eval_run.add_parser(sub)
    args = parser.parse_args(argv)
    if args.command == "run":
        return eval_run.run(args)
    problem = _argument_problem(args)
    if problem:
        parser.error(problem)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.ERROR, format=f"{PROG}: %(levelname)s: %(message)s"
    )
    try:
        return _run_summary(args)
    except (B2DFormatError, OSError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1


def _summary_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    summary = sub.add_parser(
        "summary",
        help="driving score, success rate, efficiency, smoothness and abilities of one or more result sets",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    summary.add_argument("results", nargs="+", metavar="RESULTS", help="result file, directory, or a.json+b.json")
    summary.add_argument("--routes", type=Path, help="route XML the agent ran (enables the abilities)")
    summary.add_argument(
        "--metric-dir", type=Path, action="append", default=[],
        help="folder of <save_name>/metric_info.json (enables smoothness); once for all sets or once per set",
    )  # fmt: skip
    summary.add_argument("--maps-dir", type=Path, help="folder of <Town>.xodr for the Traffic_Signs junction check")
    summary.add_argument(
        "--num-routes", type=int,
        help="denominator of driving score and success rate (default: routes in --routes, else 220)",
    )  # fmt: skip
    summary.add_argument(
        "--out", type=Path,
        help="summary JSON to write (default: beside the first RESULT, <RESULT>_summary.json; <folder>/summary.json "
        "for a b2d-eval run folder)",
    )  # fmt: skip
    summary.add_argument("--names", nargs="+", help="column label of each result set")
    summary.add_argument("--strict", action="store_true", help="duplicate routes or a wrong record count are errors")
    summary.add_argument(
        "--corrected-smoothness", action="store_true",
        help="also report smoothness with rad/s, dt 0.05 s and a real yaw acceleration (labelled 'corrected')",
    )  # fmt: skip
    summary.add_argument("--merge", action="store_true", help="all RESULTS form a single result set")
    summary.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    return summary


if __name__ == "__main__":
    sys.exit(main())
