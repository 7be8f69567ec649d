"""Typed snapshots of the simulated state, as handed to the ROS adapters."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pose:
    """A pose in the world frame: position [m] and unit quaternion (w, x, y, z)."""

    position: np.ndarray
    orientation_wxyz: np.ndarray


@dataclass(frozen=True)
class BaseState:
    """Ground truth of the floating base (or of the fixed root link).

    Attributes:
        pose: base pose in the world frame.
        linear_velocity_body: velocity of the base origin in the base frame [m/s].
        angular_velocity_body: angular velocity in the base frame [rad/s].
    """

    pose: Pose
    linear_velocity_body: np.ndarray
    angular_velocity_body: np.ndarray


@dataclass(frozen=True)
class SimState:
    """Everything a publisher needs at one instant.

    Attributes:
        time: simulation time [s].
        joint_names: actuated joints, in the order of the arrays below.
        joint_positions: [rad or m], shape (n,).
        joint_velocities: [rad/s or m/s], shape (n,).
        joint_efforts: actuator forces [N m or N], shape (n,).
        base: floating-base ground truth.
    """

    time: float
    joint_names: tuple[str, ...]
    joint_positions: np.ndarray
    joint_velocities: np.ndarray
    joint_efforts: np.ndarray
    base: BaseState
