"""The baselines chain: collect a corpus → train AD-MLP and TCP-style → evaluate on held-out routes → table.

Every stage skips the work already done, so the chain runs in pieces under a per-command time limit
(``--budget S``: collection and evaluation are interrupted cleanly at the deadline and resumed by the next call;
training stops between epochs and resumes from its last checkpoint)::

    PYTHONPATH=. python scripts/run_baselines.py --work runs/baselines --stage all --budget 520   # repeat until done
    PYTHONPATH=. python scripts/run_baselines.py --work runs/baselines --stage table              # the README table

Stages: ``collect`` (``b2d-collect`` into WORK/corpus: scenario mode on a generated town by default, or
``--preset base --n-scale S``), ``heldout`` (WORK/heldout.xml: bench2drive220 routes on the shipped CARLA towns
plus generated routes on another generated town with another seed — none of them seen in training), ``train-admlp``,
``train-tcp``, ``eval`` (``b2d-eval run`` of each agent on WORK/heldout.xml into WORK/eval/<agent>) and ``table``
(``b2d-eval summary`` of all agents → WORK/table.md and WORK/summary.json).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

log = logging.getLogger("run_baselines")

#: Scenario mix of the default training corpus (scenario mode): plain driving, stops for lights and hazards,
#: turns at junctions, one overtaking type.
DEFAULT_SCENARIOS = (
    "NoScenario", "HardBreakRoute", "DynamicObjectCrossing", "VanillaSignalizedTurnEncounterRedLight",
    "SignalizedJunctionLeftTurn", "ParkedObstacle",
)  # fmt: skip
#: CARLA towns b2d-data ships (the bench2drive220 routes on them form the held-out set).
SHIPPED_TOWNS = ("Town01", "Town04", "Town06", "Town07", "Town10HD")
AGENT_FILES = {
    "route_follower": REPO / "baselines" / "agents" / "route_follower_agent.py",
    "admlp": REPO / "baselines" / "agents" / "admlp_agent.py",
    "tcp": REPO / "baselines" / "agents" / "tcp_agent.py",
}
LABELS = {"route_follower": "constant-speed route follower", "admlp": "AD-MLP", "tcp": "TCP-style", "expert": "expert"}
STAGES = ("collect", "heldout", "train-admlp", "train-tcp", "eval", "table")


@dataclass
class Deadline:
    """The end of this invocation's time budget (None: no limit)."""

    end: float | None

    def left(self) -> float | None:
        """Seconds left, or None without a budget."""
        return None if self.end is None else self.end - time.monotonic()

    def over(self, margin: float = 0.0) -> bool:
        """Whether fewer than ``margin`` seconds are left."""
        left = self.left()
        return left is not None and left < margin


def run_until(cmd: list[str], deadline: Deadline, log_path: Path, env: dict[str, str] | None = None) -> int | None:
    """Run ``cmd`` (output to ``log_path``); at the deadline send it SIGINT (as Ctrl-C) and wait. None = interrupted."""
    log_path.parent.mkdir(parents=True, exist_ok=True)
    log.info("$ %s", " ".join(cmd))
    with open(log_path, "a", encoding="utf-8") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        while True:
            try:
                return proc.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                if not deadline.over(15.0):
                    continue
            log.warning("time budget reached: interrupting (the next call resumes)")
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=60.0)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            return None


