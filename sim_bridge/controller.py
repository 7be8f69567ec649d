"""The in-loop controller interface: what runs inside the simulation's control step.

A controller is called once per control step, after the physics state is current and before the
physics steps of that control period run, like a ros2_control controller's ``update``. It writes
``data.ctrl`` for the actuators it owns (and may retune their gains). Controllers run in slot order;
a later slot overrides what an earlier slot wrote for the same actuator.
"""

from __future__ import annotations

import enum
from typing import Protocol

import mujoco


class Slot(enum.IntEnum):
    """Where a controller sits in the control step, in execution order."""

    JOINT_SERVO = 0
    LOCOMOTION = 1
    ARM = 2


class Controller(Protocol):
    """A closed loop run at the control rate inside the simulation."""

    @property
    def active(self) -> bool:
        """Whether ``update`` must run this control step (an idle controller costs nothing)."""
        ...

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Forget internal state after the simulation was reset to a keyframe."""
        ...

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        """Compute and write actuator commands for the coming control period.

        Args:
            model: the compiled model (read-only except actuator gains).
            data: the current state, with kinematics and forces computed for this instant.
            control_dt: length of the control period [s].
        """
        ...
