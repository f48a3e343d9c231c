"""Closed-loop evaluation speed: simulator ticks per second of a route process, and the wall time of a route file.

Part 1 (default): one route process's loop in this process, on a bench2drive220 route of the shipped Town01, with a
zero-cost agent (the expert, whose own step costs ~1 ms) that mounts nothing, then the UniAD/VAD sensor rig (six
cameras of --width × --height, the 512×512 ``bev`` camera, IMU, GNSS, speedometer), each for --ticks ticks. Prints
ticks per second, the split of a tick (sensors / agent / rest), and the ratios to the physics-only loop and to real
time (20 ticks/s)::

    python scripts/bench_eval.py --ticks 200 --width 1600 --height 900

Part 2 (``--routes FILE``): ``b2d-eval run`` of every route of the file on the shipped towns with that agent and the
full UniAD/VAD rig, ``--workers auto``; prints the wall time, the routes' ticks and the driving score::

    python scripts/bench_eval.py --routes bench2drive220.xml --out /tmp/bench_eval

Benchmarks live here, not in the test suite; absolute times on shared machines are noisy, ratios are not.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from b2d_data import data
from b2d_data.closed_loop import REFERENCE_AGENTS, SHIM_DIR
from b2d_data.closed_loop.leaderboard_agent import AgentSettings, LeaderboardAgent
from b2d_data.collection.towns import load_map, shipped_town
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_runner import RouteRunner
from b2d_data.scenarios.route_xml import read_routes

#: A bench2drive220 route on Town01 (ControlLoss, 130 m, background traffic).
ROUTE_ID = "24841"
REAL_TIME = 20.0


def loop_rate(route_id: str, ticks: int, agent_config: str) -> dict[str, float]:
    """Run ``ticks`` ticks of the route with the expert agent and ``agent_config``; ticks/s and where time went."""
    from b2d_data.sim.builtin.world import BuiltinSimulator

    route = next(r for r in read_routes(data.bench2drive_file("bench2drive220.xml")) if r.id == route_id)
    source = shipped_town(route.town)
    assert source is not None
    world_map = load_map(source)
    sim = BuiltinSimulator(world_map, seed=0, weather=route.weather_at(0.0))
    dense = DenseRoute.from_route(world_map, route)
    agent = LeaderboardAgent(AgentSettings(path=REFERENCE_AGENTS["expert"], config=agent_config), sim,
                             "bench", route=dense)  # fmt: skip
    clock: dict[str, float] = {}

    def on_tick(snapshot, info) -> None:
        if info.tick == 1:
            clock["start"] = time.perf_counter()
            clock["sensors0"], clock["agent0"] = agent.timings.sensors, agent.timings.steps

    runner = RouteRunner(sim, route, agent, seed=0, record_every=1, on_frame=on_tick, on_start=agent.start,
                         dense_route=dense, max_ticks=ticks + 1)  # fmt: skip
    runner.run()
    agent.close()
    sim.close()
    ran = agent.timings.step_count - 1  # the first tick's time is the clock's start
    wall = time.perf_counter() - clock["start"]
    sensors = agent.timings.sensors - clock["sensors0"]
    steps = agent.timings.steps - clock["agent0"]
    return {"ticks": ran, "wall": wall, "rate": ran / wall, "sensors_ms": 1e3 * sensors / ran,
            "agent_ms": 1e3 * steps / ran, "rest_ms": 1e3 * (wall - sensors - steps) / ran}  # fmt: skip


def part1(args: argparse.Namespace) -> None:
    sys.path.insert(0, str(SHIM_DIR))
    os.environ.setdefault("SAVE_PATH", tempfile.mkdtemp(prefix="bench_eval_save_"))  # lets the bev camera pass
    physics = loop_rate(ROUTE_ID, args.ticks, "")
    rig = loop_rate(ROUTE_ID, args.ticks, f"rig=uniad,width={args.width},height={args.height}")
    for name, r in (("physics only (no sensors)", physics), (f"UniAD/VAD rig {args.width}x{args.height} + bev", rig)):
        print(f"{name}: {r['rate']:.1f} ticks/s over {r['ticks']} ticks (sensors {r['sensors_ms']:.1f} ms, agent "
              f"{r['agent_ms']:.1f} ms, simulator + criteria {r['rest_ms']:.1f} ms per tick)")  # fmt: skip
    print(f"ratio UniAD rig / physics only: {rig['rate'] / physics['rate']:.3f}; UniAD rig / real time (20 ticks/s): "
          f"{rig['rate'] / REAL_TIME:.2f}")  # fmt: skip


def part2(args: argparse.Namespace) -> None:
    from b2d_data.cli import eval as eval_cli

    out = Path(args.out)
    save = out.with_name(out.name + "_save")
    save.mkdir(parents=True, exist_ok=True)
    os.environ["SAVE_PATH"] = str(save)
    command = ["run", "--agent", "expert", "--agent-config", f"rig=uniad,width={args.width},height={args.height}",
               "--routes", args.routes, "--out", str(out), "--workers", args.workers, "--no-progress"]  # fmt: skip
    started = time.perf_counter()
    code = eval_cli.main(command)
    wall = time.perf_counter() - started
    attempts = [json.loads(line) for line in (out / "run_log.jsonl").read_text().splitlines()]
    attempts = [a for a in attempts if a.get("event") == "attempt"]
    ticks = sum(a.get("ticks", 0) for a in attempts)
    rates = [a["ticks"] / a["wall"] for a in attempts if a.get("ticks") and a.get("wall")]
    print(f"\n{len(attempts)} routes, {ticks} ticks in {wall:.1f} s wall ({ticks / wall:.1f} ticks/s over all route "
          f"processes; per route process median {statistics.median(rates):.1f} ticks/s); exit status {code}")


def main(argv: list[str] | None = None) -> int:
    """Run part 1, or part 2 with --routes."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ticks", type=int, default=200, help="ticks per measured loop (part 1)")
    parser.add_argument("--width", type=int, default=1600, help="width of the six cameras")
    parser.add_argument("--height", type=int, default=900, help="height of the six cameras")
    parser.add_argument("--routes", help="route file to evaluate (part 2)")
    parser.add_argument("--out", default="/tmp/bench_eval", help="output folder of part 2 (must not exist)")
    parser.add_argument("--workers", default="auto", help="route processes of part 2")
    args = parser.parse_args(argv)
    if args.routes:
        part2(args)
    else:
        part1(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
