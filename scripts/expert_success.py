"""Expert success rates on the builtin simulator, physics only (no sensors, no clips).

Generated mode (default): for each scenario in SCENARIOS, ``--routes-per-scenario`` seeded routes spread over the
generated town presets and the 23 weathers; prints a Markdown table of the success rate (route completed, no
infraction other than min-speed) with the main failure reasons, and checks the ≥ 90 % bar per scenario.

    python scripts/expert_success.py [--routes-per-scenario 20] [--workers 2] [--params bench2drive220] [--out DIR]

``--params`` picks the parameter ranges of the generated routes: ``training`` (LB2.0's routes_training.xml, the
default) or ``bench2drive220`` (the evaluation routes' narrower ranges). ``--direction left`` draws only that side of
the types that draw a ``direction`` (the kerb-side types' left needs ``--towns downtown``, Town104's one-way streets).

Route-file mode: the routes of a Leaderboard route file whose scenario type is one of those and whose town has an
OpenDRIVE file in ``--xodr-dir``; prints one row per route.

    python scripts/expert_success.py --routes bench2drive220.xml [--limit 3]   # shipped routes on the shipped towns

Every attempt is logged in ``OUT/run_log.jsonl`` and recorded in ``OUT/results/`` (``b2d-eval summary OUT/results``).
Exit status: 0 when every scenario (generated mode) or every route (file mode) passes, else 1.
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from b2d_data import data
from b2d_data.collection.job import CollectConfig, JobResult
from b2d_data.collection.plan import RouteTask, route_seed
from b2d_data.collection.runner import run_tasks
from b2d_data.collection.towns import TownSource, load_map, xodr_in_folder

#: The twelve scenario types of issue 4, then those of issues 12, 13, 11, 14 and 23 (46 types and NoScenario).
SCENARIOS: tuple[str, ...] = (
    "Accident", "ParkedObstacleTwoWays", "HazardAtSideLane", "HardBreakRoute", "DynamicObjectCrossing",
    "OppositeVehicleRunningRedLight", "SignalizedJunctionLeftTurn", "NonSignalizedJunctionRightTurn",
    "YieldToEmergencyVehicle", "VanillaSignalizedTurnEncounterRedLight", "VanillaNonSignalizedTurnEncounterStopsign",
    "ParkingExit",
    # issue 12
    "NonSignalizedJunctionLeftTurn", "SignalizedJunctionRightTurn", "SignalizedJunctionLeftTurnEnterFlow",
    "NonSignalizedJunctionLeftTurnEnterFlow", "EnterActorFlow", "CrossingBicycleFlow",
    # issue 13: highway and interurban
    "InterurbanActorFlow", "HighwayCutIn", "InterurbanAdvancedActorFlow", "MergerIntoSlowTraffic",
    "MergerIntoSlowTrafficV2", "HighwayExit",
    # issue 11: overtaking and give-way
    "ParkedObstacle", "AccidentTwoWays", "ConstructionObstacle", "ConstructionObstacleTwoWays",
    "HazardAtSideLaneTwoWays", "VehicleOpensDoorTwoWays", "InvadingTurn",
    # issue 14: emergency brakes, cut-ins, pedestrians, the remaining sign scenarios, plain routes
    "NoScenario", "VanillaNonSignalizedTurn", "VanillaSignalizedTurnEncounterGreenLight", "T_Junction",
    "OppositeVehicleTakingPriority", "ParkingCrossingPedestrian", "ControlLoss", "BlockedIntersection",
    "PedestrianCrossing", "VehicleTurningRoutePedestrian", "VehicleTurningRoute", "ParkingCutIn", "StaticCutIn",
    # issue 13: successive lane changes
    "SequentialLaneChange",
    # issue 23: the LB2.0 training types Bench2Drive drops
    "EnterActorFlowV2", "PriorityAtJunction",
)  # fmt: skip
BAR = 0.9


def generated_tasks(
    scenarios: list[str],
    per_scenario: int,
    presets: list[str],
    seed: int,
    out: Path,
    params: str = "training",
    direction: str | None = None,
) -> tuple[list[RouteTask], dict[str, str]]:
    """``per_scenario`` routes per scenario, split over the presets that hold its layout (``direction``: only that
    drawn side); also placement errors."""
    from b2d_data.scenarios import placement

    towns = {p: TownSource(preset=p).materialise(out) for p in presets}
    maps = {p: load_map(t) for p, t in towns.items()}
    tasks: list[RouteTask] = []
    errors: dict[str, str] = {}
    for scenario in scenarios:
        routes = []
        usable = list(presets)
        remaining = per_scenario
        placed: list[str] = []
        while remaining > 0 and usable:
            share = -(-remaining // len(usable))  # ceil: the first presets take the remainder
            p = usable.pop(0)
            try:
                made = placement.make_routes(maps[p], scenario, share, seed, params=params, direction=direction)
                routes += [(p, r) for r in made]
                remaining -= share
                placed.append(p)
            except placement.PlacementError as exc:
                logging.getLogger(__name__).info("%s on %s: %s", scenario, p, exc)
                errors[scenario] = str(exc)
        if remaining > 0 and placed:
            # presets without the layout leave their share to the first one that has it (its first routes are
            # the same for any count, so the others' seeded routes do not move)
            p = placed[0]
            have = sum(1 for q, _ in routes if q == p)
            try:
                more = placement.make_routes(
                    maps[p], scenario, have + remaining, seed, params=params, direction=direction
                )[have:]
                routes += [(p, r) for r in more]
                remaining -= len(more)
                errors.pop(scenario, None)
            except placement.PlacementError as exc:
                errors[scenario] = str(exc)
        if remaining > 0:
            errors[scenario] = f"only {per_scenario - remaining} of {per_scenario} routes could be placed"
        tasks += [RouteTask(r, towns[p], scenario, route_seed(seed, f"{p}:{r.id}")) for p, r in routes]
    return tasks, errors


def file_tasks(
    routes_file: Path, xodr_dir: Path, scenarios: list[str], seed: int, limit: int | None
) -> list[RouteTask]:
    """The file's routes of those scenario types on towns that ``xodr_dir`` holds, in file order."""
    from b2d_data.scenarios.route_xml import read_routes

    tasks = []
    for r in read_routes(routes_file):
        if r.scenario_type not in scenarios:
            continue
        town = xodr_in_folder(xodr_dir, r.town)
        if town is not None:
            tasks.append(RouteTask(r, town, r.scenario_type, route_seed(seed, r.id)))
    return tasks[:limit] if limit else tasks


