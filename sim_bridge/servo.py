"""Joint position servo: the default in-loop controller of every actuated joint."""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco

from sim_bridge.errors import InvalidGoalError, UnknownNameError


class JointServo:
    """Holds a position target for each actuated joint and writes it to the position actuators.

    Targets are written once when they change; between changes the actuators' own PD holds them,
    so an idle servo costs nothing per step.
    """

    def __init__(self, model: mujoco.MjModel, joint_names: tuple[str, ...]) -> None:
        self._actuator_of: dict[str, int] = {}
        for name in joint_names:
            actuator_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
            if actuator_id < 0:
                raise UnknownNameError(f"no actuator for joint {name!r}")
            self._actuator_of[name] = actuator_id
        self._pending: dict[int, float] = {}

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self._actuator_of)

    @property
    def active(self) -> bool:
        return bool(self._pending)

    def set_targets(self, targets: Mapping[str, float]) -> None:
        """Queue position targets [rad or m]; all are checked before any is applied.

        Raises:
            UnknownNameError: a name is not an actuated joint.
            InvalidGoalError: a value is not finite.
        """
        unknown = [name for name in targets if name not in self._actuator_of]
        if unknown:
            raise UnknownNameError(
                f"unknown joints {unknown}; actuated joints are: {', '.join(self._actuator_of)}"
            )
        bad = [name for name, value in targets.items() if not math.isfinite(value)]
        if bad:
            raise InvalidGoalError(f"targets of {bad} are not finite numbers")
        for name, value in targets.items():
            self._pending[self._actuator_of[name]] = float(value)

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._pending.clear()

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        for actuator_id, value in self._pending.items():
            data.ctrl[actuator_id] = value
        self._pending.clear()
