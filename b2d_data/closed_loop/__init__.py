"""Closed-loop evaluation of Leaderboard 2.0 agents on the builtin simulator (``b2d-eval run``).

An agent written for the Leaderboard / Bench2Drive evaluator runs here unchanged: each route runs in its own
process, where the folder :data:`SHIM_DIR` is put first on ``sys.path`` so that the agent's ``import carla``,
``leaderboard``, ``srunner`` and ``agents`` find modules backed by the builtin simulator (``shim/``). Those modules
read the running route through :mod:`b2d_data.closed_loop.bridge`. Nothing of this is importable under those names
outside an evaluation's route processes.
"""

from __future__ import annotations

from pathlib import Path

#: The folder whose top-level packages (``carla``, ``leaderboard``, ``srunner``, ``agents``) stand in for CARLA's
#: Python API, the Leaderboard and the scenario runner inside a route process.
SHIM_DIR = Path(__file__).resolve().parent / "shim"

#: Agents that ship with the package, by the name ``b2d-eval run --agent NAME`` accepts.
REFERENCE_AGENTS: dict[str, Path] = {
    "expert": Path(__file__).resolve().parent / "reference_agents" / "expert_agent.py",
}


def resolve_agent(path: Path) -> Path:
    """An agent file: ``path`` itself, or the shipped agent of that name (``expert``) when no such file exists."""
    if not path.exists() and str(path) in REFERENCE_AGENTS:
        return REFERENCE_AGENTS[str(path)]
    return path
