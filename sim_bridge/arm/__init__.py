"""Arm control in the simulation core: Cartesian tracking with mink IK, grippers, pick-and-place."""

from sim_bridge.arm.controller import ArmController
from sim_bridge.arm.kinematics import ArmKinematics, solve_ik
from sim_bridge.arm.pick_place import PickPlace, PickPlaceFailure, PickPlaceGoal, PickPlaceProgress, PickPlaceStage
from sim_bridge.arm.types import ArmControllerConfig, ArmMode, ArmStatus, GripperStatus, IKResult

__all__ = [
    "ArmController", "ArmControllerConfig", "ArmKinematics", "ArmMode", "ArmStatus", "GripperStatus", "IKResult",
    "PickPlace", "PickPlaceFailure", "PickPlaceGoal", "PickPlaceProgress", "PickPlaceStage", "solve_ik",
]
