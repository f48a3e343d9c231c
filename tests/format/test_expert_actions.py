"""Think2Drive's 39-action table and the nearest-action rule, with values worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.expert_actions import (
    ACTIONS,
    BRAKE_ACTION,
    DiscreteAction,
    action_control,
    nearest_action,
)


def test_table_matches_format_md():
    assert len(ACTIONS) == 39
    assert ACTIONS[0] == DiscreteAction(0.0, 0.0, 1.0, False)
    assert [a.steer for a in ACTIONS[1:10]] == [-0.5, -0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.5]
    assert {a.throttle for a in ACTIONS[1:10]} == {0.7}
    assert [a.steer for a in ACTIONS[10:21]] == [-0.7, -0.5, -0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.5, 0.7]
    assert {a.throttle for a in ACTIONS[10:21]} == {0.3}
    assert [(a.throttle, a.steer) for a in ACTIONS[21:30]] == [
        (0.0, -1.0), (0.0, -0.6), (0.0, -0.3), (0.0, -0.1), (1.0, 0.0), (0.0, 0.1), (0.0, 0.3), (0.0, 0.6), (0.0, 1.0)
    ]  # fmt: skip
    assert all(a.reverse and a.throttle == 0.5 for a in ACTIONS[30:]) and not any(a.reverse for a in ACTIONS[:30])
    assert [a.steer for a in ACTIONS[30:]] == [-0.5, -0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.5]
    assert all(a.brake == 0.0 for a in ACTIONS[1:])


@pytest.mark.parametrize(
    ("control", "index"),
    [
        # Full brake, whatever the steering: action 0 has no steer term.
        ((0.0, 0.4, 1.0, False), 0),
        # (0.75, 0.02): to (0.7, 0) d² = 0.0025 + 0.0004 = 0.0029; to (1, 0) d² = 0.0625 → 5.
        ((0.75, 0.02, 0.0, False), 5),
        # (0.95, 0): to (1, 0) d² = 0.0025; to (0.7, 0) 0.0625 → 25.
        ((0.95, 0.0, 0.0, False), 25),
        # (0.35, −0.27): to (0.3, −0.3) d² = 0.0025 + 0.0009 = 0.0034; to (0.3, −0.2) 0.0025 + 0.0049 → 12.
        ((0.35, -0.27, 0.0, False), 12),
        # (0.1, 0.02): to (0, 0.1) 0.01 + 0.0064 = 0.0164; (0, −0.1) 0.01 + 0.0144 = 0.0244; (0.3, 0) 0.0404 → 26.
        ((0.1, 0.02, 0.0, False), 26),
        # (0.45, 0): to (0.3, 0) 0.0225; to (0.7, 0) 0.0625 → 15.
        ((0.45, 0.0, 0.0, False), 15),
        # (0.5, 0): equally far (0.04) from (0.3, 0) and (0.7, 0): the lower index, 5, wins.
        ((0.5, 0.0, 0.0, False), 5),
        # (0.7, 0.9): (0.7, 0.5) 0.16; (0.3, 0.7) 0.16 + 0.04 = 0.2; (0, 1) 0.49 + 0.01 → 9.
        ((0.7, 0.9, 0.0, False), 9),
        # Reverse controls only match 30–38: (0.5, 0.1) is action 35.
        ((0.5, 0.1, 0.0, True), 35),
        # brake 0.3, no throttle, steer 0: to action 0 (1 − 0.3)² = 0.49; to (0, ±0.1) 0.01 + 0.09 = 0.1 → 24.
        ((0.0, 0.0, 0.3, False), 24),
    ],
)
def test_nearest_action_by_hand(control, index):
    assert nearest_action(*control) == index


def test_round_trip_controls_index_controls():
    # Every action decodes to controls that encode back to it (steer is irrelevant to action 0).
    for i, action in enumerate(ACTIONS):
        assert nearest_action(action.throttle, action.steer, action.brake, action.reverse) == i
    # The decoded control of the expert's usual range (no brake, |steer| ≤ 0.1) stays within 0.21 of it; the worst
    # point, (0.5, ±0.05), is √(0.2² + 0.05²) ≈ 0.206 from its four surrounding actions.
    worst = 0.0
    for throttle in np.linspace(0.0, 1.0, 41):
        for steer in np.linspace(-0.1, 0.1, 21):
            a = action_control(nearest_action(throttle, steer, 0.0))
            assert a.brake == 0.0 and not a.reverse
            worst = max(worst, float(np.hypot(a.throttle - throttle, a.steer - steer)))
    assert worst == pytest.approx(np.hypot(0.2, 0.05))


def test_action_control_checks_the_index():
    assert action_control(5.0) == DiscreteAction(0.7, 0.0, 0.0, False)  # stored as float in the npz
    assert np.array_equal(action_control(BRAKE_ACTION).as_array(), np.array([0, 0, 1, 0], np.float32))
    for bad in (-1, 39, 2.5):
        with pytest.raises(ValueError, match="action index"):
            action_control(bad)
