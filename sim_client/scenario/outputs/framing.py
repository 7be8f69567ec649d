"""Where the video's camera looks: the closest free-camera view that keeps given points in the picture."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

ELEVATION_DEG = -32.0


@dataclass(frozen=True)
class View:
    """A free camera: looks at ``lookat`` [m] from ``distance`` [m], ``azimuth``/``elevation`` [deg] (MuJoCo's convention)."""

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float


def _camera_axes(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The camera's forward, right and up unit vectors (3,) for ``azimuth``/``elevation`` [deg]."""
    az, el = math.radians(azimuth), math.radians(elevation)
    forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def fit_view(points: np.ndarray, fovy_deg: float, aspect: float, azimuth: float, elevation: float = ELEVATION_DEG,
             top_free: float = 0.2) -> View:
    """The closest view from ``azimuth``/``elevation`` that keeps every point (n, 3) [m] in the picture, centred.

    Args:
        aspect: width / height of the picture.
        top_free: fraction of the picture's height kept free at the top (for the overlay).
    """
    forward, right, up = _camera_axes(azimuth, elevation)
    tan_y = math.tan(math.radians(fovy_deg) / 2)
    tan_x = tan_y * aspect
    # allowed window of x / depth and y / depth
    x_max, y_low, y_high = 0.92 * tan_x, -0.92 * tan_y, (1.0 - 2.0 * top_free) * 0.92 * tan_y

    def spread(lookat: np.ndarray, distance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        d = points - (lookat - distance * forward)
        depth = d @ forward
        return depth, (d @ right) / np.maximum(depth, 1e-6), (d @ up) / np.maximum(depth, 1e-6)

    def fits(lookat: np.ndarray, distance: float) -> bool:
        depth, x, y = spread(lookat, distance)
        return bool(np.all(depth >= 0.2) and np.all(np.abs(x) <= x_max) and np.all(y >= y_low) and np.all(y <= y_high))

    def closest(lookat: np.ndarray) -> float:
        near, far = 0.3, 500.0
        if not fits(lookat, far):
            return far
        for _ in range(40):
            middle = (near + far) / 2
            near, far = (near, middle) if fits(lookat, middle) else (middle, far)
        return far

    lookat = (points.min(axis=0) + points.max(axis=0)) / 2
    distance = closest(lookat)
    for _ in range(3):  # centre the points in the window, then come closer
        _, x, y = spread(lookat, distance)
        shift_x = (x.min() + x.max()) / 2
        shift_y = (y.min() + y.max()) / 2 - (y_low + y_high) / 2
        lookat = lookat + distance * (shift_x * right + shift_y * up)
        distance = closest(lookat)
    return View((float(lookat[0]), float(lookat[1]), float(lookat[2])), distance, azimuth, elevation)


def box_corners(center: Sequence[float], half: Sequence[float], z0: float, z1: float, yaw: float = 0.0) -> list[list[float]]:
    """The 8 corners [m] of a box on (x, y) ``center`` with ``half`` sizes, ``z0`` to ``z1`` high, turned by ``yaw`` [rad]."""
    c, s = math.cos(yaw), math.sin(yaw)
    return [[center[0] + c * dx - s * dy, center[1] + s * dx + c * dy, z]
            for dx in (-half[0], half[0]) for dy in (-half[1], half[1]) for z in (z0, z1)]
