"""Simulation core: MuJoCo physics, in-loop controllers, pacing. Never imports rclpy."""

import os

# One OpenBLAS thread, set before this package's imports load numpy (see robot_models/__init__.py).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from sim_bridge.controller import Controller, Slot
from sim_bridge.core import Simulation
from sim_bridge.errors import InvalidGoalError, SimError, SimulationFaultError, UnknownNameError, UnreachableError
from sim_bridge.pacing import Pacer
from sim_bridge.state import BaseState, Pose, SimState

__all__ = [
    "BaseState", "Controller", "InvalidGoalError", "Pacer", "Pose", "SimError", "SimState", "Simulation",
    "SimulationFaultError", "Slot", "UnknownNameError", "UnreachableError",
]
