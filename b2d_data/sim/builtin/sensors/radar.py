"""The five radars (``sensor.other.radar``): seeded random rays in a 30°×30° cone, 100 m.

Each tick a radar casts ``points_per_second · Δt`` rays (75 at 20 Hz). Like CARLA, a ray aims at a point drawn
uniformly in radius and angle on an ellipse spanning the FOV at the far range; a hit yields
[depth, altitude, azimuth, velocity]: the hit distance (m), the ray's elevation and azimuth in the radar frame
(rad, azimuth positive towards +y), and the radial velocity of the hit object relative to the radar, negative
when it approaches (the object's velocity minus the radar's, projected on the radar → hit direction).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from b2d_data.format.rig import RadarSpec
from b2d_data.sim.api import FIXED_DELTA_SECONDS
from b2d_data.sim.builtin.sensors.raycast import RayCaster, RayHits


@dataclass(frozen=True)
class RadarPose:
    """A radar at one tick: sensor → world matrix and the radar's own world velocity (m/s)."""

    sensor_to_world: np.ndarray
    velocity: np.ndarray


def radar_ray_directions(spec: RadarSpec, rng: np.random.Generator, count: int) -> np.ndarray:
    """``count`` unit directions in the radar frame, drawn as CARLA draws them."""
    max_rx = math.tan(math.radians(spec.horizontal_fov / 2.0)) * spec.range_m
    max_ry = math.tan(math.radians(spec.vertical_fov / 2.0)) * spec.range_m
    radius = rng.random(count)
    angle = rng.uniform(0.0, 2.0 * math.pi, count)
    end = np.stack(
        [np.full(count, spec.range_m), max_rx * radius * np.cos(angle), max_ry * radius * np.sin(angle)], axis=1
    )
    return end / np.linalg.norm(end, axis=1, keepdims=True)


class Radar:
    """Casts the rays of one :class:`RadarSpec`."""

    def __init__(self, spec: RadarSpec, index: int, seed: int = 0, delta_seconds: float = FIXED_DELTA_SECONDS) -> None:
        self.spec = spec
        self.index = index
        self.seed = seed
        self.rays_per_tick = int(spec.points_per_second * delta_seconds)

    def scan(
        self,
        caster: RayCaster,
        pose: RadarPose,
        frame: int,
        actor_velocities: Mapping[int, np.ndarray],
    ) -> np.ndarray:
        """(N, 4) float32 detections [depth, altitude, azimuth, velocity] of this tick (seeded by seed and frame)."""
        local, world = self.rays(pose, frame)
        origin = np.asarray(pose.sensor_to_world, np.float64)[:3, 3]
        hits = caster.cast(origin[None, :], world, self.spec.range_m)
        return self.detections(local, world, hits, pose, actor_velocities)

    def rays(self, pose: RadarPose, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """This tick's ray directions in the radar frame and in the world (seeded by seed and frame)."""
        rng = np.random.default_rng([self.seed, frame, 1009 + self.index])
        local = radar_ray_directions(self.spec, rng, self.rays_per_tick)
        rot = np.asarray(pose.sensor_to_world, np.float64)[:3, :3]
        return local, local @ rot.T

    def detections(self, local: np.ndarray, world: np.ndarray, hits: RayHits, pose: RadarPose,
                   actor_velocities: Mapping[int, np.ndarray]) -> np.ndarray:  # fmt: skip
        """(N, 4) float32 detections of the hits of :meth:`rays` (cast from the radar's position)."""
        keep = hits.hit
        if not keep.any():
            return np.zeros((0, 4), np.float32)
        d_local = local[keep]
        d_world = world[keep]
        ids = hits.actor_ids[keep]
        target_v = np.zeros((len(ids), 3))
        for k, actor_id in enumerate(ids.tolist()):
            if actor_id:
                v = actor_velocities.get(actor_id)
                if v is not None:
                    target_v[k] = v
        radial = np.einsum("ij,ij->i", target_v - np.asarray(pose.velocity, np.float64), d_world)
        azimuth = np.arctan2(d_local[:, 1], d_local[:, 0])
        altitude = np.arctan2(d_local[:, 2], np.hypot(d_local[:, 0], d_local[:, 1]))
        return np.stack([hits.t[keep], altitude, azimuth, radial], axis=1).astype(np.float32)
