"""CARLA 0.9.15's geometry value types: mutable, with CARLA's constructors, operators, equality and matrices.

Angles are degrees and the frame is CARLA's left-handed one; rotation matrices are the ones of
``b2d_data.format.transform`` (which reproduce ``carla.Transform.get_matrix``), so both agree to the last bit.
Values are Python floats (CARLA stores float32; agents never depend on the rounding).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from b2d_data.format.transform import rotation_matrix

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = ["BoundingBox", "Color", "FloatColor", "GeoLocation", "Location", "Rotation", "Transform", "Vector2D",
           "Vector3D"]  # fmt: skip


def _f(value: Any) -> float:
    """A coordinate as a Python float (numpy scalars and 0-d arrays included)."""
    return float(value)


class Vector3D:
    """carla.Vector3D: a 3-D vector with CARLA's arithmetic and helpers."""

    __slots__ = ("x", "y", "z")
    # CARLA's objects hash by identity although they compare by value; keep that so they can sit in sets and dicts.
    __hash__ = object.__hash__
    # numpy scalars (np.float32 * vector) defer to our __rmul__ instead of wrapping the vector in an object array.
    __array_ufunc__ = None

    def __init__(self, x: Any = 0.0, y: float = 0.0, z: float = 0.0) -> None:
        if isinstance(x, Vector3D):  # the copy constructor Vector3D(rhs) / Location(rhs)
            x, y, z = x.x, x.y, x.z
        self.x = _f(x)
        self.y = _f(y)
        self.z = _f(z)

    def _new(self, x: float, y: float, z: float) -> Vector3D:
        return type(self)(x, y, z)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(x={self.x:.6f}, y={self.y:.6f}, z={self.z:.6f})"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Vector3D):
            return NotImplemented
        return self.x == other.x and self.y == other.y and self.z == other.z

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result

    def __add__(self, other: Vector3D) -> Vector3D:
        if not isinstance(other, Vector3D):
            return NotImplemented
        return self._new(self.x + other.x, self.y + other.y, self.z + other.z)

    def __sub__(self, other: Vector3D) -> Vector3D:
        if not isinstance(other, Vector3D):
            return NotImplemented
        return self._new(self.x - other.x, self.y - other.y, self.z - other.z)

    def __mul__(self, k: float) -> Vector3D:
        if isinstance(k, Vector3D):
            return NotImplemented
        return self._new(self.x * k, self.y * k, self.z * k)

    __rmul__ = __mul__

    def __truediv__(self, k: float) -> Vector3D:
        if isinstance(k, Vector3D):
            return NotImplemented
        return self._new(self.x / k, self.y / k, self.z / k)

    def __rtruediv__(self, k: float) -> Vector3D:
        return self._new(k / self.x, k / self.y, k / self.z)

    def __iadd__(self, other: Vector3D) -> Self:
        self.x, self.y, self.z = self.x + other.x, self.y + other.y, self.z + other.z
        return self

    def __isub__(self, other: Vector3D) -> Self:
        self.x, self.y, self.z = self.x - other.x, self.y - other.y, self.z - other.z
        return self

    def __imul__(self, k: float) -> Self:
        self.x, self.y, self.z = self.x * k, self.y * k, self.z * k
        return self

    def __itruediv__(self, k: float) -> Self:
        self.x, self.y, self.z = self.x / k, self.y / k, self.z / k
        return self

    def __neg__(self) -> Vector3D:
        return self._new(-self.x, -self.y, -self.z)

    def __abs__(self) -> Vector3D:
        return self._new(abs(self.x), abs(self.y), abs(self.z))

    def __reduce__(self):
        return (type(self), (self.x, self.y, self.z))

    def length(self) -> float:
        """Euclidean norm."""
        return math.sqrt(self.x * self.x + self.y * self.y + self.z * self.z)

    def squared_length(self) -> float:
        """Squared norm."""
        return self.x * self.x + self.y * self.y + self.z * self.z

    def make_unit_vector(self) -> Vector3D:
        """The vector scaled to length 1 (the zero vector stays zero instead of turning into NaNs)."""
        n = self.length()
        return self._new(0.0, 0.0, 0.0) if n == 0.0 else self._new(self.x / n, self.y / n, self.z / n)

    def dot(self, other: Vector3D) -> float:
        """Dot product."""
        return self.x * other.x + self.y * other.y + self.z * other.z

    def dot_2d(self, other: Vector3D) -> float:
        """Dot product of the x, y parts."""
        return self.x * other.x + self.y * other.y

    def cross(self, other: Vector3D) -> Vector3D:
        """Cross product."""
        return self._new(
            self.y * other.z - self.z * other.y,
            self.z * other.x - self.x * other.z,
            self.x * other.y - self.y * other.x,
        )

    def distance(self, other: Vector3D) -> float:
        """3-D distance to another point."""
        return math.sqrt(self.distance_squared(other))

    def distance_squared(self, other: Vector3D) -> float:
        """Squared 3-D distance."""
        return (self.x - other.x) ** 2 + (self.y - other.y) ** 2 + (self.z - other.z) ** 2

    def distance_2d(self, other: Vector3D) -> float:
        """Distance in the x, y plane."""
        return math.hypot(self.x - other.x, self.y - other.y)

    def distance_squared_2d(self, other: Vector3D) -> float:
        """Squared distance in the x, y plane."""
        return (self.x - other.x) ** 2 + (self.y - other.y) ** 2

    def get_vector_angle(self, other: Vector3D) -> float:
        """Angle between the two vectors in radians (0 when either is the zero vector)."""
        n = self.length() * other.length()
        if n == 0.0:
            return 0.0
        return math.acos(max(-1.0, min(1.0, self.dot(other) / n)))


