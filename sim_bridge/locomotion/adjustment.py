"""Step adjustment: where the swing foot lands (step position) and when (step timing), from the DCM error.

Step-position adjustment moves the landing by the predicted end-of-swing DCM error, plus a small
sideways offset that walks the DCM back to the path line. Step-timing adaptation (switched by
:attr:`GaitParameters.timing_adaptation`) shortens a swing whose needed landing is out of reach:
the DCM error grows as exp(omega t) until touchdown, so an earlier touchdown needs a smaller step.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco

from sim_bridge.locomotion.estimation import Estimator
from sim_bridge.locomotion.footsteps import Reach
from sim_bridge.locomotion.geometry import Footstep, Point, rotate, unrotate
from sim_bridge.locomotion.params import GaitParameters
from sim_bridge.locomotion.path import PathState
from sim_bridge.locomotion.phases import GaitState
from sim_bridge.locomotion.swing import SwingState

STEP_ADJUST_DEADBAND = 0.01  # DCM errors up to this do not move the landing [m]
LINE_STEP_GAIN = 0.1  # extra sideways landing offset per m of lateral path error
LINE_STEP_LIMIT = 0.04  # largest such offset [m]
TIMING_TRIGGER = 0.02  # the reach box moves the needed landing more than this [m]
TIMING_MIN_REMAINING = 0.12  # a shortened swing keeps at least this much time to land [s]
TIMING_MIN_SWING = 0.20  # shortest swing [s]
TIMING_MIN_CHANGE = 0.01  # smaller changes of the swing time are not made [s]
TIMING_STEP = 0.85  # each try shortens the remaining swing time by this factor
TIMING_SWING_HEIGHT = 1.0  # a restarted swing rises to at most this fraction of the step height ...
TIMING_MIN_HEIGHT = 0.01  # ... and at least this much [m]


class DcmState(NamedTuple):
    """The DCM quantities of this control step, world (x, y) [m].

    Attributes:
        cop: the desired CoP.
        dcm: the measured DCM.
        planned_dcm: the end-of-swing DCM of the unadjusted plan.
    """

    cop: Point
    dcm: Point
    planned_dcm: Point


class StepAdjuster:
    """Moves and times the swing's landing.

    Args:
        omega: LIPM natural frequency sqrt(g / z_c) [1/s].
        reach: the box the swing sole may land in.
    """

    def __init__(self, omega: float, reach: Reach) -> None:
        self._omega = omega
        self._reach = reach

    def update(self, data: mujoco.MjData, estimator: Estimator, gait: GaitState, swing: SwingState, path: PathState,
               stance: Footstep, state: DcmState, params: GaitParameters) -> Footstep:
        """The swing's landing for this control step (after shortening the swing, if that is needed and allowed).

        Args:
            data: the simulation's data (a shortened swing restarts from where the sole is).
            estimator: reads that sole.
            gait, swing, path: the walk's state; a shortened swing changes ``gait.duration`` and restarts ``swing``.
            stance: the measured stance sole.
            state: this step's CoP and DCM.
            params: the step height and the timing switches.
        """
        if params.timing_adaptation and gait.swing_adjustable:
            chosen = self._shortened_swing(gait, swing.target, path, stance, state, params.timing_crossover)
            if chosen is not None:
                side = stance.side.other
                gait.duration = gait.elapsed + chosen
                start = estimator.sole_position(data, side)
                height = max(TIMING_SWING_HEIGHT * params.step_height - start[2], TIMING_MIN_HEIGHT)
                swing.restart(start, estimator.sole_yaw(data, side), gait.elapsed, height)
        remaining = max(gait.duration - gait.elapsed, 0.0)
        landing, _ = self.landing(swing.target, path, stance, state, remaining, params.timing_crossover)
        return landing

    def landing(self, target: Footstep, path: PathState, stance: Footstep, state: DcmState, remaining: float,
                crossover: bool) -> tuple[Footstep, float]:
        """Step-position adjustment: ``target`` moved by the predicted end-of-step DCM error.

        The error is measured against the unadjusted plan (``state.planned_dcm``, the end-of-swing
        DCM of the preview built from the nominal target), so the adjustment does not cancel itself.

        Args:
            remaining: swing time left [s]; the DCM error grows as exp(omega * remaining).
            crossover: count a needed landing inside the other foot's reach limit as out of reach.

        Returns:
            The landing, and how far [m] the reach box moved it from where the DCM needs it.
        """
        cop, dcm, planned_dcm = state
        growth = math.exp(self._omega * remaining)
        offset_x = cop[0] + growth * (dcm[0] - cop[0]) - planned_dcm[0]
        offset_y = cop[1] + growth * (dcm[1] - cop[1]) - planned_dcm[1]
        size = math.sqrt(offset_x * offset_x + offset_y * offset_y)
        scale = max(size - STEP_ADJUST_DEADBAND, 0.0) / max(size, 1e-9)
        # Landing exactly at the predicted DCM error leaves a sideways error as it is (the DCM walks
        # on, parallel to the path). Landing a little farther out on the side of the error moves
        # the DCM back toward the path line over the next steps.
        away = min(max(LINE_STEP_GAIN * path.line_error, -LINE_STEP_LIMIT), LINE_STEP_LIMIT)
        away_x, away_y = rotate(path.line_yaw, 0.0, away)
        if scale == 0.0 and away == 0.0:
            return target, 0.0
        wanted_x, wanted_y = target.x + offset_x * scale + away_x, target.y + offset_y * scale + away_y
        x, y = self._reach.clip(wanted_x, wanted_y, target.side, stance)
        excess_x, excess_y = unrotate(stance.yaw, wanted_x - x, wanted_y - y)
        if not crossover and excess_y * target.side.sign < 0.0:
            excess_y = 0.0  # a crossover the feet cannot make: landing sooner does not help
        return Footstep(target.side, x, y, target.yaw), math.hypot(excess_x, excess_y)

    def _shortened_swing(self, gait: GaitState, target: Footstep, path: PathState, stance: Footstep, state: DcmState,
                         crossover: bool) -> float | None:
        """Step-timing adaptation: the new remaining swing time [s], or None to keep the swing as it is.

        When the landing the DCM needs is out of reach, the swing is shortened to the longest
        remaining time (in steps of :data:`TIMING_STEP`, at least :data:`TIMING_MIN_REMAINING`)
        whose landing is within reach.
        """
        elapsed = gait.elapsed
        remaining = gait.duration - elapsed
        shortest = max(TIMING_MIN_REMAINING, TIMING_MIN_SWING - elapsed)
        if remaining - shortest < TIMING_MIN_CHANGE:
            return None
        if self.landing(target, path, stance, state, remaining, crossover)[1] <= TIMING_TRIGGER:
            return None
        chosen = remaining
        while chosen > shortest:
            chosen = max(chosen * TIMING_STEP, shortest)
            if self.landing(target, path, stance, state, chosen, crossover)[1] <= TIMING_TRIGGER:
                break
        if remaining - chosen < TIMING_MIN_CHANGE:
            return None
        return chosen
