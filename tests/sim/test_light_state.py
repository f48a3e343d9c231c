"""Vehicle light states: CARLA's flag bits, the string Bench2Drive's annotation stores, the lamps that glow."""

from __future__ import annotations

import pytest

from b2d_data.closed_loop.shim.carla._types import VehicleLightState
from b2d_data.collection.annotations import vehicle_box
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.sim.api import ActorSpec
from b2d_data.sim.builtin.sensors.actor_mesh import light_flags
from b2d_data.sim.light_state import carla_str, light_bits, sirens_on

from .conftest import FlatTown


def _at(x: float) -> Transform:
    return Transform(Location(x, 0.0, 0.0), Rotation())


@pytest.mark.parametrize(
    ("state", "bits", "anno"),
    [
        # LibCarla rpc/VehicleLightState.h: Position 0x1, RightBlinker 1 << 4, LeftBlinker 1 << 5, Special1 1 << 9,
        # Special2 1 << 10. Boost.Python's enum_str gives a member's name for a value that is one member and
        # PyLong's str otherwise, so Special1 | Special2 = 512 + 1024 is stored as "1536".
        ("NONE", 0, "NONE"),
        ("Special1", 512, "Special1"),
        ("Special1|Special2", 1536, "1536"),  # LB2.0 emergency vehicles
        ("Special1|Special2|Position", 1537, "1537"),  # LB2.0 Accident's police car
        ("RightBlinker|LeftBlinker|Position", 49, "49"),  # LB2.0 ParkedObstacle
        ("Brake", 8, "Brake"),  # BlockedIntersection
        ("All", 0xFFFFFFFF, "All"),
        ("special2, position", 1025, "1025"),
        ("1536", 1536, "1536"),
    ],
)
def test_bits_and_the_annotation_string(state, bits, anno):
    assert light_bits(state) == bits
    assert carla_str(state) == anno
    # the CARLA shim's enum prints the same (a Bench2Drive agent's str(get_light_state()).split('.')[-1])
    assert str(VehicleLightState(bits)).split(".")[-1] == anno


def test_sirens_light_from_either_special_bit():
    assert sirens_on("Special1") and sirens_on("Special2") and sirens_on("Special1|Special2")
    assert not sirens_on("Position|LeftBlinker|RightBlinker") and not sirens_on("NONE")


def test_world_annotation_and_lamps_follow_the_flags(flat_world):
    police = flat_world.spawn_actor(ActorSpec("vehicle.dodge.charger_police_2020"), _at(0.0))
    parked = flat_world.spawn_actor(ActorSpec("vehicle.audi.a2"), _at(20.0))
    flat_world.set_light_state(police, "Special1|Special2|Position")
    flat_world.set_light_state(parked, "Special2")
    s = flat_world.tick()
    ego, car = s.actors[police], s.actors[parked]
    assert vehicle_box(FlatTown(), ego, ego, None)["light_state"] == "1537"
    assert vehicle_box(FlatTown(), ego, car, None)["light_state"] == "Special2"
    day = light_flags(ego, night=False, timestamp=0.0)
    # Position lights glow (head lamps) but cast no low beam; the siren bar flashes (4 Hz phase: 0 at t = 0).
    assert day.head and not day.beam and day.siren == 0 and not day.brake
    assert light_flags(car, night=False, timestamp=0.25).siren == 1
    assert light_flags(car, night=True, timestamp=0.0).beam
