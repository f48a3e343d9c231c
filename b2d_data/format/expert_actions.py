"""Think2Drive's 39 discrete actions, whose index ends every ``expert_assessment`` vector (format.md §2.8).

The table is the one Bench2DriveZoo's ``prepare_B2D.py`` and TCP's ``gen_tcp_data.py`` decode
(``Discrete_Actions_DICT``): index → (throttle, steer, brake, reverse). Steer has CARLA's sign (+ = right).

:func:`nearest_action` maps a vehicle control to the index whose controls are closest. The distance is the squared
Euclidean distance in (throttle, steer, brake), with two rules that make it fit the table:

- action 0 (full brake) has no steer of its own, so its steer term is dropped: a braking control matches it
  whatever its steering (the table has no steered brake, and steering does not matter while stopping);
- a forward control is compared with the forward actions 0–29 only and a reversing control with the reverse
  actions 30–38 only (the expert never reverses, so its vectors never hold 30–38).

Ties go to the lower index. The table is coarse: on the expert's usual controls (no brake, |steer| ≤ 0.1) the
decoded throttle/steer lie within 0.21 of the control (worst case: throttle 0.5, steer ±0.05, between the 0.3 and
0.7 throttle rows and the 0 and ±0.1 steer columns: √(0.2² + 0.05²) ≈ 0.206).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DiscreteAction:
    """One row of the table: the controls an action index decodes to."""

    throttle: float
    steer: float
    brake: float
    reverse: bool

    def as_array(self) -> np.ndarray:
        """``[throttle, steer, brake, reverse]`` as float32 (reverse 0 or 1)."""
        return np.array([self.throttle, self.steer, self.brake, float(self.reverse)], dtype=np.float32)


def _rows(throttle: float, steers: tuple[float, ...], reverse: bool = False) -> list[DiscreteAction]:
    return [DiscreteAction(throttle, s, 0.0, reverse) for s in steers]


_STEER_9 = (-0.5, -0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.5)

#: Index → controls, in Think2Drive's order (format.md §2.8).
ACTIONS: tuple[DiscreteAction, ...] = tuple(
    [DiscreteAction(0.0, 0.0, 1.0, False)]  # 0: full brake
    + _rows(0.7, _STEER_9)  # 1–9
    + _rows(0.3, (-0.7, *_STEER_9, 0.7))  # 10–20
    + _rows(0.0, (-1.0, -0.6, -0.3, -0.1))  # 21–24: coast while steering left
    + _rows(1.0, (0.0,))  # 25: full throttle
    + _rows(0.0, (0.1, 0.3, 0.6, 1.0))  # 26–29: coast while steering right
    + _rows(0.5, _STEER_9, reverse=True)  # 30–38
)
N_ACTIONS = len(ACTIONS)
#: The full-brake action.
BRAKE_ACTION = 0
#: Indices of the forward and of the reversing actions.
FORWARD_ACTIONS = range(0, 30)
REVERSE_ACTIONS = range(30, N_ACTIONS)

_TABLE = np.array([[a.throttle, a.steer, a.brake] for a in ACTIONS], dtype=np.float64)
# Per-action weight of the steer term: 0 for the full brake (it matches any steering), else 1.
_STEER_WEIGHT = np.array([0.0 if a.brake > 0 else 1.0 for a in ACTIONS])


def action_control(index: int | float) -> DiscreteAction:
    """The controls of action ``index`` (a float holding an integer, as stored in the npz, is accepted)."""
    i = int(index)
    if i != index or not 0 <= i < N_ACTIONS:
        raise ValueError(f"action index must be an integer in [0, {N_ACTIONS - 1}], got {index!r}")
    return ACTIONS[i]


def nearest_action(throttle: float, steer: float, brake: float, reverse: bool = False) -> int:
    """Index of the action nearest to a control (distance and tie rule in the module docstring)."""
    candidates = REVERSE_ACTIONS if reverse else FORWARD_ACTIONS
    rows = _TABLE[candidates.start : candidates.stop]
    weight = _STEER_WEIGHT[candidates.start : candidates.stop]
    d2 = (rows[:, 0] - throttle) ** 2 + weight * (rows[:, 1] - steer) ** 2 + (rows[:, 2] - brake) ** 2
    return candidates.start + int(np.argmin(d2))  # argmin keeps the first (lowest) index on ties
