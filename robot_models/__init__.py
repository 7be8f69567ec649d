"""Robot scenes by name: ``load(G1)`` or ``load(PANDA)`` returns a :class:`RobotSpec`.

The package only gathers the public names; the robots are registered in :mod:`robot_models.registry`.
"""

from __future__ import annotations

import os

# One BLAS thread unless the user asks for more, set before numpy's or scipy's OpenBLAS loads: the matrices here
# are small (the whole-body QP's 35 x 35 Cholesky with the G1's hands), and spread over the threads of a busy
# 2-core machine such a solve took 743 us instead of 54 us (the walk's wall/sim went from 0.14 to 0.6-1.2).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from robot_models.registry import (
    G1,
    PANDA,
    ROBOT_NAMES,
    cameras_of,
    check_scene,
    load,
    scenes_of,
    scenes_summary,
    sensors_of,
    walks,
)
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
    "UnknownRobotError", "UnknownSceneError", "WalkingLimits", "cameras_of", "check_scene", "load", "scenes_of", "scenes_summary",
    "sensors_of", "walks",
]
