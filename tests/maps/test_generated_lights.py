"""CARLA-style traffic lights at a junction whose OpenDRIVE file has none (``Map.with_junction_lights``).

Tiny town: ``light_less_grid`` (tests/conftest.py), a 3 × 3 street grid without lights, one 3.49 m lane each way; the
centre point (120, -120) in CARLA's frame is a 4-way junction that four roads enter with one lane each.
"""

from __future__ import annotations

import math
import pickle

import pytest

from b2d_data.format.transform import Location
from b2d_data.maps import Map
from b2d_data.maps.generated_lights import GENERATED_PREFIX, has_traffic_lights
from b2d_data.sim.api import TrafficLightState
from b2d_data.sim.builtin.furniture import furniture_from_map
from b2d_data.sim.builtin.traffic_lights import TrafficLightController

CENTRE = Location(120.0, -120.0, 0.0)
G, Y, R = TrafficLightState.GREEN, TrafficLightState.YELLOW, TrafficLightState.RED


def centre_junction(town: Map) -> int:
    """The grid's 4-way junction (the one whose box is centred at (120, -120))."""
    return next(j.id for j in town.junctions.values() if j.bounding_box.location.distance_2d(CENTRE) < 1.0)


@pytest.fixture(scope="module")
def grid(light_less_grid) -> Map:
    return light_less_grid


def test_a_light_less_junction_gets_one_head_per_incoming_road_in_one_group(grid):
    junction = centre_junction(grid)
    assert not grid.traffic_lights() and not has_traffic_lights(grid, junction)
    lit = grid.with_junction_lights([junction])
    lights = lit.traffic_lights()
    # four roads enter the junction with one lane each: four heads, one governed lane (one trigger box) each
    assert len(lights) == 4
    assert all(len(light.lanes) == 1 and light.junction_id == junction for light in lights)
    assert all(light.id.startswith(GENERATED_PREFIX) for light in lights)
    assert has_traffic_lights(lit, junction)
    # the box is CARLA's generated one: centred 3 m before the entry, half extents (1.5, 0.25 * 3.49, 1.0)
    for light in lights:
        lane = light.lanes[0]
        entry = light.affected_lane_waypoints[0]
        assert lane.stop_waypoint.transform.location.distance_2d(entry.transform.location) == pytest.approx(3.0, 0.02)
        assert lane.trigger_box.extent.x == pytest.approx(1.5)
        assert lane.trigger_box.extent.y == pytest.approx(0.25 * 3.49, abs=0.01)
        # the head stands right of the lane, half a lane width + 1 m from its centre: 1.745 + 1 = 2.745 m
        assert light.transform.location.distance_2d(entry.transform.location) == pytest.approx(2.745, abs=0.01)
    # one controller per head, sequences 0..3, all of this junction: they take turns in one group
    controllers = [c for c in lit.controllers() if c.junction_id == junction]
    assert sorted(c.sequence for c in controllers) == [0, 1, 2, 3]
    assert sorted(s for c in controllers for s in c.signal_ids) == sorted(light.id for light in lights)
    specs, _ = furniture_from_map(lit)
    assert {spec.group_key for spec in specs} == {junction}
    assert len({spec.pole_key for spec in specs}) == 4


def test_the_town_itself_is_unchanged_and_a_pickled_copy_keeps_its_lights(grid):
    junction = centre_junction(grid)
    lit = grid.with_junction_lights([junction])
    assert lit is not grid and not grid.traffic_lights()
    assert lit.with_junction_lights([junction]) is lit  # nothing new to add
    # waypoints of the copy belong to the copy (equality needs one map): junctions were rebuilt on it
    assert lit.junctions[junction].map is lit
    clone = pickle.loads(pickle.dumps(lit))
    assert sorted(light.id for light in clone.traffic_lights()) == sorted(light.id for light in lit.traffic_lights())


def test_generated_heads_cycle_with_carla_default_timing(grid):
    """Pole k is green over [15k, 15k + 10) s, yellow [15k + 10, 15k + 13), red [15k + 13, 15k + 15): 60 s a turn."""
    lit = grid.with_junction_lights([centre_junction(grid)])
    specs, _ = furniture_from_map(lit)
    ctrl = TrafficLightController([(100 + k, spec) for k, spec in enumerate(specs)])  # no rng: the cycle starts at 0
    order = sorted(range(4), key=lambda k: specs[k].pole_key)
    ids = [100 + k for k in order]

    def states() -> list[TrafficLightState]:
        return [ctrl.state(i) for i in ids]

    def run(seconds: float) -> None:
        for _ in range(round(seconds / 0.05)):
            ctrl.advance(0.05)

    assert states() == [G, R, R, R]
    run(9.95)
    assert states() == [G, R, R, R]
    run(0.05)  # t = 10 s
    assert states() == [Y, R, R, R]
    run(3.0)  # t = 13 s: all red
    assert states() == [R, R, R, R]
    run(2.0)  # t = 15 s: the second head
    assert states() == [R, G, R, R]
    run(45.0)  # t = 60 s: three more turns, back to the first head
    assert states() == [G, R, R, R]


def test_heads_take_turns_clockwise_from_north(grid):
    """Bearings from the junction centre, clockwise from north, of each head's entry point (right-hand traffic).

    The east road's lane enters 1.745 m north of the centre line, about 10 m out: atan2(10, 1.745) ≈ 80°; then
    south ≈ 170°, west ≈ 260°, and the north road's lane, 1.745 m west of its centre line, ≈ 350°, last.
    """
    lit = grid.with_junction_lights([centre_junction(grid)])
    by_sequence = {c.sequence: c.signal_ids[0] for c in lit.controllers()}
    bearings = []
    for k in range(4):
        loc = lit.signal(by_sequence[k]).affected_lane_waypoints[0].transform.location
        bearings.append(math.degrees(math.atan2(loc.x - 120.0, -(loc.y + 120.0))) % 360.0)
    assert bearings == sorted(bearings)
    assert [round(b / 90.0) % 4 for b in bearings] == [1, 2, 3, 0]  # east, south, west, north