def _reason(result: JobResult) -> str:
    return result.reason or result.route_status or result.status


def scenario_table(
    tasks: list[RouteTask], results: list[JobResult], errors: dict[str, str], scenarios: list[str]
) -> tuple[str, bool]:
    """Markdown table per scenario and whether every scenario reaches the bar."""
    lines = [
        "| scenario | routes | successes | rate | ≥ 90 % | main failure reasons |",
        "|---|---:|---:|---:|:---:|---|",
    ]
    passed = True
    total = wins = 0
    for scenario in scenarios:
        mine = [res for t, res in zip(tasks, results) if t.scenario == scenario]
        ok = sum(r.success for r in mine)
        total += len(mine)
        wins += ok
        rate = ok / len(mine) if mine else 0.0
        good = bool(mine) and rate >= BAR
        passed &= good
        reasons = Counter(_reason(r) for r in mine if not r.success)
        text = "; ".join(f"{k} ×{v}" for k, v in reasons.most_common(3)) or errors.get(scenario, "—")
        lines.append(f"| {scenario} | {len(mine)} | {ok} | {100 * rate:.0f} % | {'yes' if good else 'NO'} | {text} |")
    overall = wins / total if total else 0.0
    lines.append(f"| **all** | {total} | {wins} | {100 * overall:.0f} % | {'yes' if passed else 'NO'} | |")
    return "\n".join(lines), passed


