"""The waypoint → control conversion against values worked out by hand from Bench2DriveZoo's control_pid."""

from __future__ import annotations

import math

import pytest

from baselines.controller import ControlOutput, WaypointController, agent_control, heading_units


def test_heading_units() -> None:
    # Straight ahead is 0; 45° to the right is +0.5 (units of 90°, clockwise = right = CARLA's + steer).
    assert heading_units(10.0, 0.0) == pytest.approx(0.0)
    assert heading_units(1.0, 1.0) == pytest.approx(0.5)
    assert heading_units(1.0, -1.0) == pytest.approx(-0.5)


def test_pid_conversion_by_hand() -> None:
    """One step of a fresh controller on a right-curving prediction (numbers worked out by hand)."""
    wp = [(2.0, 0.2), (4.0, 0.8), (6.0, 1.8), (8.0, 3.2)]
    out = WaypointController().step(wp, speed=4.4, target=(20.0, 4.0))
    # desired speed = (|(2,.6)| + |(2,1)| + |(2,1.4)|) / 0.5 s / 3 = (2.08806 + 2.23607 + 2.44131) / 1.5 = 4.51029
    assert out.desired_speed == pytest.approx(4.510294, abs=1e-5)
    # Segment midpoints lie 3.04, 5.17, 7.43 m away: the first is nearest 4 m, so the aim is wp[0] = (2, 0.2).
    assert out.aim == pytest.approx((2.0, 0.2))
    # angle = atan2(0.2, 2) = 5.7106° → 0.063451; the target's 0.125666 turns more and differs from the last
    # segment's 0.388800 by 0.263 < 0.3, so the prediction is kept.
    assert out.angle_final == pytest.approx(0.063451, abs=1e-6)
    # steer = 0.75 e + 0.75 mean(39 zeros, e) + 0.3 (e − 0) = 0.75·0.063451 + 0.75·0.063451/40 + 0.3·0.063451
    assert out.steer == pytest.approx(0.0678133, abs=1e-6)
    # No brake (4.4 / 4.510 = 0.976 < 1.1); delta = 0.110294; throttle = 5 d + 0.5 d/40 + 1.0 d = 0.663140
    assert not out.brake
    assert out.throttle == pytest.approx(0.663140, abs=1e-5)


def test_brake_rules() -> None:
    # Waypoints 0.1 m apart → desired 0.2·… < 0.4 m/s: brake, and the agent makes it a full brake with no throttle.
    out = WaypointController().step([(0.1, 0.0), (0.2, 0.0), (0.3, 0.0), (0.4, 0.0)], speed=0.0, target=(20.0, 0.0))
    assert out.desired_speed == pytest.approx(0.2)
    assert out.brake and out.throttle == 0.0
    assert agent_control(out, 0.0) == (0.0, 0.0, 1.0)
    # 2 m apart (4 m/s) while driving 5 m/s: 5 / 4 = 1.25 > 1.1 → brake.
    fast = WaypointController().step([(2.0, 0.0), (4.0, 0.0), (6.0, 0.0), (8.0, 0.0)], speed=5.0, target=(20.0, 0.0))
    assert fast.brake


def test_throttle_cap_is_the_zoo_creep_rule() -> None:
    out = ControlOutput(steer=0.0, throttle=0.6, brake=False, desired_speed=5.0, angle_final=0.0, aim=(4.0, 0.0))
    assert agent_control(out, 3.0, throttle_cap=False) == (0.0, 0.6, 0.0)
    # Above 1.5 m/s with the wheel straight the Zoo TCP agent allows 0.05; below it, up to 0.5.
    assert agent_control(out, 3.0, throttle_cap=True)[1] == pytest.approx(0.05)
    assert agent_control(out, 1.0, throttle_cap=True)[1] == pytest.approx(0.5)
    assert not math.isnan(agent_control(out, 1.0)[1])
