"""Stopping: a stop point and a stop heading the planned walking frame never passes."""

from __future__ import annotations

import math

from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion.geometry import Point, unrotate


class StopLimits:
    """Where the walk stops: a world point (x, y) [m] and a world heading [rad], each optional.

    The footstep planner shortens steps and turns with :meth:`clamp_advance` and :meth:`clamp_turn`
    so that the walking frame (the midpoint between the feet) lands on them instead of passing them.
    """

    def __init__(self) -> None:
        self.point: Point | None = None
        self.heading: float | None = None

    def clear(self) -> None:
        """Lift both limits."""
        self.point = None
        self.heading = None

    def set_point(self, point: Point | None) -> None:
        """Set the stop point (world x, y [m]); None lifts it."""
        self.point = None if point is None else (float(point[0]), float(point[1]))

    def set_heading(self, heading: float | None) -> None:
        """Set the stop heading (world yaw [rad], not wrapped); None lifts it.

        Raises:
            InvalidGoalError: the heading is not finite.
        """
        if heading is not None and not math.isfinite(heading):
            raise InvalidGoalError(f"stop heading {heading!r} must be a finite number")
        self.heading = None if heading is None else float(heading)

    def heading_remaining(self, frame_yaw: float) -> float:
        """Signed turn [rad] from a walking frame's heading to the stop heading (0 without one)."""
        if self.heading is None:
            return 0.0
        return self.heading - frame_yaw

    def point_reached(self, frame_pos: Point, tolerance: float) -> bool:
        """True when the walking frame stands within ``tolerance`` [m] of the stop point (or there is none)."""
        if self.point is None:
            return True
        return math.hypot(self.point[0] - frame_pos[0], self.point[1] - frame_pos[1]) <= tolerance

    def point_remaining(self, frame_pos: Point, frame_yaw: float) -> float:
        """Distance [m] along the frame's heading from the walking frame to the stop point (0 without one)."""
        if self.point is None:
            return 0.0
        forward, _ = unrotate(frame_yaw, self.point[0] - frame_pos[0], self.point[1] - frame_pos[1])
        return forward

    def clamp_advance(self, frame_pos: Point, frame_yaw: float, forward: float, lateral: float) -> Point:
        """A step's (forward, lateral) advance of the walking frame [m], cut so the frame does not pass the stop point."""
        stop = self.point
        if stop is not None and (forward != 0.0 or lateral != 0.0):
            ahead, left = unrotate(frame_yaw, stop[0] - frame_pos[0], stop[1] - frame_pos[1])
            forward = min(forward, max(ahead, 0.0)) if forward > 0.0 else max(forward, min(ahead, 0.0))
            lateral = min(lateral, max(left, 0.0)) if lateral > 0.0 else max(lateral, min(left, 0.0))
        return forward, lateral

    def clamp_turn(self, frame_yaw: float, turn: float) -> float:
        """A step's turn [rad], cut so the walking frame's heading does not pass the stop heading."""
        heading = self.heading
        if heading is not None and turn != 0.0:
            remaining = heading - frame_yaw
            turn = min(turn, max(remaining, 0.0)) if turn > 0.0 else max(turn, min(remaining, 0.0))
        return turn
