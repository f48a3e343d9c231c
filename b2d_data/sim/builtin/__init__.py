"""The embedded simulator: a synchronous, deterministic 20 Hz world (see :mod:`b2d_data.sim.builtin.world`).

``BuiltinSimulator`` is imported lazily so that the sensor sub-package can be used without loading the world.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from b2d_data.sim.builtin.world import BuiltinSimulator

__all__ = ["BuiltinSimulator"]


def __getattr__(name: str) -> Any:
    if name == "BuiltinSimulator":
        from b2d_data.sim.builtin.world import BuiltinSimulator

        return BuiltinSimulator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
