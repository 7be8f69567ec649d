"""The DCM preview: the ZMP reference of the gait ahead, and the DCM reference it implies.

The ZMP reference is a chain of linear pieces from now to the horizon (or to standing): the current
phase's piece, then for each planned footstep a double-support piece that moves the ZMP onto the
new sole and a single-support piece that keeps it there. It is refilled every control step, from
this step's measurements (the stance sole and the CoM move every step), into one reused
:class:`ZmpPreview`, whose DCM is integrated backwards in closed form once per step.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sim_bridge.locomotion.command import CommandFilter
from sim_bridge.locomotion.footsteps import FootstepPlanner
from sim_bridge.locomotion.geometry import Footstep, Point, midpoint
from sim_bridge.locomotion.path import PathState
from sim_bridge.locomotion.phases import SETTLE_DURATION, GaitState, Phase
from sim_bridge.locomotion.swing import SwingState

HORIZON = 2.0  # DCM preview horizon [s]


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


def _settle(preview: ZmpPreview, start: Point, end: Point) -> None:
    """The closing pieces: the ZMP moves from ``start`` to ``end`` and stays there [m]."""
    preview.add(SETTLE_DURATION, start, end)
    preview.add(1.0, end, end)


def fill_preview(preview: ZmpPreview, feet: tuple[Footstep, Footstep], gait: GaitState, swing: SwingState,
                 path: PathState, command: CommandFilter, planner: FootstepPlanner) -> None:
    """Refill ``preview`` with the ZMP reference from now to the horizon (or to standing).

    Args:
        feet: the measured soles (left, right).
        gait, swing, path: the walk's state.
        command: the filtered command (its timing and whether the walk is stopping).
        planner: the footsteps after the current one.
    """
    preview.clear()
    t_ss, t_ds = command.timing
    stopping = command.stopping
    stance = feet[gait.stance.index]
    here = (stance.x, stance.y)
    phase = gait.phase
    if phase is Phase.BALANCE:
        preview.add(1.0, gait.zmp_start, gait.zmp_start)
        return
    if phase is Phase.SETTLE:
        mid = midpoint((feet[0].x, feet[0].y), (feet[1].x, feet[1].y))
        preview.add(gait.duration, gait.zmp_start, mid)
        preview.add(1.0, mid, mid)
        return
    if phase is Phase.SHIFT:
        preview.add(gait.duration, gait.zmp_start, here)
        preview.add(t_ss, here, here)
        planned = gait.duration + t_ss  # the pieces' total duration so far [s]
        frame_pos, frame_yaw = path.frame_pos, path.frame_yaw
        support = stance
        closing = False
    elif phase is Phase.SINGLE:
        preview.add(gait.duration, here, here)
        target = swing.target
        landing = (target.x, target.y)
        preview.add(t_ds, here, landing)
        if stopping and swing.closing:
            _settle(preview, landing, midpoint(here, landing))
            return
        preview.add(t_ss, landing, landing)
        planned = gait.duration + t_ds + t_ss
        frame_pos, frame_yaw = planner.frame_of(target), target.yaw
        support = target
        closing = swing.closing
    else:  # DOUBLE
        preview.add(gait.duration, gait.zmp_start, here)
        if stopping and gait.landed_closing:
            _settle(preview, here, midpoint(gait.zmp_start, here))
            return
        preview.add(t_ss, here, here)
        planned = gait.duration + t_ss
        frame_pos, frame_yaw = path.frame_pos, path.frame_yaw
        support = stance
        closing = False
    total = planned - gait.elapsed
    # The first footstep after a measured support (double support, shift) is planned every step;
    # the ones after a planned footstep come from the planner's kept plan.
    measured = phase is not Phase.SINGLE
    count = 0
    while total < HORIZON:
        if stopping and closing:
            break
        if measured and count == 0:
            step = planner.next_footstep_and_frame(frame_pos, frame_yaw, support.side.other, support)
            planner.plan_after(step[2], step[3], step[0])
        else:
            if count == 0:
                planner.plan_after(frame_pos, frame_yaw, support)
            step = planner.planned_step(count - 1 if measured else count)
        footstep, closing, frame_pos, frame_yaw = step
        count += 1
        landing = (footstep.x, footstep.y)
        preview.add(t_ds, (support.x, support.y), landing)
        preview.add(t_ss, landing, landing)
        total += t_ds + t_ss
        support = footstep
    if stopping and closing:
        _, _, _, last_x, last_y = preview.pieces[-1]
        _, before_x, before_y, _, _ = preview.pieces[-2]
        last = (last_x, last_y)
        _settle(preview, last, midpoint(last, (before_x, before_y)))
