"""Footstep geometry, swing trajectories and the DCM reference. Pure Python and numpy, no MuJoCo.

Frames: every position is in the world frame, on the floor plane (x, y) [m]; yaws are about world z
[rad], counter-clockwise positive.

The walking controller calls these every control step, so the 2-D geometry is plain float math
(a two-element numpy array costs more to make than the arithmetic on it): points are ``(x, y)``
tuples, footsteps are named tuples, and the ZMP preview is a :class:`ZmpPreview` refilled in place.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

Point = tuple[float, float]


class Side(enum.Enum):
    """A foot. ``sign`` (+1 left, -1 right), ``index`` (0 left, 1 right) and ``other`` are plain attributes."""

    LEFT = 1.0
    RIGHT = -1.0

    sign: float
    index: int
    other: Side

    def __init__(self, value: float) -> None:
        self.sign = float(value)
        self.index = 0 if value > 0 else 1


Side.LEFT.other = Side.RIGHT
Side.RIGHT.other = Side.LEFT


class Footstep(NamedTuple):
    """Where a sole lands: which foot, sole centre (x, y) in world [m], sole heading in world [rad]."""

    side: Side
    x: float
    y: float
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


class DcmReference(NamedTuple):
    """Reference ZMP and divergent component of motion at one instant, world frame (x, y) [m]."""

    zmp_x: float
    zmp_y: float
    dcm_x: float
    dcm_y: float

    @property
    def zmp(self) -> np.ndarray:
        """Reference ZMP, shape (2,) [m]."""
        return np.array([self.zmp_x, self.zmp_y])

    @property
    def dcm(self) -> np.ndarray:
        """Reference DCM, shape (2,) [m]."""
        return np.array([self.dcm_x, self.dcm_y])


class ZmpPreview:
    """The ZMP reference ahead, as linear pieces; the first piece is the current one.

    Each piece is a tuple (duration [s], start x, start y, end x, end y [m]) in one list, cleared and
    refilled every control step.
    """

    __slots__ = ("pieces",)

    def __init__(self) -> None:
        self.pieces: list[tuple[float, float, float, float, float]] = []

    def clear(self) -> None:
        self.pieces.clear()

    def add(self, duration: float, start: Point, end: Point) -> None:
        """Append a piece of ``duration`` [s] from ``start`` to ``end`` [m]."""
        self.pieces.append((duration, start[0], start[1], end[0], end[1]))

    def __len__(self) -> int:
        return len(self.pieces)

    @property
    def total_duration(self) -> float:
        """Sum of the pieces' durations [s]."""
        return sum(piece[0] for piece in self.pieces)

    def dcm_at_first_end(self, omega: float) -> Point:
        """The DCM at the end of the first piece [m].

        Integrates xi_dot = omega (xi - p) backwards in closed form over pieces 1.., with xi = p at
        the end of the last piece (the horizon should be long enough, about 2 s, for that
        assumption to fade).

        Args:
            omega: LIPM natural frequency sqrt(g / z_c) [1/s].
        """
        pieces = self.pieces
        xi_x, xi_y = pieces[-1][3], pieces[-1][4]
        for i in range(len(pieces) - 1, 0, -1):
            duration, sx, sy, ex, ey = pieces[i]
            scale = max(duration, 1e-9)
            lead_x = (ex - sx) / scale / omega
            lead_y = (ey - sy) / scale / omega
            decay = math.exp(-omega * duration)
            xi_x = sx + lead_x + decay * (xi_x - ex - lead_x)
            xi_y = sy + lead_y + decay * (xi_y - ey - lead_y)
        return xi_x, xi_y

    def reference(self, elapsed: float, omega: float, first_end_dcm: Point) -> DcmReference:
        """Reference ZMP and DCM ``elapsed`` seconds into the first piece.

        Args:
            elapsed: time already spent in the first piece [s], clamped to the piece.
            omega: LIPM natural frequency [1/s].
            first_end_dcm: :meth:`dcm_at_first_end` of this preview [m].
        """
        first_duration, sx, sy, ex, ey = self.pieces[0]
        duration = max(first_duration, 1e-9)
        t = min(max(elapsed, 0.0), duration)
        slope_x = (ex - sx) / duration
        slope_y = (ey - sy) / duration
        zmp_x = sx + slope_x * t
        zmp_y = sy + slope_y * t
        decay = math.exp(omega * (t - duration))
        dcm_x = zmp_x + slope_x / omega + decay * (first_end_dcm[0] - ex - slope_x / omega)
        dcm_y = zmp_y + slope_y / omega + decay * (first_end_dcm[1] - ey - slope_y / omega)
        return DcmReference(zmp_x, zmp_y, dcm_x, dcm_y)


