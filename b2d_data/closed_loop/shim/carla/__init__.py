"""A pure-Python stand-in for CARLA 0.9.15's Python API, backed by b2d-data's builtin simulator.

Importable as ``carla`` only inside a route of ``b2d-eval run`` (the folder ``b2d_data/closed_loop/shim`` is then first
on ``sys.path``). Value types (``Location``, ``Rotation``, ``Transform``, ``VehicleControl`` ...) behave like CARLA's;
``World``, actors and ``Map`` are read-only views of the running route (see ``carla._world``). Conversions to and from
b2d-data's own records live in ``carla._convert``.
"""

from __future__ import annotations

from . import libcarla
from .libcarla import *
from .libcarla import __all__ as _libcarla_all

__version__ = "0.9.15"

__all__ = ["libcarla"]
__all__.extend(_libcarla_all)