class Location(Vector3D):
    """carla.Location: a point in metres (a Vector3D)."""

    __slots__ = ()


class Vector2D:
    """carla.Vector2D."""

    __slots__ = ("x", "y")
    __hash__ = object.__hash__

    def __init__(self, x: float = 0.0, y: float = 0.0) -> None:
        self.x = _f(x)
        self.y = _f(y)

    def __repr__(self) -> str:
        return f"Vector2D(x={self.x:.6f}, y={self.y:.6f})"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Vector2D):
            return NotImplemented
        return self.x == other.x and self.y == other.y

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result

    def __add__(self, other: Vector2D) -> Vector2D:
        return Vector2D(self.x + other.x, self.y + other.y)

    def __sub__(self, other: Vector2D) -> Vector2D:
        return Vector2D(self.x - other.x, self.y - other.y)

    def __mul__(self, k: float) -> Vector2D:
        return Vector2D(self.x * k, self.y * k)

    __rmul__ = __mul__

    def __truediv__(self, k: float) -> Vector2D:
        return Vector2D(self.x / k, self.y / k)

    def __reduce__(self):
        return (Vector2D, (self.x, self.y))

    def length(self) -> float:
        """Euclidean norm."""
        return math.hypot(self.x, self.y)

    def squared_length(self) -> float:
        """Squared norm."""
        return self.x * self.x + self.y * self.y

    def make_unit_vector(self) -> Vector2D:
        """The vector scaled to length 1 (zero stays zero)."""
        n = self.length()
        return Vector2D(0.0, 0.0) if n == 0.0 else Vector2D(self.x / n, self.y / n)


class Rotation:
    """carla.Rotation(pitch, yaw, roll) in degrees."""

    __slots__ = ("pitch", "roll", "yaw")
    __hash__ = object.__hash__

    def __init__(self, pitch: float = 0.0, yaw: float = 0.0, roll: float = 0.0) -> None:
        self.pitch = _f(pitch)
        self.yaw = _f(yaw)
        self.roll = _f(roll)

    def __repr__(self) -> str:
        return f"Rotation(pitch={self.pitch:.6f}, yaw={self.yaw:.6f}, roll={self.roll:.6f})"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Rotation):
            return NotImplemented
        return self.pitch == other.pitch and self.yaw == other.yaw and self.roll == other.roll

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result

    def __reduce__(self):
        return (Rotation, (self.pitch, self.yaw, self.roll))

    def _matrix(self) -> np.ndarray:
        return rotation_matrix(self.pitch, self.yaw, self.roll)

    def _rotate(self, v: Vector3D) -> tuple[float, float, float]:
        r = self._matrix() @ np.array([v.x, v.y, v.z])
        return float(r[0]), float(r[1]), float(r[2])

    def get_forward_vector(self) -> Vector3D:
        """Unit x axis of the rotated frame."""
        cp, sp = math.cos(math.radians(self.pitch)), math.sin(math.radians(self.pitch))
        cy, sy = math.cos(math.radians(self.yaw)), math.sin(math.radians(self.yaw))
        return Vector3D(cp * cy, cp * sy, sp)

    def get_right_vector(self) -> Vector3D:
        """Unit y axis of the rotated frame."""
        m = self._matrix()
        return Vector3D(m[0, 1], m[1, 1], m[2, 1])

    def get_up_vector(self) -> Vector3D:
        """Unit z axis of the rotated frame."""
        m = self._matrix()
        return Vector3D(m[0, 2], m[1, 2], m[2, 2])


