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
    # rear need = 3 + 0.25 * 12 + (12 - 10)^2 / (2 * (3 + 2)) = 6.4 -> from -10 + 2.3 + 2.4 + 6.4 = 1.1
    # front need = 3 + 0.2 * 10 (no closing on the leader) = 5 -> to 20 - 2.3 - 2.4 - 5 = 10.3
    # behind the follower: to -10 - 4.7 - 5 = -19.7; ahead of the leader: from 20 + 4.7 + (3 + 2.5 + 0) = 30.2
    slots = gate._slots([follower, leader], 10.0, 2.4)
    assert [(lo, hi) for lo, hi, _ in slots] == [
        (-math.inf, pytest.approx(-19.7)),
        (pytest.approx(1.1), pytest.approx(10.3)),
        (pytest.approx(30.2), math.inf),
    ]
    assert slots[1][2] == pytest.approx(11.0)  # the gap moves at its cars' mean speed


def test_a_gap_too_short_for_the_ego_is_no_slot():
    gate = LaneChangeGate(ExpertConfig(), None, GapConfig())
    # 15 m between centres at 10 m/s: rear need 5.5, front need 5, the bodies 9.4 -> no room
    cars = [_Car(-5.0, 2.3, 10.0, None), _Car(10.0, 2.3, 10.0, None)]
    assert len(gate._slots(cars, 10.0, 2.4)) == 2  # only behind the first and ahead of the second


def test_a_dense_flow_at_15_m_s_leaves_a_slot_at_matched_speed():
    # the densest HighwayExit flow of the training ranges: cars 25 m apart at 15 m/s (route 149130001, seed 149)
    # rear need 3 + 0.25 * 15 = 6.75 -> from 4.6 + 6.75 = 11.35; front need 3 + 0.2 * 15 = 6 -> to 25 - 4.6 - 6 = 14.4
    gate = LaneChangeGate(ExpertConfig(), None, GapConfig())
    cars = [_Car(0.0, 2.3, 15.0, None), _Car(25.0, 2.3, 15.0, None)]
    slots = gate._slots(cars, 15.0, 2.3)
    assert [(lo, hi) for lo, hi, _ in slots[1:2]] == [(pytest.approx(11.35), pytest.approx(14.4))]


def test_dropping_back_to_a_gap_keeps_the_ego_rolling():
    # Ego at s = 0 (half 2.4), desired 20 m/s, 100 m to the last start point; a 14 m/s flow (half 2.3) at
    # -45, -15, 5, 22. At the gap's speed the rear need is 3 + 0.25 * 14 = 6.5 and the front need 3 + 0.2 * 14 = 5.8:
    # (-45, -15): from -45 + 4.7 + 6.5 = -33.8 to -15 - 4.7 - 5.8 = -25.5, aimed 1 m inside: r = 26.5 behind;
    #   at 0.3 * 14 = 4.2 m/s back: 6.31 s, travel 14 * 6.31 - 26.5 = 61.8 m <= 100 - 2 - 14^2 / 6 = 65.3 (fits)
    # (-15, 5) and (5, 22) are too short; (22, window end 90): from 33.2, 34.2 ahead at 6 m/s: 5.7 s, 114 m (no);
    # (window end -70, -45): to -55.5, 56.5 behind: 13.5 s, 131.8 m (no).
    # Speed: 14 - min(sqrt(2 * 1.5 * 26.5), 4.2) = 9.8 (the former gain of 0.4 / s asked 14 - 0.4 * 29.3 = 2.3, and
    # a gap of a flow that never brakes does not fit an ego that slow once it comes: route 149130003, seed 149).
    gate = LaneChangeGate(ExpertConfig(), None, GapConfig())
    cars = [_Car(s, 2.3, 14.0, None) for s in (-45.0, -15.0, 5.0, 22.0)]
    assert gate._align(cars, 0.0, 2.4, 20.0, 100.0) == pytest.approx(9.8)


def test_no_dropping_back_toward_the_unseen_end_of_the_flow():
    # Cars 20 m apart (no gap: 4.7 + 4.7 + 6.5 + 5.8 = 21.7 m needed) over the whole search window, -70 to 90 m:
    # no gap to aim at, so the desired speed; the former gate took the open end behind the last car seen for a
    # gap and stopped the ego for it (14 - 0.4 * 79.5 < 0), though the flow goes on there (route 149130020).
    gate = LaneChangeGate(ExpertConfig(), None, GapConfig())
    cars = [_Car(s, 2.3, 14.0, None) for s in (-60.0, -40.0, -20.0, 0.0, 20.0, 40.0, 60.0, 80.0)]
    assert gate._align(cars, 0.0, 2.4, 20.0, 100.0) == pytest.approx(20.0)


def test_expert_knows_the_role_of_scenario_actors():
    # The expert hands route lane changes to the gap gate only while a scenario's vehicles are in the world.
    from b2d_data.expert import expert as expert_module
    from b2d_data.scenarios.framework import SCENARIO_ROLE

    assert expert_module._SCENARIO_ROLE == SCENARIO_ROLE
