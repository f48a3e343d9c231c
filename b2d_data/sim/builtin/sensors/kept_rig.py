"""The renderer and ray caster of a closed sensor suite, kept for the next suite the process opens.

A collection's route process runs one route after another, mostly on the same town. Each new suite used to open a
GL context (0.46 s on an H100 host), compile the shader programs its weathers need (18–42 per route, 0.2–1.6 s) and
upload and build the town's scene for the renderer and the ray caster (0.4 s), all thrown away at the route's end.
A kept renderer has its programs; its static scene and the caster's are not uploaded again when the next route's
scene holds the same arrays (``mesh_digest``). One suite's worth is kept per process: taking it needs the same
construction arguments (``key``), and keeping another releases it.
"""

from __future__ import annotations

import logging
from typing import Any

log = logging.getLogger(__name__)

_kept: tuple[tuple, Any, Any] | None = None  # (key, renderer, caster)


def take(key: tuple) -> tuple[Any, Any] | None:
    """The kept (renderer, caster) if they were built with ``key``, else ``None``; taking leaves nothing kept."""
    global _kept
    if _kept is None or _kept[0] != key:
        return None
    _, renderer, caster = _kept
    _kept = None
    log.debug("reusing the last suite's renderer and ray caster")
    return renderer, caster


def keep(key: tuple, renderer: Any, caster: Any) -> None:
    """Keep ``renderer`` and ``caster`` (either may be ``None``) for a later :func:`take`, releasing what was kept."""
    global _kept
    release()
    _kept = (key, renderer, caster)


def release() -> None:
    """Close whatever is kept (the caster first: the GPU caster works in the renderer's context)."""
    global _kept
    if _kept is None:
        return
    _, renderer, caster = _kept
    _kept = None
    if caster is not None:
        caster.close()
    if renderer is not None:
        renderer.close()
