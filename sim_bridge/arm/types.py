"""Typed values of the arm layer: configuration, status and IK results (frozen dataclasses)."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from robot_models.validation import check_range
from sim_bridge.errors import InvalidGoalError
from sim_bridge.state import Pose


class ArmMode(enum.IntEnum):
    """What an arm's tracking loop does this control step."""

    IDLE = 0  # the controller writes nothing for this arm
    MOVING = 1  # the reference moves toward the target
    HOLDING = 2  # the reference is fixed; joint targets are held


@dataclass(frozen=True)
class ArmControllerConfig:
    """Tuning of :class:`~sim_bridge.arm.ArmController` (defaults in code, validated).

    Attributes:
        position_tolerance: tool position error for "settled" and "reachable" [m].
        orientation_tolerance: tool orientation error for "settled" and "reachable" [rad].
        max_ik_iterations_per_tick: mink iterations per control step (the budget is split
            between them so joint speeds stay under ``joint_velocity_limit``).
        offline_ik_iterations: iterations of the reachability check and of :func:`solve_ik`.
        frame_position_cost: FrameTask position cost [1/m].
        frame_orientation_cost: FrameTask orientation cost [1/rad].
        posture_cost: PostureTask cost toward the default keyframe [1/rad].
        lm_damping: Levenberg-Marquardt damping of the frame task.
        joint_velocity_limit: mink VelocityLimit on every arm joint [rad/s].
        collision_min_distance: distance kept between arm links and obstacles [m].
        collision_detection_distance: distance at which the collision limit activates [m].
        settle_joint_speed: arm joint speed below which the arm counts as still [rad/s].
        stall_time: time the IK may stay off target after the reference arrived before the
            target is reported unreachable [s].
        default_linear_speed: tool speed used when a goal gives none [m/s].
        default_angular_speed: tool angular speed used when a goal gives none [rad/s].
        gravity_feedforward: add the bias torque (gravity, Coriolis) not already compensated by
            the model's gravcomp to the position target as ``tau / kp``.
    """

    position_tolerance: float = 1e-3
    orientation_tolerance: float = 0.01
    max_ik_iterations_per_tick: int = 3
    offline_ik_iterations: int = 300
    frame_position_cost: float = 1.0
    frame_orientation_cost: float = 1.0
    posture_cost: float = 1e-3
    lm_damping: float = 0.5
    joint_velocity_limit: float = 2.0
    collision_min_distance: float = 0.005
    collision_detection_distance: float = 0.05
    settle_joint_speed: float = 0.02
    stall_time: float = 0.5
    default_linear_speed: float = 0.25
    default_angular_speed: float = 1.0
    gravity_feedforward: bool = True

    def __post_init__(self) -> None:
        positive = ("position_tolerance", "orientation_tolerance", "frame_position_cost", "joint_velocity_limit",
                    "collision_detection_distance", "settle_joint_speed", "stall_time", "default_linear_speed",
                    "default_angular_speed")
        for name in positive:
            check_range(name, getattr(self, name), 0, low_open=True, error=InvalidGoalError)
        for name in ("max_ik_iterations_per_tick", "offline_ik_iterations"):
            check_range(name, getattr(self, name), 1, error=InvalidGoalError)
        for name in ("frame_orientation_cost", "posture_cost", "lm_damping"):
            check_range(name, getattr(self, name), 0, error=InvalidGoalError)


@dataclass(frozen=True)
class GripperStatus:
    """Measured state of a parallel gripper.

    Attributes:
        width: distance between the fingers [m].
        commanded_width: the width last commanded [m].
        force: mean squeeze force of the finger actuators [N] (positive = closing).
        in_contact: whether each finger touches something other than the robot.
        contact_bodies: names of the bodies the fingers touch.
    """

    width: float
    commanded_width: float
    force: float
    in_contact: bool
    contact_bodies: tuple[str, ...]


@dataclass(frozen=True)
class ArmStatus:
    """State of one arm's tracking loop, measured from the simulation.

    Attributes:
        arm: arm name (joint group of the robot spec).
        mode: what the tracking loop does.
        tool_pose: measured tool point pose in the world frame.
        target_pose: goal pose in the world frame (the tool pose when no goal was given).
        reference_pose: where the smooth reference is now, in the world frame.
        position_error: |target - tool| [m].
        orientation_error: rotation angle between target and tool [rad] (0 for position-only goals).
        position_only: whether orientation is ignored.
        progress: fraction of the reference path done, in [0, 1].
        settled: reference arrived, errors within tolerance and the arm is still.
        unreachable: the target cannot be reached (see ``reason``).
        reason: why the target is unreachable ("" otherwise).
        gripper: gripper state, or None for an arm without gripper.
    """

    arm: str
    mode: ArmMode
    tool_pose: Pose
    target_pose: Pose
    reference_pose: Pose
    position_error: float
    orientation_error: float
    position_only: bool
    progress: float
    settled: bool
    unreachable: bool
    reason: str
    gripper: GripperStatus | None


@dataclass(frozen=True)
class IKResult:
    """Answer of :func:`~sim_bridge.arm.solve_ik`.

    Attributes:
        joint_names: the arm's joints, in the order of ``positions``.
        positions: joint positions [rad], shape (n,).
        position_error: remaining tool position error [m].
        orientation_error: remaining tool orientation error [rad] (0 for position-only).
        success: errors within tolerance.
        reason: why it failed ("" on success).
        iterations: IK iterations used.
    """

    joint_names: tuple[str, ...]
    positions: np.ndarray
    position_error: float
    orientation_error: float
    success: bool
    reason: str
    iterations: int
