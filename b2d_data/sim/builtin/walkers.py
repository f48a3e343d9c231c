"""Walker motion: a kinematic point that moves along ``WalkerControl.direction × speed`` and faces it."""

from __future__ import annotations

import numpy as np


def walker_velocity(direction: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """(n, 2) horizontal velocities: the horizontal part of each direction, normalised, times its speed.

    Walkers stay on the ground, so a direction's z component is dropped; a zero direction means standing.
    """
    horizontal = np.asarray(direction, dtype=np.float64)[:, :2]
    norm = np.linalg.norm(horizontal, axis=1)
    unit = np.divide(horizontal, norm[:, None], out=np.zeros_like(horizontal), where=norm[:, None] > 1e-9)
    return unit * np.maximum(np.asarray(speed, dtype=np.float64), 0.0)[:, None]


def step_walkers(x: np.ndarray, y: np.ndarray, yaw_deg: np.ndarray, velocity: np.ndarray,
                 dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Move n walkers by ``velocity · dt``; a moving walker turns to face its motion (CARLA's walkers do)."""
    moving = np.linalg.norm(velocity, axis=1) > 1e-6
    yaw = np.where(moving, np.degrees(np.arctan2(velocity[:, 1], velocity[:, 0])), yaw_deg)
    return x + velocity[:, 0] * dt, y + velocity[:, 1] * dt, yaw