def python_env() -> dict[str, str]:
    """This repository first on PYTHONPATH, so that subprocesses import this checkout's b2d_data and baselines."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


# ------------------------------------------------------------------------------------------------ stages


def retire_if_older(folder: Path, product: Path, source: Path) -> None:
    """Move ``folder`` aside when its ``product`` predates ``source`` (a grown corpus, a retrained model)."""
    if product.is_file() and source.is_file() and source.stat().st_mtime > product.stat().st_mtime:
        aside = folder.with_name(f"{folder.name}.before-{time.strftime('%Y%m%d-%H%M%S')}")
        log.warning("%s predates %s: moving %s to %s and starting over", product, source, folder, aside)
        folder.rename(aside)


def stage_collect(args: argparse.Namespace, deadline: Deadline) -> bool:
    """``b2d-collect`` into WORK/corpus (resumed when a session was there before); True when complete."""
    corpus = args.work / "corpus"
    done = corpus / ".collect_done"
    what = ["--seed", str(args.seed), "--width", str(args.width), "--height", str(args.height)]
    if args.preset:
        what += ["--preset", args.preset, "--n-scale", str(args.n_scale)]
    else:
        for s in args.scenarios:
            what += ["--scenario", s]
        what += ["--n", str(args.n), "--town", args.town]
    # The marker holds what was collected: a larger --n (or another mix) continues the corpus with --resume.
    if done.is_file() and done.read_text().strip() == " ".join(what):
        log.info("collect: done already (%s)", corpus)
        return True
    cmd = [sys.executable, "-m", "b2d_data.cli.collect", "--out", str(corpus), *what,
           "--workers", str(args.collect_workers), "--no-progress"]  # fmt: skip
    if (corpus / "collect.json").is_file():
        cmd.append("--resume")
    rc = run_until(cmd, deadline, args.work / "logs" / "collect.log", python_env())
    if rc == 0 and args.val_split and not args.preset and not (corpus / "splits").is_dir():
        # A validation part for the loss curves: b2d-split's base rule (5 %, at least one clip per scenario).
        split = [sys.executable, "-m", "b2d_data.cli.split", "generate", str(corpus), "--split", "base",
                 "--out", str(corpus / "splits" / "base.json")]  # fmt: skip
        rc = run_until(split, deadline, args.work / "logs" / "collect.log", python_env())
    if rc == 0:
        done.write_text(" ".join(what) + "\n")
        return True
    log.warning("collect: %s", "interrupted" if rc is None else f"exit code {rc} (see logs/collect.log)")
    return False


def heldout_routes(args: argparse.Namespace) -> list:
    """The held-out routes: bench2drive220's on the shipped towns (first ``--b2d220-routes``) + generated ones."""
    from b2d_data.collection.towns import TownSource, load_map
    from b2d_data.scenarios import placement
    from b2d_data.scenarios.route_xml import read_route_argument

    routes = [r for r in read_route_argument("bench2drive220.xml") if r.town in SHIPPED_TOWNS]
    routes.sort(key=lambda r: int(r.id))
    if args.b2d220_routes is not None:
        # Spread the subset over scenario types: one route per type in turn, by route id within a type.
        by_type: dict[str, list] = {}
        for r in routes:
            by_type.setdefault(r.scenario_type or "", []).append(r)
        picked: list = []
        while len(picked) < min(args.b2d220_routes, len(routes)):
            for group in by_type.values():
                if group and len(picked) < args.b2d220_routes:
                    picked.append(group.pop(0))
        routes = sorted(picked, key=lambda r: int(r.id))
    if args.heldout_n > 0:
        town = load_map(TownSource(preset=args.heldout_town).materialise(args.work))
        for scenario in args.heldout_scenarios:
            try:
                routes += placement.make_routes(town, scenario, args.heldout_n, args.heldout_seed,
                                                params="bench2drive220")  # fmt: skip
            except placement.PlacementError as exc:
                log.warning("held-out %s on %s: %s", scenario, args.heldout_town, exc)
    return routes


def stage_heldout(args: argparse.Namespace) -> Path:
    """Write WORK/heldout.xml once (its routes never change afterwards, so evaluations can resume)."""
    from b2d_data.scenarios.route_xml import write_routes

    path = args.work / "heldout.xml"
    if path.is_file():
        return path
    routes = heldout_routes(args)
    args.work.mkdir(parents=True, exist_ok=True)
    write_routes(routes, path)
    towns = sorted({r.town for r in routes})
    log.info("held-out routes: %d on %s -> %s", len(routes), ", ".join(towns), path)
    return path


def stage_train(args: argparse.Namespace, model: str, deadline: Deadline) -> bool:
    """Train one model (resuming); True when it has all its epochs."""
    out = args.work / "train" / model
    epochs = args.epochs_admlp if model == "admlp" else args.epochs_tcp
    last = out / "last.pt"
    retire_if_older(out, last, args.work / "corpus" / ".collect_done")
    if last.is_file():
        import torch

        if int(torch.load(last, map_location="cpu", weights_only=False)["epoch"]) >= epochs:
            log.info("train-%s: done already (%d epochs)", model, epochs)
            return True
    left = deadline.left()
    if left is not None and left < 30:
        return False
    args.curves.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "baselines.train", "--model", model, "--data", str(args.work / "corpus"),
           "--out", str(out), "--epochs", str(epochs), "--device", args.device, "--workers", str(args.train_workers),
           "--curve", str(args.curves / f"{model}_loss.png"), "--resume"]  # fmt: skip
    if model == "tcp":
        cmd += ["--image-size", args.image_size]
    if args.threads:
        cmd += ["--threads", str(args.threads)]
    if left is not None:
        cmd += ["--time-budget", str(max(10.0, left - 20.0))]
    rc = run_until(cmd, deadline, args.work / "logs" / f"train_{model}.log", python_env())
    if rc != 0:
        log.warning("train-%s: %s", model, "interrupted" if rc is None else f"exit code {rc}")
        return False
    import torch

    return int(torch.load(last, map_location="cpu", weights_only=False)["epoch"]) >= epochs


