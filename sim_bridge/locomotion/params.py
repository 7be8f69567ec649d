"""Gait parameters of the walking controller: one frozen, validated dataclass with documented ranges."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import Final

from robot_models.biped import StepLimits
from robot_models.validation import check_range
from sim_bridge.errors import InvalidGoalError

# Cadence follows speed: up to CADENCE_FROM_SPEED the configured timing holds; from there to
# CADENCE_FULL_SPEED both phase durations shrink linearly to CADENCE_SWING_SCALE and
# CADENCE_DOUBLE_SCALE of their configured values (0.35/0.10 s -> 0.30/0.08 s with the defaults):
# shorter, quicker steps rather than steps so long that the stance knee straightens.
CADENCE_FROM_SPEED = 0.6  # [m/s]
CADENCE_FULL_SPEED = 0.8  # [m/s]
CADENCE_SWING_SCALE = 0.30 / 0.35
CADENCE_DOUBLE_SCALE = 0.08 / 0.10

# name -> (min, max, description). A ROS node turns each entry into a parameter descriptor.
PARAMETER_RANGES: Final[Mapping[str, tuple[float, float, str]]] = MappingProxyType({
    "step_duration": (0.25, 0.80, "single-support (swing) time of one step [s]"),
    "double_support_duration": (0.05, 0.30, "double-support time between two steps [s]"),
    "step_height": (0.02, 0.12, "swing foot apex height above the floor [m]"),
    "max_forward_speed": (0.0, 0.80, "largest forward speed a command is clamped to [m/s]"),
    "max_backward_speed": (0.0, 0.40, "largest backward speed a command is clamped to [m/s]"),
    "max_lateral_speed": (0.0, 0.20, "largest sideways speed a command is clamped to [m/s]"),
    "max_yaw_rate": (0.0, 1.00, "largest turning rate a command is clamped to [rad/s]"),
    "max_acceleration": (0.05, 2.00, "rate at which the walking speed follows a command [m/s^2]"),
    "max_yaw_acceleration": (0.1, 4.00, "rate at which the turning rate follows a command [rad/s^2]"),
})


@dataclass(frozen=True)
class GaitParameters:
    """Timing, swing height and command limits of the gait, and the step-adjustment switches.

    Ranges of the numbers are in :data:`PARAMETER_RANGES`.

    Attributes:
        step_duration: single-support (swing) time of one step [s], in [0.25, 0.80].
        double_support_duration: double-support time between steps [s], in [0.05, 0.30].
        step_height: swing foot apex above the floor [m], in [0.02, 0.12].
        max_forward_speed: forward speed limit [m/s], in [0, 0.80].
        max_backward_speed: backward speed limit (a magnitude) [m/s], in [0, 0.40].
        max_lateral_speed: sideways speed limit (a magnitude) [m/s], in [0, 0.20].
        max_yaw_rate: turning rate limit (a magnitude) [rad/s], in [0, 1.0].
        max_acceleration: how fast the walking speed follows the command [m/s^2], in [0.05, 2.0].
        max_yaw_acceleration: how fast the turning rate follows the command [rad/s^2], in [0.1, 4.0].
        timing_adaptation: shorten a swing whose landing, as the DCM needs it, is out of reach
            (:mod:`sim_bridge.locomotion.adjustment`).
        timing_crossover: count a needed landing inside the other foot's reach limit as out of
            reach too (with ``timing_adaptation``).

    Raises:
        InvalidGoalError: a number is not finite or is outside its range (the message names the
            range), or a switch is not a bool.
    """

    step_duration: float = 0.35
    double_support_duration: float = 0.10
    step_height: float = 0.06
    max_forward_speed: float = 0.80
    max_backward_speed: float = 0.30
    max_lateral_speed: float = 0.20
    max_yaw_rate: float = 0.60
    max_acceleration: float = 0.50
    max_yaw_acceleration: float = 1.00
    timing_adaptation: bool = True
    timing_crossover: bool = True

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name in PARAMETER_RANGES:
                low, high, description = PARAMETER_RANGES[item.name]
                check_range(f"gait parameter {item.name} ({description})", value, low, high, error=InvalidGoalError)
            elif not isinstance(value, bool):
                raise InvalidGoalError(f"gait switch {item.name} must be True or False, got {value!r}")

    def timing(self, speed: float) -> tuple[float, float]:
        """Single- and double-support durations [s] at a walking speed [m/s] (its magnitude counts).

        The configured durations up to :data:`CADENCE_FROM_SPEED`; faster, both shrink linearly
        to their scaled values at :data:`CADENCE_FULL_SPEED` (shorter, quicker steps rather than
        steps longer than the legs reach).
        """
        fraction = min(max((abs(speed) - CADENCE_FROM_SPEED) / (CADENCE_FULL_SPEED - CADENCE_FROM_SPEED), 0.0), 1.0)
        return (
            self.step_duration * (1.0 - fraction * (1.0 - CADENCE_SWING_SCALE)),
            self.double_support_duration * (1.0 - fraction * (1.0 - CADENCE_DOUBLE_SCALE)),
        )

    def speed_limits(self, steps: StepLimits) -> tuple[float, float, float, float]:
        """Effective command limits (forward, backward, lateral [m/s], yaw [rad/s]) for a robot's steps.

        The configured maxima, further reduced so that one step never exceeds what the legs reach
        (``steps``: the longest step forward and backward, the sideways lead step, the turn) and the
        swing foot never has to travel faster than it can (``steps.advance_rate_mps``), with the
        timing :meth:`timing` gives at that speed.
        """
        swing, double = self.timing(self.max_forward_speed)
        period = swing + double
        forward = min(self.max_forward_speed, min(steps.forward_m, steps.advance_rate_mps * swing) / period)
        period = self.step_period
        swing_reach = steps.advance_rate_mps * self.step_duration
        return (
            forward,
            min(self.max_backward_speed, min(steps.backward_m, swing_reach) / period),
            min(self.max_lateral_speed, steps.lateral_m / (2.0 * period)),
            min(self.max_yaw_rate, steps.turn_rad / period),
        )

    @property
    def step_period(self) -> float:
        """Time from one lift-off to the next [s]."""
        return self.step_duration + self.double_support_duration
