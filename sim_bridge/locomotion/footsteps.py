"""Footstep planning: where the next feet land, from the walking frame and the filtered command.

Each step advances the walking frame (the midpoint between the feet) by the command over one step
period, cut at the stop point and heading; the swing sole lands half a step width beside the new
frame, within its reach box around the stance sole. Footsteps that follow a planned footstep depend
on nothing measured, so they are kept until the command, the pace correction or the footstep they
follow changes, which at a steady command means once per gait phase.
"""

from __future__ import annotations

from dataclasses import dataclass

from robot_models.biped import BipedDescription
from sim_bridge.locomotion.command import ZERO, CommandFilter, Velocity
from sim_bridge.locomotion.geometry import Footstep, Point, Side, rotate, unrotate
from sim_bridge.locomotion.path import PathState
from sim_bridge.locomotion.stopping import StopLimits

PlannedStep = tuple[Footstep, bool, Point, float]  # landing, closing step?, walking frame after it ([m], [rad])


@dataclass(frozen=True)
class Reach:
    """The box a swing sole may land in around the stance sole, in the stance sole's frame.

    Attributes:
        forward: (min, max) x of the swing sole relative to the stance sole [m].
        outward: (min, max) outward distance between the sole centres [m].
    """

    forward: tuple[float, float]
    outward: tuple[float, float]

    @classmethod
    def of(cls, biped: BipedDescription) -> Reach:
        """A biped's reach box."""
        return cls(biped.reach_forward_m, biped.reach_outward_m)

    def clip(self, x: float, y: float, swing: Side, stance: Footstep) -> Point:
        """The nearest sole position to (x, y) within the swing leg's reach box around the stance sole [m]."""
        relative_forward, left = unrotate(stance.yaw, x - stance.x, y - stance.y)
        forward = min(max(relative_forward, self.forward[0]), self.forward[1])
        outward = min(max(swing.sign * left, self.outward[0]), self.outward[1])
        if forward == relative_forward and outward == swing.sign * left:
            return x, y  # within reach: the position itself (not its rotated round trip)
        dx, dy = rotate(stance.yaw, forward, swing.sign * outward)
        return stance.x + dx, stance.y + dy


class FootstepPlanner:
    """Plans the footsteps of one walk.

    Args:
        half_step_width: lateral distance from the walking frame to each sole centre [m].
        reach: the box a swing sole may land in.
        command: the filtered command the steps follow.
        path: the walk's path state (its pace correction lengthens the steps).
        stop: the stop point and heading the walking frame does not pass.
    """

    def __init__(self, half_step_width: float, reach: Reach, command: CommandFilter, path: PathState,
                 stop: StopLimits) -> None:
        self._half_width = half_step_width
        self._reach = reach
        self._command = command
        self._path = path
        self._stop = stop
        self._plan: list[PlannedStep] = []  # footsteps planned ahead (see plan_after)
        self._plan_base: PlannedStep = (Footstep(Side.LEFT, 0.0, 0.0, 0.0), False, (0.0, 0.0), 0.0)
        self._plan_key: tuple[object, ...] = ()

    def frame_of(self, step: Footstep) -> Point:
        """The walking frame (midpoint between the feet) that puts this sole at its nominal place [m]."""
        dx, dy = rotate(step.yaw, 0.0, step.side.sign * self._half_width)
        return step.x - dx, step.y - dy

    def advance_frame(self, frame_pos: Point, frame_yaw: float, swing: Side, velocity: Velocity) -> tuple[Point, float]:
        """The walking frame one step of ``swing`` later, at ``velocity`` [m, rad]."""
        timing = self._command.timing
        period = timing[0] + timing[1]
        turn = velocity[2] * period
        forward = velocity[0] * period + (self._path.speed_correction if velocity[0] != 0.0 else 0.0)
        lateral = 2.0 * velocity[1] * period if velocity[1] * swing.sign > 0 else 0.0
        forward, lateral = self._stop.clamp_advance(frame_pos, frame_yaw, forward, lateral)
        turn = self._stop.clamp_turn(frame_yaw, turn)
        dx, dy = rotate(frame_yaw + 0.5 * turn, forward, lateral)
        return (frame_pos[0] + dx, frame_pos[1] + dy), frame_yaw + turn

    def place(self, frame_pos: Point, frame_yaw: float, swing: Side, stance: Footstep) -> Footstep:
        """The ``swing`` sole at its nominal place beside a walking frame, within reach of ``stance``."""
        dx, dy = rotate(frame_yaw, 0.0, swing.sign * self._half_width)
        x, y = self._reach.clip(frame_pos[0] + dx, frame_pos[1] + dy, swing, stance)
        return Footstep(swing, x, y, frame_yaw)

    def planned(self) -> list[Footstep]:
        """The footsteps planned ahead so far (world frame), next first; empty while none is."""
        return [step[0] for step in self._plan]

    def next_footstep(self, frame_pos: Point, frame_yaw: float, swing: Side, stance: Footstep) -> tuple[Footstep, bool]:
        """The next landing of ``swing`` and whether it is a closing (zero-velocity) step."""
        footstep, closing, _, _ = self.next_footstep_and_frame(frame_pos, frame_yaw, swing, stance)
        return footstep, closing

    def next_footstep_and_frame(self, frame_pos: Point, frame_yaw: float, swing: Side, stance: Footstep) -> PlannedStep:
        """The next landing of ``swing``, whether it closes the feet, and the walking frame after it."""
        velocity = self._command.planned
        new_pos, new_yaw = self.advance_frame(frame_pos, frame_yaw, swing, velocity)
        return self.place(new_pos, new_yaw, swing, stance), velocity == ZERO, new_pos, new_yaw

    def plan_after(self, frame_pos: Point, frame_yaw: float, support: Footstep) -> None:
        """Plan (on demand, :meth:`planned_step`) the footsteps after the planned ``support``.

        They depend only on that footstep, the walking frame it leaves and the filtered command,
        none of them measured: the steps already planned are kept while these are unchanged.
        """
        command = self._command
        key = (frame_pos, frame_yaw, support, command.stopping, command.velocity, self._path.speed_correction,
               command.timing, self._stop.point)
        if key != self._plan_key:
            self._plan_key = key
            self._plan_base = (support, False, frame_pos, frame_yaw)
            self._plan = []

    def planned_step(self, index: int) -> PlannedStep:
        """The ``index``-th footstep after the support given to :meth:`plan_after`, planned on demand."""
        plan = self._plan
        while len(plan) <= index:
            footstep, _, frame_pos, frame_yaw = plan[-1] if plan else self._plan_base
            plan.append(self.next_footstep_and_frame(frame_pos, frame_yaw, footstep.side.other, footstep))
        return plan[index]
