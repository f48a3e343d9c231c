"""``b2d-eval run``: score a Leaderboard 2.0 agent closed loop on the builtin simulator.

Examples::

    b2d-eval run --agent expert --routes bench2drive220.xml --out eval/expert          # the privileged expert
    b2d-eval run --agent examples/sensor_agent.py --routes bench2drive220.xml --out eval/sensor_agent
    IS_BENCH2DRIVE=True SAVE_PATH=eval/vad/save b2d-eval run --agent Bench2DriveZoo/team_code/vad_b2d_agent.py \\
        --agent-config Bench2DriveZoo/adzoo/vad/configs/VAD/VAD_base_e2e_b2d.py+ckpts/vad_b2d_base.pth \\
        --routes bench2drive220.xml --out eval/vad
    b2d-eval run ... --out eval/vad --resume          # after Ctrl-C, a crash or kill -9
    b2d-eval summary eval/vad                         # DS, SR, abilities, efficiency, comfort

The agent file is loaded as the Leaderboard loads it (its folder first on sys.path, ``get_entry_point()`` names the
class); inside each route process ``import carla``, ``leaderboard``, ``srunner`` and ``agents`` find b2d-data's
stand-ins backed by the builtin simulator. The agent's configuration string reaches ``setup()`` with ``+<save_name>``
appended, as Bench2Drive's evaluator does. Routes on towns without a map are listed as skipped.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from b2d_data.cli.signals import restore_sigterm, stop_on_sigterm
from b2d_data.cli.ticking_bar import TickingBar

if TYPE_CHECKING:  # the evaluator loads only when an evaluation runs (a fast --help)
    from b2d_data.closed_loop.evaluator import EvalProgress, EvalResult

PROG = "b2d-eval run"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``run`` subcommand."""
    p = sub.add_parser(
        "run", help="evaluate a Leaderboard 2.0 agent closed loop on the routes of a route file",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument("--agent", type=Path, required=True, metavar="AGENT.py",
                   help="the agent's Python file, or 'expert' for b2d-data's privileged expert")
    p.add_argument("--agent-config", default="", metavar="CONF",
                   help="string handed to the agent's setup() (a config path, 'cfg.py+ckpt.pth', ...)")  # fmt: skip
    p.add_argument("--routes", type=Path, required=True, metavar="FILE.xml",
                   help="Leaderboard route file (a bare shipped name such as bench2drive220.xml works)")  # fmt: skip
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="folder of the results (created)")
    p.add_argument("--xodr", type=Path, metavar="FILE|DIR",
                   help="OpenDRIVE town file, or a folder of <Town>.xodr, for towns the package does not ship")
    p.add_argument("--workers", default="auto", metavar="N|auto",
                   help="routes run at once, each in its own process (default auto: from the cores and GPUs)")
    p.add_argument("--resume", action="store_true", help="continue the evaluation in --out (after a stop or crash)")
    p.add_argument("--repetitions", type=int, default=1, metavar="K", help="runs of each route (default 1)")
    p.add_argument("--seed", type=int, default=0, help="seed of the routes' simulations (default 0)")
    p.add_argument("--route-id", action="append", default=[], metavar="ID", help="run only this route (repeatable)")
    p.add_argument("--track", default="SENSORS", choices=("SENSORS", "MAP", "SENSORS_QUALIFIER", "MAP_QUALIFIER"),
                   help="Leaderboard track the agent must declare (default SENSORS)")
    p.add_argument("--step-timeout", type=float, default=600.0, metavar="S",
                   help="seconds an agent step may take before the route fails as 'Agent crashed' (default 600)")
    p.add_argument("--setup-timeout", type=float, default=600.0, metavar="S",
                   help="seconds the agent's set-up may take (default 600)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("-v", "--verbose", action="count", default=0, help="log more (-v info, -vv debug)")
    return p


def _workers(value: str) -> int:
    if value == "auto":
        from b2d_data.collection.layout import auto_layout

        return auto_layout().workers
    try:
        return int(value)
    except ValueError:
        raise SystemExit(f"{PROG}: error: --workers expects a number or auto, got {value!r}") from None


class _ProgressBar(TickingBar):
    """Routes done over all, failures, the running routes' ticks, elapsed time and the ETA."""

    BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} routes, {elapsed} elapsed{postfix}"

    def __init__(self, enabled: bool) -> None:
        super().__init__("b2d-eval", enabled)
        self._last: EvalProgress | None = None

    def __call__(self, p: EvalProgress) -> None:
        with self._lock:
            self._last = p
            self.reported(p.total)

    def count(self) -> int:
        """Routes with their record."""
        return self._last.done if self._last is not None else 0

    def text(self) -> str:
        """Failures, the first running routes' ticks and completion, the ETA counted down since the last report."""
        from b2d_data.collection.progress import format_seconds

        p = self._last
        if p is None:
            return ""
        eta = None if p.eta is None else max(p.eta - self.since_report(), 0.0)
        running = "; ".join(f"{r.route_id} {r.frames} ticks {r.completion:.0f}%" for r in p.running[:3])
        more = f" +{len(p.running) - 3} more" if len(p.running) > 3 else ""
        return f"{p.failed} failed | {running}{more} | ETA {format_seconds(eta)}"


def run(args: argparse.Namespace) -> int:
    """Run the evaluation; 0 when every route has its record, 1 on a usage problem, 130 when interrupted."""
    from b2d_data.closed_loop import resolve_agent
    from b2d_data.closed_loop.evaluator import EvalConfig, EvalError, EvalInterrupted, run_evaluation

    level = logging.WARNING if args.verbose == 0 else logging.INFO if args.verbose == 1 else logging.DEBUG
    logging.getLogger().setLevel(level)
    workers = _workers(args.workers)
    config = EvalConfig(
        agent=resolve_agent(args.agent), routes_file=args.routes, out=args.out, agent_config=args.agent_config, xodr=args.xodr,
        workers=workers, resume=args.resume, repetitions=args.repetitions, seed=args.seed,
        route_ids=tuple(args.route_id), track=args.track, step_timeout=args.step_timeout,
        setup_timeout=args.setup_timeout,
    )  # fmt: skip
    bar = _ProgressBar(enabled=not args.no_progress)
    previous_term = stop_on_sigterm()
    try:
        result = run_evaluation(config, bar)
    except EvalError as exc:
        bar.close()
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except EvalInterrupted as exc:
        bar.close()
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 130
    finally:
        restore_sigterm(previous_term)
    bar.close()
    _report(result)
    return 0


def _report(result: EvalResult) -> None:
    """Per-route lines, the skipped routes, then the Bench2Drive summary of the folder."""
    from b2d_data.cli.eval import summarise_eval_folder

    for skipped in result.plan.skipped:
        print(f"skipped route {skipped.route_id} ({skipped.town}): {skipped.reason}")
    failed = [r for r in result.records if r.status.startswith("Failed")]
    for record in failed:
        detail = record.extra.get("b2d_eval", {}).get("detail", "")
        print(f"{record.route_id}: {record.status}{' - ' + detail if detail else ''}")
    print(f"{len(result.records)} of {result.total} routes have their record ({result.resumed} from before), "
          f"{result.wall_seconds:.1f} s; results in {result.out}")  # fmt: skip
    summarise_eval_folder(result.out)