def route_table(tasks: list[RouteTask], results: list[JobResult]) -> tuple[str, bool]:
    """Markdown table per route and whether every route succeeded."""
    lines = [
        "| route | town | scenario | weather | status | success | infractions | completion | time |",
        "|---|---|---|---:|---|:---:|---|---:|---:|",
    ]
    for t, r in zip(tasks, results):
        kinds = ", ".join(f"{k} ×{v}" for k, v in r.infractions.items() if k != "min_speed_infractions") or "—"
        status = r.route_status or f"{r.status}: {r.reason}"
        lines.append(
            f"| {t.route.id} | {t.route.town} | {t.scenario} | {r.weather_id} | {status} | "
            f"{'yes' if r.success else 'no'} | {kinds} | {r.score_route:.1f} % | {r.duration:.0f} s |"
        )
    wins = sum(r.success for r in results)
    lines.append(f"\n{wins} of {len(results)} routes succeeded.")
    return "\n".join(lines), wins == len(results)


def main(argv: list[str] | None = None) -> int:
    """Run the table; returns the exit status."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", action="append", default=[], help="restrict to these scenarios (repeatable)")
    p.add_argument("--routes-per-scenario", type=int, default=20)
    p.add_argument("--towns", default="all,urban", help="comma-separated generated presets (generated mode)")
    p.add_argument("--routes", type=Path, help="route file (route-file mode)")
    p.add_argument("--xodr-dir", type=Path, default=data.carla_maps_dir(), help="folder of <Town>.xodr (file mode)")
    p.add_argument("--limit", type=int, default=None, help="run at most this many routes of the file")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--params",
        choices=("training", "bench2drive220"),
        default="training",
        help="parameter ranges of generated routes (default training: LB2.0 routes_training.xml)",
    )
    p.add_argument(
        "--direction",
        choices=("right", "left"),
        default=None,
        help="generated routes draw only this side of 'direction' (types that draw it; e.g. left on --towns downtown)",
    )
    p.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="[TOWN:]ROUTE_ID",
        help="rerun only these routes of the table (repeatable), e.g. Town100:29160010",
    )
    p.add_argument("--workers", type=int, default=1, help="routes in parallel processes")
    p.add_argument("--out", type=Path, default=None, help="where records and the run log go (default: a temp dir)")
    p.add_argument("-v", "--verbose", action="store_true")
    args = p.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s"
    )
    scenarios = args.scenario or list(SCENARIOS)
    out = args.out or Path(tempfile.mkdtemp(prefix="expert_success_"))
    t0 = time.monotonic()
    errors: dict[str, str] = {}
    if args.routes is not None:
        args.routes = data.shipped_or_given(args.routes)
        tasks = file_tasks(args.routes, args.xodr_dir, scenarios, args.seed, args.limit)
        if not tasks:
            print(
                f"no route of {', '.join(scenarios)} in {args.routes} lies on a town of {args.xodr_dir}",
                file=sys.stderr,
            )
            return 2
    else:
        presets = args.towns.split(",")
        tasks, errors = generated_tasks(
            scenarios, args.routes_per_scenario, presets, args.seed, out, args.params, direction=args.direction
        )
    if args.only:
        wanted = set(args.only)
        tasks = [t for t in tasks if t.route.id in wanted or f"{t.route.town}:{t.route.id}" in wanted]
        if not tasks:
            print(f"no route matches --only {' '.join(args.only)}", file=sys.stderr)
            return 2
    config = CollectConfig(out=out, sensors=False, workers=args.workers)
    done = 0

    def report(task: RouteTask, result: JobResult) -> None:
        nonlocal done
        done += 1
        verdict = "ok" if result.success else f"FAILED ({_reason(result)})"
        print(
            f"[{done}/{len(tasks)}] {task.scenario} route {task.route.id} on {task.route.town}: {verdict} "
            f"in {result.duration:.0f} s",
            file=sys.stderr,
            flush=True,
        )

    results = run_tasks(tasks, out, config, report)
    if args.routes is not None:
        table, passed = route_table(tasks, results)
    else:
        table, passed = scenario_table(tasks, results, errors, scenarios)
    print(table)
    print(f"\n{len(results)} routes in {time.monotonic() - t0:.0f} s; records in {out / 'results'}")
    if args.routes is None:
        print(f"≥ 90 % on every scenario: {'PASS' if passed else 'FAIL'}")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
