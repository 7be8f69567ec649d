"""Command filtering: the velocity command, clamped to the gait's limits, and the walking velocity that follows it."""

from __future__ import annotations

import math

from robot_models.biped import StepLimits
from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion.params import GaitParameters

Velocity = tuple[float, float, float]  # (vx [m/s], vy [m/s], wz [rad/s]) in the heading frame
ZERO: Velocity = (0.0, 0.0, 0.0)


class CommandFilter:
    """The commanded velocity (``target``) and the walking velocity the gait plans with (``velocity``).

    ``velocity`` moves toward ``target`` at the gait's acceleration limits, one control step at a
    time; ``timing`` is the gait's (single, double support) durations [s] at that velocity, and
    ``stopping`` holds once both are zero (the feet close and the robot stands).

    Args:
        steps: the robot's step limits, which bound the command (:meth:`GaitParameters.speed_limits`).
        params: the gait parameters at the start.
    """

    def __init__(self, steps: StepLimits, params: GaitParameters) -> None:
        self._steps = steps
        self.target: Velocity = ZERO
        self.velocity: Velocity = ZERO
        self.timing = params.timing(0.0)
        self.stopping = False

    def set_target(self, vx: float, vy: float, wz: float, params: GaitParameters) -> None:
        """Command a velocity [m/s, m/s, rad/s], clamped to ``params``' speed limits for this robot.

        Raises:
            InvalidGoalError: a component is not a finite number.
        """
        values = (vx, vy, wz)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            raise InvalidGoalError(f"velocity command {values} must be three finite numbers")
        forward, backward, lateral, yaw_rate = params.speed_limits(self._steps)
        self.target = (
            min(max(float(vx), -backward), forward),
            min(max(float(vy), -lateral), lateral),
            min(max(float(wz), -yaw_rate), yaw_rate),
        )

    def restart(self, params: GaitParameters) -> None:
        """Forget the walking velocity (the command stays)."""
        self.velocity = ZERO
        self.timing = params.timing(0.0)
        self.stopping = False

    def step(self, dt: float, params: GaitParameters) -> None:
        """Move the walking velocity toward the command at the gait's acceleration limits over ``dt`` [s]."""
        linear, angular = params.max_acceleration * dt, params.max_yaw_acceleration * dt
        (vx, vy, wz), (tx, ty, tz) = self.velocity, self.target
        self.velocity = (
            vx + min(max(tx - vx, -linear), linear),
            vy + min(max(ty - vy, -linear), linear),
            wz + min(max(tz - wz, -angular), angular),
        )
        self.timing = params.timing(self.velocity[0])
        self.stopping = self.target == ZERO and self.velocity == ZERO

    @property
    def planned(self) -> Velocity:
        """The velocity the next footsteps are planned with: zero while stopping."""
        return ZERO if self.stopping else self.velocity
