"""Path keeping: the walking frame, the path line it keeps to, and the pace (speed) integral.

The walking frame is the midpoint between the feet, with the walk's heading. At each lift-off
the frame the step is planned from is measured from the stance sole, with part of its lateral
error against the path line removed (line keeping). The path line is anchored where the walk
started and moved only by the commanded steps (sideways steps, turns), so a lateral bias per step
cannot accumulate into a drift. At each touchdown the measured CoM advance over the step is
compared with the command, and the integrated error lengthens or shortens the next steps.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim_bridge.locomotion.command import CommandFilter
from sim_bridge.locomotion.geometry import Point, rotate, unrotate

LINE_KEEPING = 0.3  # fraction of the lateral path error removed per step
SPEED_INTEGRAL_GAIN = 0.5  # fraction of a step's distance error (pace error x step period) added to the steps
SPEED_INTEGRAL_LIMIT = 0.05  # [m]


@dataclass
class PathState:
    """The walking frames and the path line of a walk, world frame.

    Attributes:
        frame_pos: the planned walking frame (after the last landing) [m].
        frame_yaw: its heading [rad].
        step_frame_pos: the walking frame the current step is planned from (after line keeping) [m].
        step_frame_yaw: its heading [rad].
        line_pos: a point of the path line the walk keeps to [m].
        line_yaw: the line's heading [rad].
        line_error: lateral distance of the measured walking frame from the line at lift-off [m].
        speed_correction: forward length added to each step by the pace integral [m].
        touchdown_com: CoM (x, y) at the last touchdown [m].
        touchdown_time: gait time of the last touchdown [s].
    """

    frame_pos: Point = (0.0, 0.0)
    frame_yaw: float = 0.0
    step_frame_pos: Point = (0.0, 0.0)
    step_frame_yaw: float = 0.0
    line_pos: Point = (0.0, 0.0)
    line_yaw: float = 0.0
    line_error: float = 0.0
    speed_correction: float = 0.0
    touchdown_com: Point = (0.0, 0.0)
    touchdown_time: float = 0.0

    def start(self, frame_pos: Point, frame_yaw: float) -> None:
        """A walk starts from this walking frame [m, rad]; the path line runs through it along its heading."""
        self.frame_yaw = frame_yaw
        self.frame_pos = frame_pos
        self.line_pos, self.line_yaw = self.frame_pos, self.frame_yaw
        self.speed_correction = 0.0

    def keep_line(self, measured_frame: Point) -> None:
        """At lift-off: the step's walking frame from the measured one [m], pulled part way back to the line."""
        mx, my = measured_frame
        lx, ly = self.line_pos
        forward, lateral = unrotate(self.line_yaw, mx - lx, my - ly)
        dx, dy = rotate(self.line_yaw, forward, 0.0)
        lx, ly = self.line_pos = (lx + dx, ly + dy)  # the foot of the perpendicular from the measured frame
        self.line_error = lateral
        dx, dy = rotate(self.line_yaw, 0.0, lateral * (1.0 - LINE_KEEPING))
        self.step_frame_pos = (lx + dx, ly + dy)
        self.step_frame_yaw = self.frame_yaw

    def follow_step(self, moved: Point, turned: float) -> None:
        """At touchdown: move the line by the step's commanded sideways step and turn.

        Args:
            moved: the step frame advanced by the commanded step [m].
            turned: its heading after the step [rad].
        """
        _, sideways = unrotate(self.step_frame_yaw, moved[0] - self.step_frame_pos[0], moved[1] - self.step_frame_pos[1])
        dx, dy = rotate(self.line_yaw, 0.0, sideways)
        self.line_pos = (self.line_pos[0] + dx, self.line_pos[1] + dy)
        self.line_yaw = turned

    def mark_touchdown(self, com: Point, time: float) -> None:
        """Remember the CoM (x, y) [m] and gait time [s] the pace of the next step is measured from."""
        self.touchdown_com = com
        self.touchdown_time = time

    def integrate_speed(self, com: Point, time: float, command: CommandFilter) -> None:
        """At touchdown: integrate the pace error of the step that ended (CoM (x, y) [m], gait time [s]).

        Not while the speed still ramps toward the command: the lag of a ramp is not an error to
        integrate.
        """
        elapsed = time - self.touchdown_time
        velocity = command.velocity
        if elapsed > 0 and not command.stopping and velocity[0] != 0.0 and velocity[0] == command.target[0]:
            advance, _ = unrotate(self.frame_yaw, com[0] - self.touchdown_com[0], com[1] - self.touchdown_com[1])
            speed = advance / elapsed
            period = command.timing[0] + command.timing[1]
            correction = self.speed_correction + SPEED_INTEGRAL_GAIN * (velocity[0] - speed) * period
            self.speed_correction = min(max(correction, -SPEED_INTEGRAL_LIMIT), SPEED_INTEGRAL_LIMIT)
        elif velocity[0] == 0.0:
            self.speed_correction = 0.0
        self.mark_touchdown(com, time)
