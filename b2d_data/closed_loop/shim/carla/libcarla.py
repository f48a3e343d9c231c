"""``carla.libcarla``: every class of the stand-in CARLA API, as the real package exposes them in its extension module.

Leaderboard code dispatches sensor data with ``isinstance(data, carla.libcarla.Image)`` and the like, so the names
must exist here as well as at the top level of ``carla``.
"""

from __future__ import annotations

from ._geom import *
from ._geom import __all__ as _geom_all
from ._types import *
from ._types import __all__ as _types_all
from ._world import *
from ._world import __all__ as _world_all

__all__: list[str] = []
__all__.extend(_geom_all)
__all__.extend(_types_all)
__all__.extend(_world_all)
