"""Leaderboard 2.0 routes and scenarios without CARLA: route XML, the scenario framework and catalog, placement,
criteria and the route runner (docs/interfaces.md, "Issue 4").

The framework's names are importable from here lazily (``from b2d_data.scenarios import ScenarioManager``), so
that importing a light submodule such as ``route_xml`` does not pull in the simulator protocol and the catalog.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    "SCENARIO_CLASSES": "framework",
    "SCENARIO_TIMEOUT": "framework",
    "Scenario": "framework",
    "ScenarioContext": "framework",
    "ScenarioError": "framework",
    "ScenarioManager": "framework",
    "ScenarioSetupError": "framework",
    "ScenarioStatus": "framework",
    "ScenarioTimeoutTest": "framework",
    "UnknownScenarioError": "framework",
    "YieldToEmergencyVehicleTest": "framework",
    "register": "framework",
    "scenario_class": "framework",
    "Candidate": "placement",
    "PlacementError": "placement",
    "find_candidates": "placement",
    "make_routes": "placement",
    "Route": "route_xml",
    "ScenarioConfig": "route_xml",
    "read_routes": "route_xml",
    "write_routes": "route_xml",
}

__all__ = [
    "SCENARIO_CLASSES",
    "SCENARIO_TIMEOUT",
    "Candidate",
    "PlacementError",
    "Route",
    "Scenario",
    "ScenarioConfig",
    "ScenarioContext",
    "ScenarioError",
    "ScenarioManager",
    "ScenarioSetupError",
    "ScenarioStatus",
    "ScenarioTimeoutTest",
    "UnknownScenarioError",
    "YieldToEmergencyVehicleTest",
    "find_candidates",
    "make_routes",
    "read_routes",
    "register",
    "scenario_class",
    "write_routes",
]


def __getattr__(name: str) -> Any:
    """Import the exported names on first use."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'b2d_data.scenarios' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"b2d_data.scenarios.{module}"), name)
    globals()[name] = value
    return value
