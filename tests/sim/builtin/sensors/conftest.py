"""Fixtures for the sensor tests: a small rig over flat ground, and the projection Bench2Drive uses."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from b2d_data.format.rig import CameraSpec
from b2d_data.format.weather import WeatherParameters
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.sim.builtin.sensors.synthetic import flat_scene

#: Small camera images and a coarse LiDAR keep the tests fast on two cores.
SMALL = RigConfig(width=160, height=90, top_down_width=160, top_down_height=90, lidar_azimuth_steps=360)


def _project(spec: CameraSpec, cam_to_world: np.ndarray, points: np.ndarray, width: int, height: int):
    """Pixels (N, 2) and OpenCV depth (N,) of world points, as Bench2Drive projects them: K · (y, −z, x)."""
    world2cam = np.linalg.inv(cam_to_world)
    ue = np.asarray(points, float) @ world2cam[:3, :3].T + world2cam[:3, 3]
    cv = np.stack([ue[:, 1], -ue[:, 2], ue[:, 0]], axis=1)
    pix = cv @ spec.intrinsic(width, height).T
    return pix[:, :2] / pix[:, 2:3], cv[:, 2]


def _convex_mask(poly: np.ndarray, width: int, height: int) -> np.ndarray:
    """Pixels whose centre lies inside the convex hull of ``poly`` (GL's coverage rule, ties aside)."""
    hull = poly[ConvexHull(poly).vertices]  # counter-clockwise in (x, y) terms
    ys, xs = np.mgrid[0:height, 0:width]
    px, py = xs + 0.5, ys + 0.5
    inside = np.ones((height, width), bool)
    for i in range(len(hull)):
        (x0, y0), (x1, y1) = hull[i], hull[(i + 1) % len(hull)]
        inside &= (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0) >= 0
    return inside


@pytest.fixture(scope="session")
def geometry() -> SimpleNamespace:
    """Hand-side geometry: ``project`` (K and world→camera) and ``convex_mask`` (pixel-centre coverage)."""
    return SimpleNamespace(project=_project, convex_mask=_convex_mask, small=SMALL)


@pytest.fixture(scope="session")
def noon() -> WeatherParameters:
    """Clear noon."""
    return WeatherParameters(cloudiness=0.0, sun_altitude_angle=60.0)


@pytest.fixture(scope="module")
def small_suite():
    """A 160×90 rig over flat ground (one GL context per test module)."""
    suite = SensorSuite.from_scene(flat_scene(), SMALL, seed=0)
    yield suite
    suite.close()
