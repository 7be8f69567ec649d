"""The whole-body QP's motion tasks: the accelerations it asks of the pelvis, the torso and the soles.

Eighteen task rows, in this order: pelvis rotation (3), torso rotation (3), left sole (linear 3,
angular 3), right sole (linear 3, angular 3). Each asks for a task-space acceleration J qacc = a
with a = PD toward the reference - J_dot qvel: the pelvis and torso upright at the walking heading,
a stance sole held where it is, a swing sole on its trajectory.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from sim_bridge.locomotion.swing import SwingSample

N_TASK = 18  # task rows: pelvis rotation (3), torso rotation (3), left sole (3 + 3), right sole (3 + 3)
W_STANCE = 1000.0  # cost weight of a stance sole's rows
W_SWING = 10.0  # cost weight of a swing sole's rows
ORIENTATION_KP, ORIENTATION_KD = 150.0, 25.0  # pelvis and torso [1/s^2, 1/s]
SWING_KP, SWING_KD = 400.0, 40.0  # swing sole [1/s^2, 1/s]
STANCE_KD = 10.0  # a stance sole's velocity damping [1/s]


class MotionTasks:
    """Fills the task rows' right-hand sides and the soles' weights every control step.

    Args:
        upper_bodies: (pelvis, torso) body ids.
        sole_sites: (left, right) sole site ids.

    Attributes:
        rhs: the task accelerations a - J_dot qvel [m/s^2, rad/s^2], shape (18,).
    """

    def __init__(self, upper_bodies: tuple[int, int], sole_sites: tuple[int, int]) -> None:
        self._pelvis, self._torso = upper_bodies
        self._upper_bodies = np.array(upper_bodies)
        self._sole_sites = sole_sites
        self.rhs = np.zeros(N_TASK)
        self._error_local = np.zeros(3)
        self._upper_body_error = np.zeros((2, 3, 1))  # local rotation errors of the pelvis and torso [rad]
        self._yaw_quat = np.zeros(4)
        self._site_quat = np.zeros(4)

    def _set_yaw_quat(self, yaw: float) -> None:
        half = 0.5 * yaw
        self._yaw_quat[0] = math.cos(half)
        self._yaw_quat[3] = math.sin(half)

    def fill(self, data: mujoco.MjData, drift_velocity: np.ndarray, heading: float,
             swing: Sequence[SwingSample | None], weight: np.ndarray) -> None:
        """Set :attr:`rhs` and the soles' entries of ``weight``.

        Args:
            drift_velocity: J_dot qvel (18,) then J qvel (18,), stacked.
            heading: the pelvis and torso yaw to hold [rad].
            swing: (left, right) swing reference, None for a stance sole.
            weight: the 18 task rows' cost weights; the soles' rows are written.
        """
        velocity = drift_velocity[N_TASK:]
        rhs = self.rhs
        # Pelvis and torso: PD toward the heading (rotation errors in world = R_body @ local error).
        self._set_yaw_quat(heading)
        errors = self._upper_body_error
        mujoco.mju_subQuat(errors[0, :, 0], self._yaw_quat, data.xquat[self._pelvis])
        mujoco.mju_subQuat(errors[1, :, 0], self._yaw_quat, data.xquat[self._torso])
        orientation = rhs[:6].reshape(2, 3, 1)
        np.matmul(data.xmat[self._upper_bodies].reshape(2, 3, 3), errors, out=orientation)
        rhs[:6] *= ORIENTATION_KP
        rhs[:6] -= ORIENTATION_KD * velocity[:6]
        for side in (0, 1):
            row = 6 + 6 * side
            reference = swing[side]
            if reference is None:
                np.multiply(velocity[row : row + 6], -STANCE_KD, out=rhs[row : row + 6])
                weight[row : row + 6] = W_STANCE
            else:
                site = self._sole_sites[side]
                rhs[row : row + 3] = (
                    reference.acceleration
                    + SWING_KP * (reference.position - data.site_xpos[site])
                    + SWING_KD * (reference.velocity - velocity[row : row + 3])
                )
                mujoco.mju_mat2Quat(self._site_quat, data.site_xmat[site])
                self._set_yaw_quat(reference.yaw)
                mujoco.mju_subQuat(self._error_local, self._yaw_quat, self._site_quat)
                angular = rhs[row + 3 : row + 6]
                np.matmul(data.site_xmat[site].reshape(3, 3), self._error_local, out=angular)
                angular *= SWING_KP
                angular[2] += SWING_KD * reference.yaw_rate
                angular -= SWING_KD * velocity[row + 3 : row + 6]
                weight[row : row + 6] = W_SWING
        rhs -= drift_velocity[:N_TASK]
