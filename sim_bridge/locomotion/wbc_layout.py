"""The fixed layout of the whole-body QP (:mod:`.wbc`): which dofs, bodies, corners, rows and bounds it uses.

Everything here is resolved once, when the QP is built: the robot's joints split into the floating
base, the torque-driven motors and the position-servo joints; the sole corners the contact forces
act at; the friction pyramids; and, per support (both feet, left only, right only), which QP
variables, constraint rows and bounds that support keeps.
"""

from __future__ import annotations

from dataclasses import dataclass

import daqp
import mujoco
import numpy as np

from robot_models.biped import BipedDescription

FRICTION = 0.6  # pyramid coefficient used by the QP (the floor has 1.0)
CORNERS_PER_FOOT = 4
FORCE_BLOCK = 2 * CORNERS_PER_FOOT * 3  # contact force variables: 3 per sole corner of both feet
N_FRICTION = 4 * 2 * CORNERS_PER_FOOT  # friction pyramid rows: 4 per corner


def robot_dofs(model: mujoco.MjModel, base_body: int) -> np.ndarray:
    """The dofs of the robot whose base is ``base_body``: those of its kinematic tree, in order (not the objects')."""
    root = model.body_rootid[base_body]
    return np.flatnonzero(model.body_rootid[model.dof_bodyid] == root)


def robot_mass(model: mujoco.MjModel, base_body: int) -> float:
    """Mass of the robot whose base is ``base_body``: its kinematic tree's [kg] (not the objects')."""
    # Summed over every body with the others' zeroed: without objects, the very sum of all bodies' masses.
    return float(np.sum(np.where(model.body_rootid == model.body_rootid[base_body], model.body_mass, 0.0)))


def as_index(indices: np.ndarray) -> slice | np.ndarray:
    """A slice when the indices are consecutive (indexing then gives a view, not a copy), else the indices."""
    if len(indices) and np.array_equal(indices, np.arange(indices[0], indices[0] + len(indices))):
        return slice(int(indices[0]), int(indices[0]) + len(indices))
    return indices


def clip(values: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """``values`` clipped in place to ``limits[:, 0]`` .. ``limits[:, 1]``."""
    np.maximum(values, limits[:, 0], out=values)
    return np.minimum(values, limits[:, 1], out=values)


@dataclass(frozen=True)
class JointLayout:
    """The robot's dofs as the QP sees them (addresses are MuJoCo's, each array in joint order).

    Attributes:
        motor_dofs, motor_qpos: the torque-driven joints' dof and qpos addresses, shape (nm,).
        servo_dofs, servo_qpos, servo_actuators: the servo-driven joints' addresses and actuator ids.
        base_dofs: the floating base's six dofs.
        eliminated: base then servo dofs, whose accelerations the equality rows determine, shape (ne,).
        knee_z: the knees' columns in z; knee_qpos, knee_dofs: their addresses.
        torque_limit, servo_limit: (lower, upper) actuator force range of the motor and servo joints [N m], shape (n, 2).
        leg_motor: which motor joints are leg joints, shape (nm,).
    """

    motor_dofs: np.ndarray
    motor_qpos: np.ndarray
    servo_dofs: np.ndarray
    servo_qpos: np.ndarray
    servo_actuators: np.ndarray
    base_dofs: np.ndarray
    eliminated: np.ndarray
    knee_z: np.ndarray
    knee_qpos: np.ndarray
    knee_dofs: np.ndarray
    torque_limit: np.ndarray
    servo_limit: np.ndarray
    leg_motor: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, biped: BipedDescription) -> JointLayout:
        """Resolve the biped's joints in ``model``.

        Raises:
            ValueError: the floating base, motor and servo joints do not cover every dof of the robot
                (the base body's tree) exactly once; other free bodies of the scene (objects) are left out.
        """
        motors, servos = biped.motor_joints, biped.servo_joints
        motor_dofs = np.array([model.joint(j).dofadr[0] for j in motors])
        servo_dofs = np.array([model.joint(j).dofadr[0] for j in servos])
        base = model.body(biped.base_body).id
        base_dof = int(model.jnt_dofadr[model.body_jntadr[base]])
        base_dofs = np.arange(base_dof, base_dof + 6)
        eliminated = np.concatenate([base_dofs, servo_dofs])
        if sorted(np.concatenate([eliminated, motor_dofs]).tolist()) != robot_dofs(model, base).tolist():
            raise ValueError("the floating base, motor and servo joints must cover every dof of the robot exactly once")
        return cls(
            motor_dofs=motor_dofs,
            motor_qpos=np.array([model.joint(j).qposadr[0] for j in motors]),
            servo_dofs=servo_dofs,
            servo_qpos=np.array([model.joint(j).qposadr[0] for j in servos]),
            servo_actuators=np.array([model.actuator(j).id for j in servos]),
            base_dofs=base_dofs,
            eliminated=eliminated,
            knee_z=np.array([FORCE_BLOCK + motors.index(j) for j in biped.knee_joints]),
            knee_qpos=np.array([model.joint(j).qposadr[0] for j in biped.knee_joints]),
            knee_dofs=np.array([model.joint(j).dofadr[0] for j in biped.knee_joints]),
            torque_limit=np.array([model.jnt_actfrcrange[model.joint(j).id] for j in motors]),
            servo_limit=np.array([model.jnt_actfrcrange[model.joint(j).id] for j in servos]),
            leg_motor=np.array([j in biped.leg_joints for j in motors]),
        )


