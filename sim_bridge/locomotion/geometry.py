"""Floor-plane geometry of walking: feet, footsteps, rotations, support polygons. Pure Python, no MuJoCo.

Frames: every position is in the world frame, on the floor plane (x, y) [m]; yaws are about world z
[rad], counter-clockwise positive.

The walking controller calls these every control step, so the 2-D geometry is plain float math
(a two-element numpy array costs more to make than the arithmetic on it): points are ``(x, y)``
tuples and footsteps are named tuples.
"""

from __future__ import annotations

import enum
import math
from typing import NamedTuple

Point = tuple[float, float]
Vec3 = tuple[float, float, float]


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


def mid_angle(a: float, b: float) -> float:
    """The heading halfway between two headings, along the shorter way round [rad]."""
    return a + 0.5 * wrap_angle(b - a)


def midpoint(a: Point, b: Point) -> Point:
    """The point halfway between two points [m]."""
    return 0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])


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
