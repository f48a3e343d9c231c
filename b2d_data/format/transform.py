"""CARLA-convention poses: Location, Rotation, Transform and their 4×4 matrices.

CARLA's world is left-handed (x east, y south, z up); yaw is in degrees and positive clockwise seen from
above. ``Transform.matrix`` reproduces ``carla.Transform.get_matrix`` (and Bench2Drive's tools/utils.py
``get_matrix``), which is what every ``world2X`` / ``X2ego`` matrix in an annotation is built from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Location:
    """A point or vector in metres (CARLA frame)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0

    def __add__(self, other: Location) -> Location:
        return Location(self.x + other.x, self.y + other.y, self.z + other.z)

    def __sub__(self, other: Location) -> Location:
        return Location(self.x - other.x, self.y - other.y, self.z - other.z)

    def __mul__(self, k: float) -> Location:
        return Location(self.x * k, self.y * k, self.z * k)

    def distance(self, other: Location) -> float:
        """3-D Euclidean distance."""
        return math.sqrt((self.x - other.x) ** 2 + (self.y - other.y) ** 2 + (self.z - other.z) ** 2)

    def distance_2d(self, other: Location) -> float:
        """Horizontal distance (x, y only)."""
        return math.hypot(self.x - other.x, self.y - other.y)

    def length(self) -> float:
        """Euclidean norm."""
        return math.sqrt(self.x * self.x + self.y * self.y + self.z * self.z)

    def dot(self, other: Location) -> float:
        """Dot product."""
        return self.x * other.x + self.y * other.y + self.z * other.z

    def to_list(self) -> list[float]:
        """``[x, y, z]`` as plain floats."""
        return [float(self.x), float(self.y), float(self.z)]

    def to_array(self) -> np.ndarray:
        """``np.array([x, y, z])``."""
        return np.array([self.x, self.y, self.z], dtype=np.float64)

    @classmethod
    def from_array(cls, a: np.ndarray | list[float] | tuple[float, ...]) -> Location:
        """Build from any 2- or 3-sequence (z defaults to 0)."""
        return cls(float(a[0]), float(a[1]), float(a[2]) if len(a) > 2 else 0.0)


#: Velocities and accelerations share Location's arithmetic.
Vector3D = Location


@dataclass(frozen=True)
class Rotation:
    """Euler angles in degrees with CARLA's meaning (pitch about y, yaw about z, roll about x)."""

    pitch: float = 0.0
    yaw: float = 0.0
    roll: float = 0.0

    def to_anno(self) -> list[float]:
        """``[pitch, roll, yaw]``: the order annotations store rotations in."""
        return [float(self.pitch), float(self.roll), float(self.yaw)]

    def forward_vector(self) -> Location:
        """Unit x axis of the rotated frame."""
        cp, sp = math.cos(math.radians(self.pitch)), math.sin(math.radians(self.pitch))
        cy, sy = math.cos(math.radians(self.yaw)), math.sin(math.radians(self.yaw))
        return Location(cp * cy, cp * sy, sp)

    def right_vector(self) -> Location:
        """Unit y axis of the rotated frame."""
        m = rotation_matrix(self.pitch, self.yaw, self.roll)
        return Location(m[0, 1], m[1, 1], m[2, 1])

    def up_vector(self) -> Location:
        """Unit z axis of the rotated frame."""
        m = rotation_matrix(self.pitch, self.yaw, self.roll)
        return Location(m[0, 2], m[1, 2], m[2, 2])


def rotation_matrix(pitch: float, yaw: float, roll: float) -> np.ndarray:
    """3×3 rotation of CARLA's ``Transform.get_matrix`` (angles in degrees)."""
    cy, sy = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    cr, sr = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    cp, sp = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    return np.array(
        [
            [cp * cy, cy * sp * sr - sy * cr, -cy * sp * cr - sy * sr],
            [cp * sy, sy * sp * sr + cy * cr, -sy * sp * cr + cy * sr],
            [sp, -cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True)
class Transform:
    """A pose: ``location`` plus ``rotation``; maps points from the local frame to the parent frame."""

    location: Location = field(default_factory=Location)
    rotation: Rotation = field(default_factory=Rotation)

    def matrix(self) -> np.ndarray:
        """4×4 local → parent matrix, entries as CARLA's ``get_matrix``."""
        m = np.eye(4)
        m[:3, :3] = rotation_matrix(self.rotation.pitch, self.rotation.yaw, self.rotation.roll)
        m[:3, 3] = (self.location.x, self.location.y, self.location.z)
        return m

    def inverse_matrix(self) -> np.ndarray:
        """4×4 parent → local matrix (CARLA's ``get_inverse_matrix``)."""
        r = rotation_matrix(self.rotation.pitch, self.rotation.yaw, self.rotation.roll)
        m = np.eye(4)
        m[:3, :3] = r.T
        m[:3, 3] = -r.T @ np.array([self.location.x, self.location.y, self.location.z])
        return m

    def transform_point(self, p: Location) -> Location:
        """Map one local point to the parent frame."""
        return Location.from_array(self.matrix()[:3, :3] @ p.to_array() + self.location.to_array())

    def transform_points(self, points: np.ndarray) -> np.ndarray:
        """Map an (N, 3) array of local points to the parent frame."""
        m = self.matrix()
        return points @ m[:3, :3].T + m[:3, 3]

    def inverse_transform_points(self, points: np.ndarray) -> np.ndarray:
        """Map an (N, 3) array of parent-frame points into the local frame."""
        m = self.matrix()
        return (points - m[:3, 3]) @ m[:3, :3]

    def get_forward_vector(self) -> Location:
        """Unit forward (x) axis in the parent frame."""
        return self.rotation.forward_vector()

    def get_right_vector(self) -> Location:
        """Unit right (y) axis in the parent frame."""
        return self.rotation.right_vector()

    @classmethod
    def from_matrix(cls, m: np.ndarray) -> Transform:
        """Recover location and CARLA Euler angles from a 4×4 rigid matrix."""
        m = np.asarray(m, dtype=np.float64)
        pitch = math.degrees(math.asin(max(-1.0, min(1.0, m[2, 0]))))
        yaw = math.degrees(math.atan2(m[1, 0], m[0, 0]))
        roll = math.degrees(math.atan2(-m[2, 1], m[2, 2]))
        return cls(Location(m[0, 3], m[1, 3], m[2, 3]), Rotation(pitch=pitch, yaw=yaw, roll=roll))


@dataclass(frozen=True)
class BoundingBox:
    """CARLA bounding box: centre ``location`` in the actor frame and **half** extents."""

    location: Location
    extent: Location
    rotation: Rotation = field(default_factory=Rotation)

    def local_corners(self) -> np.ndarray:
        """8 corners in the actor frame, in Bench2Drive's ``world_cord`` order (x slowest, + before −)."""
        e, c = self.extent, self.location
        signs = np.array(
            [(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)], dtype=np.float64
        )
        return c.to_array() + signs * np.array([e.x, e.y, e.z])

    def world_corners(self, actor_transform: Transform) -> np.ndarray:
        """8 corners in the world frame (the ``world_cord`` field)."""
        return actor_transform.transform_points(self.local_corners())


def wrap_degrees(angle: float) -> float:
    """Wrap an angle to (−180, 180]."""
    wrapped = (angle + 180.0) % 360.0 - 180.0
    return 180.0 if wrapped == -180.0 else wrapped
