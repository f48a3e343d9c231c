"""Shared pieces of the collection tests: a real town and hand-built actor states."""

from __future__ import annotations

import pytest

from b2d_data.format.transform import BoundingBox, Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.sim.api import ActorKind, ActorState


@pytest.fixture(scope="session")
def town01(carla_maps_dir):
    """CARLA's Town01."""
    return load_opendrive(carla_maps_dir / "Town01.xodr")


def make_actor(actor_id: int, type_id: str, kind: ActorKind, transform: Transform, extent: tuple[float, ...],
               tags: tuple[int, ...] = (), speed: float = 0.0, **kw: object) -> ActorState:
    """An actor moving ``speed`` m/s along its heading, its box centred ``extent[2]`` above its origin."""
    fwd = transform.get_forward_vector()
    return ActorState(
        id=actor_id, type_id=type_id, kind=kind, transform=transform,
        velocity=Location(fwd.x * speed, fwd.y * speed, 0.0), angular_velocity=Location(), acceleration=Location(),
        bounding_box=BoundingBox(Location(0.0, 0.0, extent[2]), Location(*extent)), semantic_tags=tags,
        **kw,  # type: ignore[arg-type]
    )  # fmt: skip
