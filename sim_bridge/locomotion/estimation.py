"""Estimation and fall detection: what the walk measures of the robot (soles, base velocity, CoM, support)."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from robot_models.biped import BipedDescription
from sim_bridge.locomotion.command import ZERO, Velocity
from sim_bridge.locomotion.geometry import Footstep, Point, Side, Vec3, hull_of, unrotate

SUPPORT_MARGIN = 0.01  # the desired CoP stays this far inside the sole [m]
VELOCITY_FILTER_TIME = 0.5  # time constant of the measured base velocity's low-pass filter [s]
_CORNER_SIGNS = ((1, 1), (-1, 1), (-1, -1), (1, -1))  # counter-clockwise around the sole


class Estimator:
    """Reads the walk's measurements from MuJoCo's data; names resolve to ids once, here.

    Attributes:
        pelvis: id of the base body, whose subtree CoM is the robot's CoM.
        sole_sites: (left, right) sole site ids.
        measured: the base velocity (vx, vy [m/s] in its heading frame, yaw rate [rad/s]),
            low-pass filtered by :meth:`filter_velocity`.

    Raises:
        KeyError: a body or site of ``biped`` is not in the model.
    """

    def __init__(self, model: mujoco.MjModel, biped: BipedDescription) -> None:
        self.pelvis = model.body(biped.base_body).id
        base_joint = model.body_jntadr[self.pelvis]
        self._base_qpos = int(model.jnt_qposadr[base_joint])
        self._base_dof = int(model.jnt_dofadr[base_joint])
        self.sole_sites = (model.site(biped.sole_sites[0]).id, model.site(biped.sole_sites[1]).id)
        self._sole_half = (biped.sole_half_size[0] - SUPPORT_MARGIN, biped.sole_half_size[1] - SUPPORT_MARGIN)
        self._fall_height = biped.fall_height_m
        self._fall_up_z = math.cos(biped.fall_tilt_rad)  # the base z axis's world z below which it has fallen
        self._jac_com = np.zeros((3, model.nv))
        self.measured: Velocity = ZERO

    # ----- fall detection ---------------------------------------------------------------
    def has_fallen(self, data: mujoco.MjData) -> bool:
        """True when the base is below the fall height or tilted beyond the fall tilt."""
        height = data.qpos[self._base_qpos + 2]
        up_z = data.xmat[self.pelvis][8]
        return bool(height < self._fall_height or up_z < self._fall_up_z)

    # ----- soles ------------------------------------------------------------------------
    def feet(self, data: mujoco.MjData) -> tuple[Footstep, Footstep]:
        """The measured soles (left, right): centre (x, y) [m] and yaw [rad] in world."""
        left, right = self.sole_sites
        xpos, xmat = data.site_xpos, data.site_xmat
        lx, ly, _ = xpos[left].tolist()
        rx, ry, _ = xpos[right].tolist()
        lm, rm = xmat[left].tolist(), xmat[right].tolist()
        return (
            Footstep(Side.LEFT, lx, ly, math.atan2(lm[3], lm[0])),
            Footstep(Side.RIGHT, rx, ry, math.atan2(rm[3], rm[0])),
        )

    def sole_position(self, data: mujoco.MjData, side: Side) -> Vec3:
        """A sole centre in world (x, y, z) [m]."""
        position = data.site_xpos[self.sole_sites[side.index]]
        return float(position[0]), float(position[1]), float(position[2])

    def sole_yaw(self, data: mujoco.MjData, side: Side) -> float:
        """A sole's yaw in world [rad]."""
        xmat = data.site_xmat[self.sole_sites[side.index]]
        return math.atan2(float(xmat[3]), float(xmat[0]))

    def support_hull(self, data: mujoco.MjData, sides: tuple[int, ...]) -> list[Point]:
        """The support polygon of the soles ``sides`` (0 left, 1 right), counter-clockwise, shrunk by the
        support margin, world frame [m].

        One sole's polygon is its rectangle, already convex and in counter-clockwise order; two soles
        take the convex hull of their eight corners.
        """
        hx, hy = self._sole_half
        points: list[Point] = []
        for side in sides:
            site = self.sole_sites[side]
            px, py, _ = data.site_xpos[site].tolist()
            r00, r01, _, r10, r11, _, _, _, _ = data.site_xmat[site].tolist()
            for sx, sy in _CORNER_SIGNS:
                a, b = sx * hx, sy * hy
                points.append((px + (r00 * a + r01 * b), py + (r10 * a + r11 * b)))
        return points if len(sides) == 1 else hull_of(points)

    # ----- centre of mass ---------------------------------------------------------------
    def com_xy(self, data: mujoco.MjData) -> Point:
        """The CoM (x, y) in world [m]."""
        com = data.subtree_com[self.pelvis]
        return float(com[0]), float(com[1])

    def com_jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The CoM Jacobian, shape (3, nv) [m/rad or 1] (a reused array)."""
        mujoco.mj_jacSubtreeCom(model, data, self._jac_com, self.pelvis)
        return self._jac_com

    def com_height_in_pose(self, model: mujoco.MjModel, keyframe: str, qpos_index: np.ndarray, pose: np.ndarray) -> float:
        """CoM height above the lower sole [m] in a keyframe with the joints at ``qpos_index`` set to ``pose``."""
        data = mujoco.MjData(model)
        key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
        if key >= 0:
            mujoco.mj_resetDataKeyframe(model, data, key)
        data.qpos[qpos_index] = pose
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        sole = min(data.site_xpos[s][2] for s in self.sole_sites)
        return float(data.subtree_com[self.pelvis][2] - sole)

    # ----- base velocity ----------------------------------------------------------------
    def instant_velocity(self, data: mujoco.MjData) -> Velocity:
        """Pelvis (vx, vy) in its heading frame [m/s] and yaw rate [rad/s]."""
        mat = data.xmat[self.pelvis].tolist()
        b = self._base_dof
        qvel = data.qvel[b : b + 6].tolist()
        vx, vy = unrotate(math.atan2(mat[3], mat[0]), qvel[0], qvel[1])
        yaw_rate = mat[6] * qvel[3] + mat[7] * qvel[4] + mat[8] * qvel[5]
        return vx, vy, yaw_rate

    def filter_velocity(self, data: mujoco.MjData, dt: float) -> None:
        """Move :attr:`measured` toward the instant velocity over one control step of ``dt`` [s]."""
        alpha = min(1.0, dt / VELOCITY_FILTER_TIME)
        now = self.instant_velocity(data)
        old = self.measured
        self.measured = (
            old[0] + alpha * (now[0] - old[0]), old[1] + alpha * (now[1] - old[1]), old[2] + alpha * (now[2] - old[2])
        )