def checkpoint_of(work: Path, agent: str) -> Path:
    """The checkpoint an agent drives: ``best.pt`` (lowest val loss) where training wrote one, else ``last.pt``."""
    folder = work / "train" / agent
    best = folder / "best.pt"
    return best if best.is_file() else folder / "last.pt"


def agent_args(args: argparse.Namespace, agent: str) -> list[str]:
    """``--agent`` / ``--agent-config`` of one evaluated agent."""
    if agent == "expert":
        return ["--agent", "expert"]
    if agent == "route_follower":
        return ["--agent", str(AGENT_FILES[agent]), "--agent-config", f"speed={args.follower_speed}"]
    config = f"ckpt={checkpoint_of(args.work, agent).resolve()}"
    if agent == "tcp":
        config += f",planner={args.tcp_planner}"
    return ["--agent", str(AGENT_FILES[agent]), "--agent-config", config]


def eval_done(out: Path) -> bool:
    """Whether ``b2d-eval run`` finished every route of its folder (results.json says so)."""
    results = out / "results.json"
    if not results.is_file():
        return False
    try:
        progress = json.loads(results.read_text()).get("_checkpoint", {}).get("progress", [])
    except (OSError, ValueError):
        return False
    return len(progress) == 2 and progress[0] >= progress[1] > 0


def stage_eval(args: argparse.Namespace, routes: Path, deadline: Deadline) -> bool:
    """``b2d-eval run`` of every agent on the held-out routes (resumed); True when all are complete."""
    complete = True
    for agent in args.agents:
        out = args.work / "eval" / agent
        retire_if_older(out, out / "eval.json", checkpoint_of(args.work, agent))
        if eval_done(out):
            log.info("eval %s: done already", agent)
            continue
        if agent in ("admlp", "tcp") and not (args.work / "train" / agent / "last.pt").is_file():
            log.warning("eval %s: no checkpoint yet (train-%s first)", agent, agent)
            complete = False
            continue
        if deadline.over(60.0):
            return False
        cmd = [sys.executable, "-m", "b2d_data.cli.eval", "run", *agent_args(args, agent), "--routes", str(routes),
               "--out", str(out), "--seed", str(args.eval_seed), "--workers", str(args.eval_workers),
               "--no-progress"]  # fmt: skip
        if out.exists():
            cmd.append("--resume")
        rc = run_until(cmd, deadline, args.work / "logs" / f"eval_{agent}.log", python_env())
        if rc is None:
            return False
        if rc != 0 or not eval_done(out):
            log.warning("eval %s: exit code %s (see logs/eval_%s.log)", agent, rc, agent)
            complete = False
    return complete


# ------------------------------------------------------------------------------------------------- table

_ABILITIES = ("Overtaking", "Merging", "Emergency_Brake", "Give_Way", "Traffic_Signs")


def _fmt(value: object) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, (int, float)):
        return f"{value:.2f}"
    return str(value)


def stage_table(args: argparse.Namespace, routes: Path) -> str | None:
    """``b2d-eval summary`` over the agents' folders → WORK/summary.json and a markdown table (WORK/table.md)."""
    folders = [(a, args.work / "eval" / a) for a in args.agents if (args.work / "eval" / a / "records").is_dir()]
    if not folders:
        log.warning("table: no evaluation yet")
        return None
    summary = args.work / "summary.json"
    # One folder with every held-out town's OpenDRIVE file, for the summary's Traffic_Signs junction check.
    maps = args.work / "summary_maps"
    maps.mkdir(exist_ok=True)
    shipped = REPO / "b2d_data" / "data" / "carla_maps"
    for xodr in [*shipped.glob("*.xodr"), *(args.work / "towns").glob("*.xodr")]:
        link = maps / xodr.name
        if not link.exists():
            link.symlink_to(xodr.resolve())
    cmd = [sys.executable, "-m", "b2d_data.cli.eval", "summary", *[str(f) for _, f in folders],
           "--routes", str(routes), "--names", *[a for a, _ in folders], "--out", str(summary),
           "--maps-dir", str(maps)]  # fmt: skip
    proc = subprocess.run(cmd, env=python_env(), capture_output=True, text=True)
    if proc.returncode != 0:
        log.error("b2d-eval summary failed: %s", proc.stderr[-2000:])
        return None
    data = json.loads(summary.read_text())
    rows = ["| agent | routes | DS | SR (%) | completion (%) | efficiency | comfort | " + " | ".join(_ABILITIES) + " |",
            "|---|---:|---:|---:|---:|---:|---:|" + "---:|" * len(_ABILITIES)]  # fmt: skip
    for entry in data.get("result_sets", []):
        abilities = entry.get("abilities") or {}
        cells = [LABELS.get(entry["name"], entry["name"]), f"{entry.get('records')}/{entry.get('expected_routes')}",
                 _fmt(entry.get("driving_score")), _fmt(entry.get("success_rate")),
                 _fmt(entry.get("route_completion")), _fmt((entry.get("efficiency") or {}).get("value")),
                 _fmt((entry.get("smoothness") or {}).get("value"))]  # fmt: skip
        cells += [_fmt((abilities.get(a) or {}).get("value")) for a in _ABILITIES]
        rows.append("| " + " | ".join(cells) + " |")
    table = "\n".join(rows)
    (args.work / "table.md").write_text(table + "\n\n```text\n" + proc.stdout + "```\n")
    return table + "\n\n" + proc.stdout