def _matrix_of(location: Vector3D, rotation: Rotation) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = rotation._matrix()
    m[:3, 3] = (location.x, location.y, location.z)
    return m


class Transform:
    """carla.Transform(location, rotation): maps points from the local frame to the parent frame."""

    __slots__ = ("location", "rotation")
    __hash__ = object.__hash__

    def __init__(self, location: Vector3D | None = None, rotation: Rotation | None = None) -> None:
        # CARLA copies the arguments into the transform: later changes to them do not move it.
        self.location = Location(location) if location is not None else Location()
        self.rotation = Rotation(rotation.pitch, rotation.yaw, rotation.roll) if rotation is not None else Rotation()

    def __repr__(self) -> str:
        return f"Transform({self.location!r}, {self.rotation!r})"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Transform):
            return NotImplemented
        return self.location == other.location and self.rotation == other.rotation

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result

    def __reduce__(self):
        return (Transform, (self.location, self.rotation))

    def _np_matrix(self) -> np.ndarray:
        return _matrix_of(self.location, self.rotation)

    def transform(self, in_point: Any) -> Any:
        """A local point in the parent frame: a new point of the argument's type (the argument is left as it is).

        Given a list of points, each point is transformed in place (CARLA's list overload) and None is returned.
        """
        if isinstance(in_point, list):
            for point in in_point:
                moved = self.transform(point)
                point.x, point.y, point.z = moved.x, moved.y, moved.z
            return None
        r = self.rotation._matrix() @ np.array([in_point.x, in_point.y, in_point.z])
        out_type = type(in_point) if isinstance(in_point, Vector3D) else Location
        return out_type(r[0] + self.location.x, r[1] + self.location.y, r[2] + self.location.z)

    def transform_vector(self, in_vector: Vector3D) -> Vector3D:
        """A local vector in the parent frame (rotation only, no translation), e.g. a velocity."""
        r = self.rotation._matrix() @ np.array([in_vector.x, in_vector.y, in_vector.z])
        out_type = type(in_vector) if isinstance(in_vector, Vector3D) else Vector3D
        return out_type(r[0], r[1], r[2])

    def inverse_transform(self, in_point: Vector3D) -> Vector3D:
        """A parent-frame point in this local frame (the inverse of :meth:`transform`)."""
        d = np.array([in_point.x - self.location.x, in_point.y - self.location.y, in_point.z - self.location.z])
        r = self.rotation._matrix().T @ d
        out_type = type(in_point) if isinstance(in_point, Vector3D) else Location
        return out_type(r[0], r[1], r[2])

    def get_forward_vector(self) -> Vector3D:
        """Unit forward (x) axis in the parent frame."""
        return self.rotation.get_forward_vector()

    def get_right_vector(self) -> Vector3D:
        """Unit right (y) axis in the parent frame."""
        return self.rotation.get_right_vector()

    def get_up_vector(self) -> Vector3D:
        """Unit up (z) axis in the parent frame."""
        return self.rotation.get_up_vector()

    def get_matrix(self) -> list[list[float]]:
        """The 4×4 local → parent matrix as four rows of floats (``b2d_data.format.transform.Transform.matrix``)."""
        return [[float(v) for v in row] for row in self._np_matrix()]

    def get_inverse_matrix(self) -> list[list[float]]:
        """The 4×4 parent → local matrix as four rows of floats."""
        r = self.rotation._matrix()
        m = np.eye(4)
        m[:3, :3] = r.T
        m[:3, 3] = -r.T @ np.array([self.location.x, self.location.y, self.location.z])
        return [[float(v) for v in row] for row in m]


