"""Model inputs and targets, computed the same way from a ``ClipDataset`` sample and from an agent's sensors.

Everything is in CARLA's ego frame (x forward, y right, yaw clockwise), the frame Bench2DriveZoo's AD-MLP and TCP
train and drive in: the datasets are built with ``frame="carla"`` and ``pose_source="gnss"`` so that a training
sample sees the ego pose as the agent will at test time (GNSS position at the GNSS mount and compass heading).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from b2d_data.format.road_option import RoadOption

#: Past ego poses the AD-MLP sees (every 0.5 s, oldest first; the current pose is the origin and is left out).
PAST_STEPS = 4
#: Seconds between two history / future waypoints (5 frames at 10 Hz).
WAYPOINT_DT = 0.5
#: Length of the AD-MLP input: 4 past (x, y), 4 past yaws, speed, IMU acceleration (3), 6-way command.
ADMLP_INPUT_DIM = 2 * PAST_STEPS + PAST_STEPS + 1 + 3 + 6
#: TCP's speed normalisation (speed / 12 in its measurement input and speed head).
TCP_SPEED_SCALE = 12.0
#: TCP's measurement vector: speed / 12, target point (2), 6-way command.
TCP_STATE_DIM = 1 + 2 + 6


def command_one_hot(command: int) -> np.ndarray:
    """The 6-way one-hot of a RoadOption value (VOID and unknown values count as LANEFOLLOW, as in the Zoo)."""
    try:
        index = RoadOption(int(command)).to_six_way()
    except ValueError:
        index = RoadOption.LANEFOLLOW.to_six_way()
    out = np.zeros(6, np.float32)
    out[index] = 1.0
    return out


def admlp_input(
    past_xy: np.ndarray, past_yaw: np.ndarray, speed: float, accel: Sequence[float], command: int
) -> np.ndarray:
    """The (22,) AD-MLP input: past positions and yaws in the current ego frame, speed, IMU acceleration, command."""
    past_xy = np.asarray(past_xy, np.float32).reshape(PAST_STEPS, 2)
    past_yaw = np.asarray(past_yaw, np.float32).reshape(PAST_STEPS)
    return np.concatenate(
        [past_xy.reshape(-1), past_yaw, [np.float32(speed)], np.asarray(accel, np.float32).reshape(3),
         command_one_hot(command)]
    ).astype(np.float32)  # fmt: skip


def tcp_state(speed: float, target_point: Sequence[float], command: int) -> np.ndarray:
    """TCP's (9,) measurement vector: speed / 12, target point in the ego frame, 6-way command."""
    tp = np.nan_to_num(np.asarray(target_point, np.float32).reshape(2))
    return np.concatenate([[np.float32(speed) / TCP_SPEED_SCALE], tp, command_one_hot(command)]).astype(np.float32)


def to_ego(points_world: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    """(N, 2) CARLA-world points into the CARLA ego frame of pose (x, y, yaw radians), as ``waypoint_fields`` does."""
    c, s = math.cos(yaw), math.sin(yaw)
    pts = np.asarray(points_world, np.float64).reshape(-1, 2)
    dx, dy = pts[:, 0] - x, pts[:, 1] - y
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=1)


def wrap(angle: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to [−π, π)."""
    return np.mod(np.asarray(angle, np.float64) + math.pi, 2.0 * math.pi) - math.pi


class PoseHistory:
    """The ego's past poses at the agent's tick rate, read back every ``WAYPOINT_DT`` seconds like the clips' history.

    At the start of a route, poses older than the first one repeat the first pose, as ``ClipDataset`` repeats a
    clip's first frame for the history it lacks.
    """

    def __init__(self, tick_dt: float = 0.05) -> None:
        self.ticks_per_step = max(1, round(WAYPOINT_DT / tick_dt))
        self.poses: list[tuple[float, float, float]] = []

    def append(self, x: float, y: float, yaw: float) -> None:
        """Record this tick's pose (CARLA world x, y, yaw in radians)."""
        self.poses.append((float(x), float(y), float(yaw)))
        keep = PAST_STEPS * self.ticks_per_step + 1
        if len(self.poses) > keep:
            del self.poses[: len(self.poses) - keep]

    def past(self) -> tuple[np.ndarray, np.ndarray]:
        """Past (4, 2) positions and (4,) yaws, oldest first, in the current pose's ego frame."""
        x0, y0, yaw0 = self.poses[-1]
        picked = []
        for k in range(PAST_STEPS, 0, -1):
            index = max(0, len(self.poses) - 1 - k * self.ticks_per_step)
            picked.append(self.poses[index])
        arr = np.asarray(picked, np.float64)
        return to_ego(arr[:, :2], x0, y0, yaw0).astype(np.float32), wrap(arr[:, 2] - yaw0).astype(np.float32)
