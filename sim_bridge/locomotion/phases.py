"""The gait phase machine: balance, weight shift, single and double support, settle.

    IDLE --(torque on)--> BALANCE --(command)--> SHIFT --> SINGLE <--> DOUBLE
    SHIFT (stopping) or DOUBLE (stopping, feet closed) --> SETTLE --> BALANCE --(still)--> IDLE

A walk starts with a weight shift onto the first stance foot; each SINGLE (swing) phase ends in a
touchdown, each DOUBLE phase in the next lift-off; once the command is zero, the closing step's
double support settles the ZMP between the feet and the robot balances until it is handed back to
the position servos (:mod:`.actuation`). FALLEN ends everything until a reset.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import mujoco

from sim_bridge.locomotion.actuation import HandOver
from sim_bridge.locomotion.command import ZERO, CommandFilter
from sim_bridge.locomotion.estimation import Estimator
from sim_bridge.locomotion.footsteps import FootstepPlanner
from sim_bridge.locomotion.geometry import Footstep, Point, Side, mid_angle, midpoint
from sim_bridge.locomotion.params import GaitParameters
from sim_bridge.locomotion.path import PathState
from sim_bridge.locomotion.swing import SwingState

SHIFT_DURATION = 0.6  # initial weight shift onto the first stance foot [s]
SETTLE_DURATION = 0.6  # final shift of the ZMP to the midpoint between the feet [s]
SWING_FREEZE = 0.85  # fraction of the swing after which its target no longer changes
RUSHED_DOUBLE_SUPPORT = 0.05  # double support after a swing shortened by step-timing adaptation [s]


class Phase(enum.Enum):
    """A phase of the gait (its value is the kind :class:`~sim_bridge.locomotion.types.GaitPhase` reports)."""

    IDLE = "idle"  # position servos hold the stance; the controller does not run
    SHIFT = "shift"
    SINGLE = "single"
    DOUBLE = "double"
    SETTLE = "settle"
    BALANCE = "balance"  # feet together, QP balancing before the hand-over
    FALLEN = "fallen"


@dataclass
class GaitState:
    """Where the gait is.

    Attributes:
        phase: the current phase.
        elapsed: time spent in it [s].
        duration: its planned duration [s].
        time: time since the controller took over [s].
        steps: touchdowns so far.
        stance: the stance foot (in SHIFT, the first one; in DOUBLE, the one that landed last).
        zmp_start: where the ZMP reference of the phase starts, world (x, y) [m].
        landed_closing: the last touchdown closed the feet.
    """

    phase: Phase = Phase.IDLE
    elapsed: float = 0.0
    duration: float = 0.0
    time: float = 0.0
    steps: int = 0
    stance: Side = Side.RIGHT
    zmp_start: Point = (0.0, 0.0)
    landed_closing: bool = False

    def enter(self, phase: Phase, duration: float) -> None:
        """Start ``phase``, planned to last ``duration`` [s]."""
        self.phase = phase
        self.elapsed = 0.0
        self.duration = duration

    @property
    def swing_adjustable(self) -> bool:
        """The swing's target may still change (before :data:`SWING_FREEZE` of its duration)."""
        return self.elapsed < SWING_FREEZE * self.duration