class BoundingBox:
    """carla.BoundingBox(location, extent): centre in the owner's frame, **half** extents, and a rotation."""

    __slots__ = ("extent", "location", "rotation")
    __hash__ = object.__hash__

    def __init__(
        self, location: Vector3D | None = None, extent: Vector3D | None = None, rotation: Rotation | None = None
    ) -> None:
        self.location = Location(location) if location is not None else Location()
        self.extent = Vector3D(extent) if extent is not None else Vector3D()
        self.rotation = Rotation(rotation.pitch, rotation.yaw, rotation.roll) if rotation is not None else Rotation()

    def __repr__(self) -> str:
        e = self.extent
        return (f"BoundingBox({self.location!r}, Extent(x={e.x:.6f}, y={e.y:.6f}, z={e.z:.6f}), "
                f"{self.rotation!r})")  # fmt: skip

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, BoundingBox):
            return NotImplemented
        return self.location == other.location and self.extent == other.extent and self.rotation == other.rotation

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result

    def __reduce__(self):
        return (BoundingBox, (self.location, self.extent, self.rotation))

    def contains(self, point: Vector3D, bbox_transform: Transform) -> bool:
        """Whether a world point lies inside the box placed by ``bbox_transform`` (the box's own rotation is not
        applied, as in CARLA's ``BoundingBox::Contains``)."""
        local = bbox_transform.inverse_transform(point)
        dx, dy, dz = local.x - self.location.x, local.y - self.location.y, local.z - self.location.z
        e = self.extent
        return -e.x <= dx <= e.x and -e.y <= dy <= e.y and -e.z <= dz <= e.z

    def get_local_vertices(self) -> list[Location]:
        """The 8 corners in the owner's frame (x slowest, then y, then z; minus before plus, as CARLA)."""
        e = self.extent
        out = []
        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                for sz in (-1.0, 1.0):
                    rx, ry, rz = self.rotation._rotate(Vector3D(sx * e.x, sy * e.y, sz * e.z))
                    out.append(Location(self.location.x + rx, self.location.y + ry, self.location.z + rz))
        return out

    def get_world_vertices(self, bbox_transform: Transform) -> list[Location]:
        """The 8 corners placed by ``bbox_transform`` (e.g. the owner actor's world transform)."""
        return [bbox_transform.transform(v) for v in self.get_local_vertices()]


class GeoLocation:
    """carla.GeoLocation: latitude and longitude in degrees, altitude in metres."""

    __slots__ = ("altitude", "latitude", "longitude")
    __hash__ = object.__hash__

    def __init__(self, latitude: float = 0.0, longitude: float = 0.0, altitude: float = 0.0) -> None:
        self.latitude = _f(latitude)
        self.longitude = _f(longitude)
        self.altitude = _f(altitude)

    def __repr__(self) -> str:
        return (
            f"GeoLocation(latitude={self.latitude:.6f}, longitude={self.longitude:.6f}, altitude={self.altitude:.6f})"
        )

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GeoLocation):
            return NotImplemented
        return (self.latitude, self.longitude, self.altitude) == (other.latitude, other.longitude, other.altitude)

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result


class Color:
    """carla.Color: 8-bit RGBA."""

    __slots__ = ("a", "b", "g", "r")
    __hash__ = object.__hash__

    def __init__(self, r: int = 0, g: int = 0, b: int = 0, a: int = 255) -> None:
        self.r, self.g, self.b, self.a = int(r), int(g), int(b), int(a)

    def __repr__(self) -> str:
        return f"Color({self.r},{self.g},{self.b},{self.a})"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Color):
            return NotImplemented
        return (self.r, self.g, self.b, self.a) == (other.r, other.g, other.b, other.a)

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result


class FloatColor:
    """carla.FloatColor: RGBA in [0, 1]."""

    __slots__ = ("a", "b", "g", "r")
    __hash__ = object.__hash__

    def __init__(self, r: float = 0.0, g: float = 0.0, b: float = 0.0, a: float = 1.0) -> None:
        self.r, self.g, self.b, self.a = _f(r), _f(g), _f(b), _f(a)

    def __repr__(self) -> str:
        return f"FloatColor({self.r},{self.g},{self.b},{self.a})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FloatColor):
            return NotImplemented
        return (self.r, self.g, self.b, self.a) == (other.r, other.g, other.b, other.a)