def rotation(yaw: float) -> np.ndarray:
    """2-D rotation matrix of a yaw [rad], shape (2, 2)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def rotate(yaw: float, x: float, y: float) -> Point:
    """The vector (x, y) rotated by ``yaw`` [rad]."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x - s * y, s * x + c * y


def unrotate(yaw: float, x: float, y: float) -> Point:
    """The vector (x, y) rotated by ``-yaw`` [rad] (world to a frame of heading ``yaw``)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x + s * y, c * y - s * x


def wrap_angle(angle: float) -> float:
    """Angle wrapped to [-pi, pi) [rad]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def dcm_reference(segments: Sequence[ZmpSegment], elapsed: float, omega: float) -> DcmReference:
    """DCM reference at ``elapsed`` seconds into the first segment (see :class:`ZmpPreview`).

    Args:
        segments: ZMP pieces, the first one being the current one.
        elapsed: time already spent in the first segment [s].
        omega: LIPM natural frequency sqrt(g / z_c) [1/s].
    """
    preview = ZmpPreview()
    for segment in segments:
        preview.add(float(segment.duration), (float(segment.start[0]), float(segment.start[1])),
                    (float(segment.end[0]), float(segment.end[1])))
    return preview.reference(elapsed, omega, preview.dcm_at_first_end(omega))


class SwingSample(NamedTuple):
    """Swing sole reference: position (3,), velocity (3,), acceleration (3,) [m, m/s, m/s^2], yaw [rad], yaw rate [rad/s]."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw: float
    yaw_rate: float


def swing_sample(
    start: Sequence[float], start_yaw: float, target: Footstep, height: float, elapsed: float, duration: float
) -> SwingSample:
    """Swing sole reference: quintic in x, y and yaw, height ``64 h s^3 (1 - s)^3`` (zero speed at both ends).

    Args:
        start: sole position at lift-off (x, y, z) [m].
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
    x0, y0, z0 = start[0], start[1], start[2]
    dx, dy = target.x - x0, target.y - y0
    z = 64.0 * height * s**3 * (1 - s) ** 3
    z_d = 64.0 * height * 3 * s**2 * (1 - s) ** 2 * (1 - 2 * s) / duration
    z_dd = 64.0 * height * 6 * s * (1 - s) * ((1 - 2 * s) ** 2 - s * (1 - s)) / duration**2
    yaw_delta = wrap_angle(target.yaw - start_yaw)
    return SwingSample(
        position=np.array([x0 + dx * blend, y0 + dy * blend, z + z0 * (1 - blend)]),
        velocity=np.array([dx * blend_d, dy * blend_d, z_d - z0 * blend_d]),
        acceleration=np.array([dx * blend_dd, dy * blend_dd, z_dd - z0 * blend_dd]),
        yaw=start_yaw + yaw_delta * blend,
        yaw_rate=yaw_delta * blend_d,
    )


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def hull_of(points: list[Point]) -> list[Point]:
    """Counter-clockwise convex hull of 2-D points (Andrew's monotone chain)."""
    pts = sorted(points)
    lower: list[Point] = []
    for p in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[Point] = []
    for p in reversed(pts):
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def clip_point(x: float, y: float, hull: list[Point]) -> Point:
    """(x, y) itself if it is inside the counter-clockwise convex polygon, else the nearest boundary point."""
    count = len(hull)
    inside = True
    for i in range(count):
        ax, ay = hull[i]
        bx, by = hull[(i + 1) % count]
        if (bx - ax) * (y - ay) - (by - ay) * (x - ax) < 0:
            inside = False
            break
    if inside or count == 0:
        return x, y
    best = (x, y)
    best_distance = math.inf
    for i in range(count):
        ax, ay = hull[i]
        bx, by = hull[(i + 1) % count]
        edge_x, edge_y = bx - ax, by - ay
        t = min(max(((x - ax) * edge_x + (y - ay) * edge_y) / max(edge_x * edge_x + edge_y * edge_y, 1e-12), 0.0), 1.0)
        cx, cy = ax + t * edge_x, ay + t * edge_y
        distance = (x - cx) ** 2 + (y - cy) ** 2
        if distance < best_distance:
            best, best_distance = (cx, cy), distance
    return best


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2-D points, shape (k, 2) (array form of :func:`hull_of`)."""
    return np.array(hull_of([(float(p[0]), float(p[1])) for p in np.asarray(points, dtype=float)]))


def clip_to_polygon(point: np.ndarray, hull: np.ndarray) -> np.ndarray:
    """The point itself if it is inside the counter-clockwise convex polygon, else the nearest boundary point."""
    vertices = [(float(p[0]), float(p[1])) for p in hull]
    return np.array(clip_point(float(point[0]), float(point[1]), vertices))
