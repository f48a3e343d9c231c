"""The lane-change gate's gap arithmetic (distances worked out by hand from GapConfig's defaults)."""

from __future__ import annotations

import math

import pytest

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.lane_change_gap import GapConfig, LaneChangeGate, _Car


def test_slots_between_flow_cars_follow_speeds_and_closing_speed():
    gate = LaneChangeGate(ExpertConfig(), None)
    follower = _Car(s=-10.0, half=2.3, speed=12.0, actor=None)
    leader = _Car(s=20.0, half=2.3, speed=10.0, actor=None)
    # ego at 10 m/s, half length 2.4:
    # rear need = 3 + 0.4 * 12 + (12 - 10)^2 / (2 * (3 + 2)) = 8.2 -> from -10 + 2.3 + 2.4 + 8.2 = 2.9
    # front need = 3 + 0.3 * 10 (no closing on the leader) = 6 -> to 20 - 2.3 - 2.4 - 6 = 9.3
    # behind the follower: to -10 - 4.7 - 6 = -20.7; ahead of the leader: from 20 + 4.7 + (3 + 4 + 0) = 31.7
    slots = gate._slots([follower, leader], 10.0, 2.4)
    assert [(lo, hi) for lo, hi, _ in slots] == [
        (-math.inf, pytest.approx(-20.7)),
        (pytest.approx(2.9), pytest.approx(9.3)),
        (pytest.approx(31.7), math.inf),
    ]
    assert slots[1][2] == pytest.approx(11.0)  # the gap moves at its cars' mean speed


def test_a_gap_too_short_for_the_ego_is_no_slot():
    gate = LaneChangeGate(ExpertConfig(), None, GapConfig())
    # 15 m between centres at 10 m/s: rear need 7, front need 6, the bodies 9.4 -> no room
    cars = [_Car(-5.0, 2.3, 10.0, None), _Car(10.0, 2.3, 10.0, None)]
    assert len(gate._slots(cars, 10.0, 2.4)) == 2  # only behind the first and ahead of the second


def test_expert_knows_the_role_of_scenario_actors():
    # The expert hands route lane changes to the gap gate only while a scenario's vehicles are in the world.
    from b2d_data.expert import expert as expert_module
    from b2d_data.scenarios.framework import SCENARIO_ROLE

    assert expert_module._SCENARIO_ROLE == SCENARIO_ROLE
