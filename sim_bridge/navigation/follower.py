"""Following a planned path with velocity commands for a walking robot (pure pursuit)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PUSHED_AWAY_M = 0.30  # turning at the goal, the robot follows the path again only once this far from the goal [m]
ALIGN_GAIN_PER_S = 1.0  # turning at the goal, the robot steps back toward it at this gain [1/s] ...
ALIGN_MAX_SPEED_MPS = 0.10  # ... and at most this fast along each axis [m/s]


def wrap_angle(angle: float) -> float:
    """Angle wrapped to [-pi, pi) [rad]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class FollowerCommand:
    """What to command now and how far there is to go.

    Attributes:
        vx: forward speed [m/s] in the robot's heading frame.
        wz: turning rate [rad/s].
        distance_remaining: along the path from the robot's projection to the goal [m].
        cross_track_error: distance from the robot to the path [m].
        phase: "follow", "align" (turning to the goal heading) or "arrived".
        vy: leftward speed [m/s] in the robot's heading frame (only while aligning: stepping back onto the goal).
    """

    vx: float
    wz: float
    distance_remaining: float
    cross_track_error: float
    phase: str
    vy: float = 0.0


class PathFollower:
    """Pure pursuit toward a lookahead point, then a turn in place to the goal heading.

    Once within ``xy_tolerance`` of the goal the robot turns there; swayed or pushed farther than twice
    that while it turns (a held load moves the pelvis), it steps straight or sideways back toward the goal
    as it turns, and follows the path again only when pushed ``PUSHED_AWAY_M`` away. (Pursuing a goal a few centimetres
    behind the robot would turn it in circles around the goal.)

    Args:
        path: world waypoints [m], first = start.
        goal_yaw: heading to end with [rad].
        lookahead: pursuit distance [m].
        xy_tolerance: position tolerance at the goal [m].
        yaw_tolerance: heading tolerance at the goal [rad].
    """

    def __init__(self, path: list[tuple[float, float]], goal_yaw: float, lookahead: float = 0.5,
                 xy_tolerance: float = 0.15, yaw_tolerance: float = 0.15) -> None:
        self.path = np.asarray(path, dtype=float)
        self.goal_yaw = float(goal_yaw)
        self.lookahead = float(lookahead)
        self.xy_tolerance = float(xy_tolerance)
        self.yaw_tolerance = float(yaw_tolerance)
        self._segment = 0
        self._aligning = False
        lengths = np.hypot(*np.diff(self.path, axis=0).T) if len(self.path) > 1 else np.zeros(0)
        self._remaining_after = np.concatenate([np.cumsum(lengths[::-1])[::-1], [0.0]])[1:] if len(lengths) else np.zeros(0)

    def _project(self, p: np.ndarray) -> tuple[int, float, float]:
        """(segment index, fraction along it, distance) of the nearest path point from the current segment on."""
        best = (self._segment, 0.0, math.inf)
        for i in range(self._segment, len(self.path) - 1):
            a, b = self.path[i], self.path[i + 1]
            ab = b - a
            length2 = float(ab @ ab)
            t = 0.0 if length2 == 0.0 else float(np.clip((p - a) @ ab / length2, 0.0, 1.0))
            distance = float(np.linalg.norm(a + t * ab - p))
            if distance < best[2] - 1e-9:
                best = (i, t, distance)
        return best

    def command(self, x: float, y: float, yaw: float, speed: float, max_yaw_rate: float) -> FollowerCommand:
        """The velocity command for the robot at (x, y, yaw) walking at ``speed`` [m/s]."""
        p = np.array([x, y])
        goal = self.path[-1]
        to_goal = float(np.linalg.norm(goal - p))
        if len(self.path) < 2:
            return FollowerCommand(0.0, 0.0, to_goal, 0.0, "arrived")
        segment, t, cross = self._project(p)
        self._segment = segment
        a, b = self.path[segment], self.path[segment + 1]
        remaining = float(np.linalg.norm(b - (a + t * (b - a)))) + float(self._remaining_after[segment])
        if to_goal <= self.xy_tolerance or self._aligning:
            self._aligning = True
            error = wrap_angle(self.goal_yaw - yaw)
            if abs(error) <= self.yaw_tolerance and to_goal <= 2.0 * self.xy_tolerance:
                return FollowerCommand(0.0, 0.0, to_goal, cross, "arrived")
            if to_goal > max(2.0 * self.xy_tolerance, PUSHED_AWAY_M):  # pushed away while turning: walk back
                self._aligning = False
            else:
                wz = float(np.clip(1.5 * error, -max_yaw_rate, max_yaw_rate))
                vx = vy = 0.0
                if to_goal > 2.0 * self.xy_tolerance:  # swayed off while turning: step back toward the goal
                    dx, dy = goal - p
                    c, s = math.cos(yaw), math.sin(yaw)
                    limit = ALIGN_MAX_SPEED_MPS
                    vx = float(np.clip(ALIGN_GAIN_PER_S * (c * dx + s * dy), -limit, limit))
                    vy = float(np.clip(ALIGN_GAIN_PER_S * (-s * dx + c * dy), -limit, limit))
                return FollowerCommand(vx, wz, to_goal, cross, "align", vy)
        target = self._lookahead_point(segment, t)
        heading = math.atan2(target[1] - y, target[0] - x)
        error = wrap_angle(heading - yaw)
        wz = float(np.clip(2.0 * error, -max_yaw_rate, max_yaw_rate))
        slow_down = min(1.0, max(0.25, remaining / 0.6))  # approach the goal gently
        vx = speed * slow_down * max(0.0, math.cos(error)) ** 2 if abs(error) < 0.8 else 0.0
        return FollowerCommand(float(vx), wz, remaining, cross, "follow")

    def _lookahead_point(self, segment: int, t: float) -> np.ndarray:
        a, b = self.path[segment], self.path[segment + 1]
        point = a + t * (b - a)
        left = self.lookahead
        index = segment
        while True:
            end = self.path[index + 1]
            step = float(np.linalg.norm(end - point))
            if step >= left or index + 2 >= len(self.path):
                if step <= 1e-12:
                    return end
                return point + (end - point) * min(1.0, left / step)
            left -= step
            point = end
            index += 1