@dataclass(frozen=True)
class FootLayout:
    """The feet: bodies, sole sites and the sole corners the contact forces act at.

    Attributes:
        bodies: (left, right) foot body ids.
        sole_sites: (left, right) sole site ids.
        corners_in_foot: the four sole corners in the foot frame, shape (4, 3) [m].
        corner_offsets: corner minus sole site, foot frame, shape (2, 4, 3) [m].
        skew: maps r (3,) to the flattened cross-product matrix [r]x (9,), shape (3, 9).
    """

    bodies: tuple[int, int]
    sole_sites: tuple[int, int]
    corners_in_foot: np.ndarray
    corner_offsets: np.ndarray
    skew: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, biped: BipedDescription) -> FootLayout:
        """Resolve the biped's feet in ``model``.

        Raises:
            ValueError: a sole site is not on its foot body.
        """
        bodies = (model.body(biped.foot_bodies[0]).id, model.body(biped.foot_bodies[1]).id)
        sites = (model.site(biped.sole_sites[0]).id, model.site(biped.sole_sites[1]).id)
        cx, cy, cz = biped.sole_center_in_foot
        hx, hy, hz = biped.sole_half_size
        corners = np.array([[cx + sx * hx, cy + sy * hy, cz - hz] for sx in (1, -1) for sy in (1, -1)])
        for side in (0, 1):
            if model.site_bodyid[sites[side]] != bodies[side]:
                raise ValueError("each sole site must be on its foot body")
        skew = np.zeros((3, 9))
        for axis, (row, column, sign) in enumerate(((2, 1, 1.0), (0, 2, 1.0), (1, 0, 1.0))):
            skew[axis, 3 * row + column] = sign  # [r]x[row, column] = +r_axis
            skew[axis, 3 * column + row] = -sign
        offsets = np.array([corners - model.site_pos[site] for site in sites])
        return cls(bodies, sites, corners, offsets, skew)


def friction_pyramids(nz: int, nm: int) -> np.ndarray:
    """The inequality rows on z, shape (N_FRICTION + nm, nz): the friction pyramids, then (left zero
    here, filled every step) the motor torques."""
    constraints = np.zeros((N_FRICTION + nm, nz))
    for c in range(2 * CORNERS_PER_FOOT):
        for k, (axis, sign) in enumerate(((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))):
            constraints[4 * c + k, 3 * c + axis] = sign
            constraints[4 * c + k, 3 * c + 2] = -FRICTION
    return constraints


class Support:
    """The QP of one support (both feet, or one foot): which z columns, constraint rows and bounds it
    keeps (flat indices into the full arrays; ``full`` when it keeps everything) and its DAQP model."""

    def __init__(self, keep: np.ndarray, hessian_index: np.ndarray, constraint_index: np.ndarray,
                 bound_index: np.ndarray, full: bool = False) -> None:
        self.full = full
        self.keep = keep
        self.hessian_index = hessian_index
        self.constraint_index = constraint_index
        self.bound_index = bound_index
        self.model = daqp.Model()
        self.ready = False


def supports(nz: int, nm: int) -> list[Support]:
    """One support per case: both feet, left only, right only.

    A foot with no load has zero forces (normal bound 0, hence tangential 0 through its pyramid), so
    in single support the QP drops its 12 forces and 16 pyramid rows: the same optimum, a smaller problem.
    """
    half = 3 * CORNERS_PER_FOOT
    force_columns = (np.arange(0, half), np.arange(half, FORCE_BLOCK))
    pyramid_rows = (np.arange(0, N_FRICTION // 2), np.arange(N_FRICTION // 2, N_FRICTION))
    torque_rows = np.arange(N_FRICTION, N_FRICTION + nm)
    motor_columns = np.arange(FORCE_BLOCK, nz)
    nothing = np.zeros(0, dtype=int)
    result = [Support(nothing, nothing, nothing, nothing, full=True)]
    for side in (0, 1):
        keep = np.concatenate([force_columns[side], motor_columns])
        rows = np.concatenate([pyramid_rows[side], torque_rows])
        result.append(Support(
            keep,
            (keep[:, None] * nz + keep[None, :]).ravel(),
            (rows[:, None] * nz + keep[None, :]).ravel(),
            np.concatenate([keep, nz + rows]),
        ))
    return result