# -------------------------------------------------------------------------------------------------- main


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line options."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--work", type=Path, required=True, help="working folder (corpus, checkpoints, evaluations)")
    p.add_argument("--stage", choices=("all",) + STAGES, default=["all"], nargs="+",
                   help="stage(s) to run, always in the chain's order (default all)")  # fmt: skip
    p.add_argument("--budget", type=float, default=None, help="seconds this call may take (resume with the next)")
    g = p.add_argument_group("corpus (b2d-collect)")
    g.add_argument("--preset", choices=("mini", "base", "full", "uniform"), default=None,
                   help="collect --preset PRESET --n-scale S instead of scenario mode")  # fmt: skip
    g.add_argument("--n-scale", type=float, default=0.1)
    g.add_argument("--scenarios", nargs="+", default=list(DEFAULT_SCENARIOS), help="scenario mode: the types")
    g.add_argument("--n", type=int, default=2, help="scenario mode: clips per type (the corpus size)")
    g.add_argument("--town", default="all", help="scenario mode: generated town of the corpus (default all = Town100)")
    g.add_argument("--width", type=int, default=320)
    g.add_argument("--height", type=int, default=180)
    g.add_argument("--collect-workers", default="auto")
    g.add_argument("--seed", type=int, default=1, help="seed of the training routes")
    g.add_argument("--val-split", action="store_true",
                   help="scenario mode: hold out a val part (b2d-split base rule) for the validation loss curve")  # fmt: skip
    g = p.add_argument_group("training")
    g.add_argument("--epochs-admlp", type=int, default=30)
    g.add_argument("--epochs-tcp", type=int, default=20)
    g.add_argument("--device", default="auto", help="auto, cpu or cuda")
    g.add_argument("--image-size", default="256x144", help="TCP input WxH")
    g.add_argument("--train-workers", type=int, default=2, help="DataLoader workers of the reading pass")
    g.add_argument("--threads", type=int, default=None, help="torch CPU threads while training")
    g.add_argument("--curves", type=Path, default=REPO / "baselines" / "curves", help="folder of the loss PNGs")
    g = p.add_argument_group("held-out evaluation")
    g.add_argument("--b2d220-routes", type=int, default=None,
                   help="bench2drive220 routes on the shipped towns to use (default: all 31), spread over types")
    g.add_argument("--heldout-town", default="urban", help="generated town of the generated held-out routes")
    g.add_argument("--heldout-scenarios", nargs="+", default=list(DEFAULT_SCENARIOS))
    g.add_argument("--heldout-n", type=int, default=1, help="generated held-out routes per type (0: none)")
    g.add_argument("--heldout-seed", type=int, default=1001)
    g.add_argument("--agents", nargs="+", default=["route_follower", "admlp", "tcp", "expert"],
                   choices=("route_follower", "admlp", "tcp", "expert"))  # fmt: skip
    g.add_argument("--eval-workers", default="auto")
    g.add_argument("--eval-seed", type=int, default=0)
    g.add_argument("--follower-speed", type=float, default=6.0)
    g.add_argument("--tcp-planner", default="only_traj", choices=("only_traj", "only_ctrl", "merge_ctrl_traj"))
    args = p.parse_args(argv)
    args.stages = list(STAGES) if "all" in args.stage else [s for s in STAGES if s in args.stage]
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the chosen stages in order; exit 0 when they are all complete, 3 when a later call must continue."""
    args = parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", stream=sys.stderr)
    deadline = Deadline(None if args.budget is None else time.monotonic() + args.budget)
    args.work.mkdir(parents=True, exist_ok=True)
    complete = True
    routes = args.work / "heldout.xml"
    for stage in args.stages:
        if stage == "collect":
            complete &= stage_collect(args, deadline)
            if not complete:
                break
        elif stage == "heldout":
            routes = stage_heldout(args)
        elif stage.startswith("train-"):
            complete &= stage_train(args, stage.removeprefix("train-"), deadline)
        elif stage == "eval":
            if not routes.is_file():
                routes = stage_heldout(args)
            complete &= stage_eval(args, routes, deadline)
        elif stage == "table":
            table = stage_table(args, routes)
            if table:
                print(table)
    if not complete:
        log.warning("not complete yet: run the same command again (it resumes)")
        return 3
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
