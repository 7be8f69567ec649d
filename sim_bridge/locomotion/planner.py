"""Footstep geometry, swing trajectories and the DCM reference. Pure numpy, no MuJoCo.

Frames: every position is in the world frame, on the floor plane (x, y) [m]; yaws are about world z
[rad], counter-clockwise positive.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


class Side(enum.Enum):
    LEFT = 1.0
    RIGHT = -1.0

    @property
    def other(self) -> Side:
        return Side.RIGHT if self is Side.LEFT else Side.LEFT

    @property
    def sign(self) -> float:
        """+1 for the left foot, -1 for the right foot."""
        return float(self.value)


@dataclass(frozen=True)
class Footstep:
    """Where a sole lands.

    Attributes:
        side: which foot.
        position: sole centre in world, shape (2,) [m].
        yaw: sole heading in world [rad].
    """

    side: Side
    position: np.ndarray
    yaw: float


@dataclass(frozen=True)
class ZmpSegment:
    """A piece of the ZMP reference that moves linearly from ``start`` to ``end``.

    Attributes:
        duration: length of the segment [s].
        start: ZMP at the start, shape (2,) [m].
        end: ZMP at the end, shape (2,) [m].
    """

    duration: float
    start: np.ndarray
    end: np.ndarray


@dataclass(frozen=True)
class DcmReference:
    """Reference ZMP and divergent component of motion at this instant, world frame [m]."""

    zmp: np.ndarray
    dcm: np.ndarray


def rotation(yaw: float) -> np.ndarray:
    """2-D rotation matrix of a yaw [rad], shape (2, 2)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def wrap_angle(angle: float) -> float:
    """Angle wrapped to [-pi, pi) [rad]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def dcm_reference(segments: Sequence[ZmpSegment], elapsed: float, omega: float) -> DcmReference:
    """DCM reference at ``elapsed`` seconds into the first segment.

    Integrates xi_dot = omega (xi - p) backwards in closed form, with xi = p at the end of the last
    segment (the horizon should be long enough, about 2 s, for that assumption to fade).

    Args:
        segments: ZMP pieces, the first one being the current one.
        elapsed: time already spent in the first segment [s].
        omega: LIPM natural frequency sqrt(g / z_c) [1/s].
    """
    xi_end = np.asarray(segments[-1].end, dtype=float)
    for segment in reversed(segments[1:]):
        slope = (segment.end - segment.start) / max(segment.duration, 1e-9)
        decay = math.exp(-omega * segment.duration)
        xi_end = segment.start + slope / omega + decay * (xi_end - segment.end - slope / omega)
    first = segments[0]
    duration = max(first.duration, 1e-9)
    t = min(max(elapsed, 0.0), duration)
    slope = (first.end - first.start) / duration
    zmp = first.start + slope * t
    dcm = zmp + slope / omega + math.exp(omega * (t - duration)) * (xi_end - first.end - slope / omega)
    return DcmReference(zmp=zmp, dcm=dcm)


@dataclass(frozen=True)
class SwingSample:
    """Swing sole reference: position (3,), velocity (3,), acceleration (3,) [m, m/s, m/s^2], yaw [rad], yaw rate [rad/s]."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw: float
    yaw_rate: float


def swing_sample(
    start: np.ndarray, start_yaw: float, target: Footstep, height: float, elapsed: float, duration: float
) -> SwingSample:
    """Swing sole reference: quintic in x, y and yaw, height ``64 h s^3 (1 - s)^3`` (zero speed at both ends).

    Args:
        start: sole position at lift-off, shape (3,) [m].
        start_yaw: sole yaw at lift-off [rad].
        target: where the sole lands.
        height: apex height above the floor [m].
        elapsed: time since lift-off [s].
        duration: swing time [s].
    """
    s = min(max(elapsed / duration, 0.0), 1.0)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    blend_d = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    blend_dd = (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    delta = np.asarray(target.position) - start[:2]
    z = 64.0 * height * s**3 * (1 - s) ** 3
    z_d = 64.0 * height * 3 * s**2 * (1 - s) ** 2 * (1 - 2 * s) / duration
    z_dd = 64.0 * height * 6 * s * (1 - s) * ((1 - 2 * s) ** 2 - s * (1 - s)) / duration**2
    z0 = start[2] * (1 - blend)
    yaw_delta = wrap_angle(target.yaw - start_yaw)
    return SwingSample(
        position=np.array([*(start[:2] + delta * blend), z + z0]),
        velocity=np.array([*(delta * blend_d), z_d - start[2] * blend_d]),
        acceleration=np.array([*(delta * blend_dd), z_dd - start[2] * blend_dd]),
        yaw=start_yaw + yaw_delta * blend,
        yaw_rate=yaw_delta * blend_d,
    )


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2-D points, shape (k, 2) (Andrew's monotone chain)."""
    pts = sorted(map(tuple, np.asarray(points, dtype=float)))

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def clip_to_polygon(point: np.ndarray, hull: np.ndarray) -> np.ndarray:
    """The point itself if it is inside the counter-clockwise convex polygon, else the nearest boundary point."""
    inside = True
    best = None
    best_distance = math.inf
    count = len(hull)
    for i in range(count):
        a, b = hull[i], hull[(i + 1) % count]
        edge = b - a
        if edge[0] * (point[1] - a[1]) - edge[1] * (point[0] - a[0]) < 0:
            inside = False
        t = float(np.clip(np.dot(point - a, edge) / max(np.dot(edge, edge), 1e-12), 0.0, 1.0))
        candidate = a + t * edge
        distance = float(np.sum((point - candidate) ** 2))
        if distance < best_distance:
            best, best_distance = candidate, distance
    return point.copy() if inside or best is None else best
