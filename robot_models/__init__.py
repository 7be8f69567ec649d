"""Robot scenes by name: ``load(G1)`` or ``load(PANDA)`` returns a :class:`RobotSpec`.

The package only gathers the public names; the robots are registered in :mod:`robot_models.registry`.
"""

from __future__ import annotations

from robot_models.registry import G1, PANDA, ROBOT_NAMES, cameras_of, check_scene, load, scenes_summary, sensors_of, walks
from robot_models.spec import (
    ArmScene,
    GraspLimits,
    JointLimits,
    Obstacle,
    RobotModelError,
    RobotSpec,
    UnknownRobotError,
    UnknownSceneError,
    WalkingLimits,
)

__all__ = [
    "G1", "PANDA", "ROBOT_NAMES", "ArmScene", "GraspLimits", "JointLimits", "Obstacle", "RobotModelError", "RobotSpec",
    "UnknownRobotError", "UnknownSceneError", "WalkingLimits", "cameras_of", "check_scene", "load", "scenes_summary",
    "sensors_of", "walks",
]
