"""``leaderboard.autoagents.agent_wrapper``: the sensor rules an agent's rig must follow (Bench2Drive's values).

The rules live in :mod:`b2d_data.closed_loop.sensor_config`, which the evaluator uses too; this module re-exports them
under the Leaderboard's names.
"""

from __future__ import annotations

from b2d_data.closed_loop.sensor_config import (
    ALLOWED_SENSORS,
    MAX_ALLOWED_RADIUS_SENSOR,
    QUALIFIER_SENSORS_LIMITS,
    SENSORS_LIMITS,
    SensorConfigurationInvalid,
    max_allowed_radius,
    validate_sensor_configuration,
)

__all__ = [
    "ALLOWED_SENSORS", "MAX_ALLOWED_RADIUS_SENSOR", "QUALIFIER_SENSORS_LIMITS", "SENSORS_LIMITS", "AgentError",
    "SensorConfigurationInvalid", "TickRuntimeError", "max_allowed_radius", "validate_sensor_configuration",
]  # fmt: skip


class AgentError(Exception):
    """The agent failed while the route ran."""


class TickRuntimeError(Exception):
    """The route ran past its tick limit."""
