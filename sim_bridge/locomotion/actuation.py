"""The actuation hand-over: the leg and waist actuators as position servos (standing) or torque motors (walking).

While walking, the torque-driven joints' actuators become torque motors (gain 1, no bias) and the
QP's torques are written to their controls. When the robot has stood still long enough, their
servo gains come back, with targets that hold the pose it stopped in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

HANDOVER_SPEED = 0.03  # CoM speed below which standing is handed back to the position servos [m/s]
HANDOVER_DELAY = 0.5  # time standing still before the hand-over [s]


@dataclass
class HandOver:
    """How long the CoM has been still [s]; the hand-over is due after :data:`HANDOVER_DELAY`."""

    still_time: float = 0.0

    def track(self, speed: float, dt: float) -> None:
        """Count a control step of ``dt`` [s] at CoM ``speed`` [m/s] (a faster one restarts the count)."""
        self.still_time = self.still_time + dt if speed < HANDOVER_SPEED else 0.0

    def restart(self) -> None:
        """Start counting again (a walk starts)."""
        self.still_time = 0.0

    @property
    def due(self) -> bool:
        """The CoM has been still for :data:`HANDOVER_DELAY`."""
        return not self.still_time < HANDOVER_DELAY


class Actuation:
    """The torque-driven joints' actuators: servo gains saved at construction, switched by the walk.

    Args:
        model: the robot model, with a position actuator named after each joint.
        joints: the joints driven by torque while walking, in the order torques are written.

    Attributes:
        actuators: their actuator ids, shape (n,).
        qpos: their qpos addresses, shape (n,).
        last_torque: the torques written last [N m], shape (n,).
    """

    def __init__(self, model: mujoco.MjModel, joints: Sequence[str]) -> None:
        self.actuators = np.array([model.actuator(j).id for j in joints])
        self.qpos = np.array([model.joint(j).qposadr[0] for j in joints])
        self._saved_gain = model.actuator_gainprm[self.actuators].copy()
        self._saved_bias = model.actuator_biasprm[self.actuators].copy()
        self.last_torque = np.zeros(len(joints))

    def to_torque(self, model: mujoco.MjModel) -> None:
        """Make the actuators torque motors (ctrl = torque [N m])."""
        ids = self.actuators
        model.actuator_gainprm[ids] = 0.0
        model.actuator_gainprm[ids, 0] = 1.0
        model.actuator_biasprm[ids] = 0.0

    def write_torque(self, data: mujoco.MjData, torque: np.ndarray) -> None:
        """Command ``torque`` [N m], shape (n,)."""
        self.last_torque = torque
        data.ctrl[self.actuators] = torque

    def restore_servos(self, model: mujoco.MjModel) -> None:
        """Give the actuators their servo gains back (their ctrl is a position target again)."""
        model.actuator_gainprm[self.actuators] = self._saved_gain
        model.actuator_biasprm[self.actuators] = self._saved_bias

    def hold_current_pose(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Servos on, targets at the joints' current positions."""
        self.restore_servos(model)
        data.ctrl[self.actuators] = data.qpos[self.qpos]

    def hand_over(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Servos on, targets offset from the current positions by last torque / kp: the servos start by
        pushing as the QP did, so the pose does not sag."""
        kp = self._saved_gain[:, 0]
        self.restore_servos(model)
        data.ctrl[self.actuators] = data.qpos[self.qpos] + self.last_torque / kp
