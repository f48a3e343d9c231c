"""Intelligent Driver Model target speeds (expert-and-scenarios.md §1.4).

Each hazard (leading vehicle, red light, stop sign, ...) becomes a virtual leader; IDM is integrated for one
frame from the ego's current speed and the speed reached is the target speed for that hazard.
"""

from __future__ import annotations

import math

from scipy.integrate import RK45

from b2d_data.expert.config import ExpertConfig

#: Below this desired speed (m/s) the target is 0: the (v / v_des)^δ term makes the integration so stiff that RK45
#: crawls through millions of steps and overflows (a merge whose speed cap fell to 0.015 m/s).
MIN_DESIRED_SPEED = 0.1


def idm_acceleration(ego_speed: float, desired_speed: float, gap: float, lead_speed: float, s0: float, T: float,
                     a: float, b: float, delta: float) -> float:
    """Standard IDM acceleration dv/dt = a·[1 − (v/v_des)^δ − (s*/s)²]."""
    s_star = s0 + ego_speed * T + ego_speed * (ego_speed - lead_speed) / (2.0 * math.sqrt(a * b))
    return a * (1.0 - (ego_speed / desired_speed) ** delta - (s_star / gap) ** 2)


def idm_target_speed(config: ExpertConfig, desired_speed: float, ego_speed: float, lead_length: float,
                     lead_speed: float, distance: float, s0: float, T: float) -> float:
    """Speed (≥ 0) after integrating IDM for ``config.idm_t_bound`` s from the ego's current speed.

    ``distance`` is measured from the ego to the leader's reference point, ``lead_length`` is the part of it
    that is not free road (the gap is ``max(0.1, distance + t·lead_speed − x_ego − lead_length)``).
    """
    if desired_speed < MIN_DESIRED_SPEED:
        return 0.0
    if math.isinf(distance):
        distance = 1e9  # no leader: free-road acceleration
    a = config.idm_max_acceleration
    # a softer b at higher speed was measured on CARLA's car (§1.4)
    b = config.idm_braking_high_speed if ego_speed > config.idm_braking_threshold else config.idm_braking_low_speed
    delta = config.idm_acceleration_exponent

    def rhs(t: float, state):
        x, v = state
        # the floor keeps the (s*/s)² term finite when the leader is reached
        gap = max(0.1, distance + t * lead_speed - x - lead_length)
        return [v, idm_acceleration(v, desired_speed, gap, lead_speed, s0, T, a, b, delta)]

    solver = RK45(rhs, 0.0, [0.0, float(ego_speed)], config.idm_t_bound)
    while solver.status == "running":
        solver.step()
    return max(0.0, float(solver.y[1]))