class GaitMachine:
    """The phase transitions of one walk, acting on its state.

    Args:
        gait, swing, path: the walk's state.
        planner: plans the swing targets.
        command: the filtered command (its target starts a walk, its ``stopping`` ends one).
        estimator: reads the soles and the CoM.
        hand_over: its stillness count restarts when a walk starts.
    """

    def __init__(self, gait: GaitState, swing: SwingState, path: PathState, planner: FootstepPlanner,
                 command: CommandFilter, estimator: Estimator, hand_over: HandOver) -> None:
        self._gait = gait
        self._swing = swing
        self._path = path
        self._planner = planner
        self._command = command
        self._estimator = estimator
        self._hand_over = hand_over

    def balance(self, feet: tuple[Footstep, Footstep]) -> None:
        """The QP takes over from the position servos: balance on both feet, the walking frame between them."""
        left, right = feet
        path = self._path
        path.frame_yaw = mid_angle(left.yaw, right.yaw)
        path.frame_pos = midpoint((left.x, left.y), (right.x, right.y))
        self._gait.enter(Phase.BALANCE, 0.0)
        self._gait.zmp_start = path.frame_pos

    def advance(self, data: mujoco.MjData, feet: tuple[Footstep, Footstep], dt: float, params: GaitParameters) -> None:
        """One control step of ``dt`` [s]: advance the phase clock and make the transitions that are due."""
        gait = self._gait
        gait.time += dt
        gait.elapsed += dt
        phase = gait.phase
        if phase is Phase.BALANCE:
            target = self._command.target
            if target != ZERO:
                lead = Side.RIGHT if (target[1] < 0 or (target[1] == 0 and target[2] < 0)) else Side.LEFT
                left, right = feet
                gait.stance = lead.other
                gait.zmp_start = midpoint((left.x, left.y), (right.x, right.y))
                self._path.start(gait.zmp_start, mid_angle(left.yaw, right.yaw))
                self._hand_over.restart()
                gait.enter(Phase.SHIFT, SHIFT_DURATION)
        elif phase is Phase.SHIFT:
            if self._command.stopping:
                # Freeze the ZMP where the shift toward the stance sole has brought it.
                stance = feet[gait.stance.index]
                progress = min(gait.elapsed / max(gait.duration, 1e-6), 1.0)
                sx, sy = gait.zmp_start
                gait.zmp_start = (sx + progress * (stance.x - sx), sy + progress * (stance.y - sy))
                gait.enter(Phase.SETTLE, SETTLE_DURATION)
            elif gait.elapsed >= gait.duration:
                self._path.mark_touchdown(self._estimator.com_xy(data), gait.time)
                self._lift_off(data, feet, params)
        elif phase is Phase.SINGLE:
            if gait.swing_adjustable:
                path = self._path
                self._swing.target, self._swing.closing = self._planner.next_footstep(
                    path.step_frame_pos, path.step_frame_yaw, gait.stance.other, feet[gait.stance.index]
                )
            if gait.elapsed >= gait.duration:
                self._touchdown(data, feet)
        elif phase is Phase.DOUBLE:
            if gait.elapsed >= gait.duration:
                if self._command.stopping and gait.landed_closing:
                    stance = feet[gait.stance.index]
                    gait.zmp_start = (stance.x, stance.y)
                    gait.enter(Phase.SETTLE, SETTLE_DURATION)
                else:
                    self._lift_off(data, feet, params)
        elif phase is Phase.SETTLE and gait.elapsed >= gait.duration:
            gait.enter(Phase.BALANCE, 0.0)
            left, right = feet
            gait.zmp_start = midpoint((left.x, left.y), (right.x, right.y))

    def _lift_off(self, data: mujoco.MjData, feet: tuple[Footstep, Footstep], params: GaitParameters) -> None:
        """Start a swing of the non-stance foot toward its planned footstep."""
        gait, swing = self._gait, self._swing
        side = gait.stance.other
        swing.restart(self._estimator.sole_position(data, side), feet[side.index].yaw, 0.0, params.step_height)
        stance = feet[gait.stance.index]
        path = self._path
        path.keep_line(self._planner.frame_of(stance))
        swing.target, swing.closing = self._planner.next_footstep(path.step_frame_pos, path.step_frame_yaw, side, stance)
        swing.landing = None
        gait.enter(Phase.SINGLE, self._command.timing[0])

    def _touchdown(self, data: mujoco.MjData, feet: tuple[Footstep, Footstep]) -> None:
        """The swing foot lands: it becomes the stance foot, and double support begins."""
        gait, swing, path, command = self._gait, self._swing, self._path, self._command
        target = swing.target
        gait.steps += 1
        moved, turned = self._planner.advance_frame(path.step_frame_pos, path.step_frame_yaw, target.side, command.planned)
        path.follow_step(moved, turned)
        path.frame_yaw = target.yaw
        path.frame_pos = self._planner.frame_of(target)
        gait.landed_closing = swing.closing
        path.integrate_speed(self._estimator.com_xy(data), gait.time, command)
        stance = feet[gait.stance.index]
        gait.zmp_start = (stance.x, stance.y)
        gait.stance = target.side
        # After a swing shortened by step-timing adaptation, hurry on to the next step.
        adapted = swing.origin > 0.0
        gait.enter(Phase.DOUBLE, min(command.timing[1], RUSHED_DOUBLE_SUPPORT) if adapted else command.timing[1])
