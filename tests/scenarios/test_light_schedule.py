"""LightSchedule (scenario_runner's TrafficLightFreezer): forced phases, then the lights' earlier states back."""

from __future__ import annotations

from types import SimpleNamespace

from b2d_data.scenarios.catalog.junctions import LightSchedule
from b2d_data.sim.api import TrafficLightState

GREEN, RED, YELLOW = TrafficLightState.GREEN, TrafficLightState.RED, TrafficLightState.YELLOW


class _Lights:
    """A simulator that only holds light states and whether each is frozen."""

    def __init__(self, states: dict[int, TrafficLightState]) -> None:
        self.states = dict(states)
        self.frozen: dict[int, bool] = {}

    def set_traffic_light_state(self, light_id: int, state: TrafficLightState, freeze: bool = True) -> None:
        self.states[light_id] = state
        self.frozen[light_id] = freeze

    def snapshot(self, t: float) -> SimpleNamespace:
        lights = {k: SimpleNamespace(state=v) for k, v in self.states.items()}
        return SimpleNamespace(timestamp=t, traffic_lights=lights)


def test_the_lights_get_their_states_from_before_the_freeze_back():
    # TrafficLightFreezer.terminate (atomic_behaviors.py) sets every light it froze back to the state it saved in
    # initialise: here light 1 was RED and 2 GREEN before the schedule forced 1 GREEN / 2 RED, then (after 5 s) both
    # RED, and a third light 3 (YELLOW before) only in the second phase.
    sim = _Lights({1: RED, 2: GREEN, 3: YELLOW})
    schedule = LightSchedule(sim, [({1: GREEN, 2: RED}, 5.0), ({1: RED, 2: RED, 3: RED}, 5.0)])  # type: ignore[arg-type]
    schedule.update(sim.snapshot(0.0))
    assert sim.states == {1: GREEN, 2: RED, 3: YELLOW} and sim.frozen == {1: True, 2: True}
    schedule.update(sim.snapshot(5.0))
    assert sim.states == {1: RED, 2: RED, 3: RED}
    schedule.update(sim.snapshot(10.0))  # the last timed phase is over: released
    assert sim.states == {1: RED, 2: GREEN, 3: YELLOW}
    assert sim.frozen == {1: False, 2: False, 3: False}
    schedule.update(sim.snapshot(15.0))  # nothing more happens
    assert sim.states == {1: RED, 2: GREEN, 3: YELLOW}


def test_an_open_ended_phase_restores_on_release():
    sim = _Lights({7: GREEN})
    schedule = LightSchedule(sim, [({7: RED}, None)])  # type: ignore[arg-type]
    schedule.update(sim.snapshot(0.0))
    schedule.update(sim.snapshot(100.0))
    assert sim.states[7] == RED and sim.frozen[7]
    schedule.release()
    assert sim.states[7] == GREEN and not sim.frozen[7]
