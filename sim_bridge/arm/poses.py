"""Pose maths of the arm layer: rotations as quaternions (w, x, y, z) and matrices, and pose validation."""

from __future__ import annotations

import mujoco
import numpy as np

from sim_bridge.errors import InvalidGoalError
from sim_bridge.state import Pose


def quat_to_mat(quat_wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat_wxyz, dtype=float))
    return mat.reshape(3, 3)


def mat_to_quat(mat: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (3, 3) or (9,)."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.asarray(mat, dtype=float).reshape(9))
    return quat


def rotation_error(quat_a: np.ndarray, quat_b: np.ndarray) -> float:
    """Angle of the rotation between two orientations [rad]."""
    diff = np.empty(3)
    mujoco.mju_subQuat(diff, np.asarray(quat_a, dtype=float), np.asarray(quat_b, dtype=float))
    return float(np.linalg.norm(diff))


def interpolate_quat(quat_from: np.ndarray, quat_to: np.ndarray, fraction: float) -> np.ndarray:
    """Geodesic interpolation (slerp) between two unit quaternions; ``fraction`` in [0, 1]."""
    delta = np.empty(3)
    mujoco.mju_subQuat(delta, np.asarray(quat_to, dtype=float), np.asarray(quat_from, dtype=float))
    quat = np.array(quat_from, dtype=float)
    mujoco.mju_quatIntegrate(quat, delta, float(fraction))
    return quat


def validate_pose(pose: Pose) -> Pose:
    """A copy of ``pose`` with a normalised quaternion.

    Raises:
        InvalidGoalError: wrong shapes, non-finite values or a zero quaternion.
    """
    position = np.asarray(pose.position, dtype=float).reshape(-1)
    quat = np.asarray(pose.orientation_wxyz, dtype=float).reshape(-1)
    if position.shape != (3,) or quat.shape != (4,):
        raise InvalidGoalError(f"a pose needs 3 position and 4 quaternion values, got {position.size} and {quat.size}")
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quat))):
        raise InvalidGoalError("pose values must be finite numbers")
    norm = float(np.linalg.norm(quat))
    if norm < 1e-9:
        raise InvalidGoalError("the orientation quaternion (w, x, y, z) has zero norm")
    return Pose(position.copy(), quat / norm)
