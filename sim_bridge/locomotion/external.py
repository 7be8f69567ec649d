"""Movable objects' contact forces on a biped (what it holds), as generalized forces for the whole-body QP.

A carried object presses on the hands: forces the QP's equations of motion
(M qacc + h = tau + J_c^T f, with f the sole forces it chooses) do not contain, which the balance would
meet only as an error to correct. Measured from the last physics step, each such contact's force on the
robot enters as a known generalized force J^T f_ext (``mj_applyFT`` at the contact point), so the legs
carry an object's weight and the squeeze that holds it as they carry the robot's own. Contacts between two
parts of the robot cancel and are left out; those of the feet are the QP's own variables; those with the
static scene (a table the body brushes) are left out too.
"""

from __future__ import annotations

import mujoco
import numpy as np


class ExternalContacts:
    """The generalized force of movable objects' contacts on a robot, except at its feet.

    Args:
        model: the model.
        base_body: the robot's floating base body id (its kinematic tree is the robot).
        foot_bodies: the bodies whose contacts the QP models (their forces are its variables).

    Attributes:
        generalized: the last result, shape (nv,) [N, N m in the dofs' units].
        count: contacts counted in the last :meth:`update`.
    """

    def __init__(self, model: mujoco.MjModel, base_body: int, foot_bodies: tuple[int, ...]) -> None:
        robot_body = model.body_rootid == model.body_rootid[base_body]
        foot = np.zeros(model.nbody, dtype=bool)
        foot[list(foot_bodies)] = True
        self._robot = robot_body[model.geom_bodyid]  # per geom: part of the robot
        self._measured = self._robot & ~foot[model.geom_bodyid]  # per geom: a robot geom whose contacts are measured
        # per geom: a movable object's (its body not fixed to the world), what the robot holds. The static scene (a
        # table a thigh brushes) is left out: feeding its push in a physics step late was not tried.
        self._movable = ~self._robot & (model.body_rootid[model.geom_bodyid] != 0)
        self.generalized = np.zeros(model.nv)
        self._force = np.zeros(6)
        self.count = 0

    def update(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray | None:
        """J^T f summed over the contacts between a measured robot geom and a movable object [generalized force];
        None when there are none (the common case: nothing is computed)."""
        self.count = 0
        n = data.ncon
        if n == 0:
            return None
        geoms = data.contact.geom[:n]
        if not self._measured[geoms].any():  # the common case: only the soles (and the scene) touch anything
            return None
        first, second = geoms[:, 0], geoms[:, 1]
        on_second = self._measured[second] & self._movable[first]  # the robot is geom2: the force is on it
        on_first = self._measured[first] & self._movable[second]
        chosen = np.flatnonzero(on_first | on_second)
        if len(chosen) == 0:
            return None
        out = self.generalized
        out[:] = 0.0
        force = self._force
        for i in chosen.tolist():
            mujoco.mj_contactForce(model, data, i, force)  # in the contact frame, on geom2 from geom1
            frame = data.contact.frame[i].reshape(3, 3)  # rows: normal (geom1 -> geom2), tangents
            linear, angular = frame.T @ force[:3], frame.T @ force[3:]
            geom = int(second[i])
            if not on_second[i]:
                linear, angular, geom = -linear, -angular, int(first[i])
            mujoco.mj_applyFT(model, data, linear, angular, data.contact.pos[i], int(model.geom_bodyid[geom]), out)
        self.count = len(chosen)
        return out
