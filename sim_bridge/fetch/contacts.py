"""The contacts of one body in MuJoCo's contact list, found with numpy (the grip measures read them every control step)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import mujoco
import numpy as np

T = TypeVar("T")


def contacts_on(model: mujoco.MjModel, data: mujoco.MjData, body: int, label: Callable[[int], T | None]) -> list[tuple[int, T]]:
    """``(contact index, label(other body))`` of each contact between ``body`` and another body ``label`` names
    (it returns None for the bodies of no interest), in the contact list's order."""
    ncon = data.ncon
    if ncon == 0:
        return []
    bodies = model.geom_bodyid[data.contact.geom[:ncon]]  # (ncon, 2): the two bodies of each contact
    found = []
    for index in np.flatnonzero((bodies == body).any(axis=1)).tolist():
        first, second = int(bodies[index, 0]), int(bodies[index, 1])
        name = label(second if first == body else first)
        if name is not None:
            found.append((index, name))
    return found


def solve_contact_forces(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Solve the constraint forces of the current contacts between ``mj_step1`` and ``mj_step2`` (which solves them
    again with the new controls): the measures inside a control step read them."""
    mujoco.mj_fwdActuation(model, data)
    mujoco.mj_fwdAcceleration(model, data)
    mujoco.mj_fwdConstraint(model, data)


def normal_force(model: mujoco.MjModel, data: mujoco.MjData, index: int, wrench: np.ndarray) -> float:
    """The normal force [N] of contact ``index`` (0 for one in the margin, not active); ``wrench`` (6,) is scratch."""
    if data.contact[index].efc_address < 0:
        return 0.0
    mujoco.mj_contactForce(model, data, index, wrench)
    return float(wrench[0])
