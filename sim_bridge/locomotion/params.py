"""Gait parameters of the walking controller: one frozen, validated dataclass with documented ranges."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import Final

from sim_bridge.errors import InvalidGoalError

MAX_STEP_FORWARD = 0.40  # [m]
MAX_STEP_BACKWARD = 0.18  # [m]
MAX_STEP_LATERAL = 0.18  # sideways displacement of the leading foot in one step [m]
MAX_STEP_TURN = 0.45  # [rad]
MAX_ADVANCE_RATE = 1.20  # step advance per second of swing, i.e. half the mean swing-foot speed [m/s]
# Cadence follows speed: up to CADENCE_FROM_SPEED the configured timing holds; from there to
# CADENCE_FULL_SPEED both phase durations shrink linearly to CADENCE_SWING_SCALE and
# CADENCE_DOUBLE_SCALE of their configured values (0.35/0.10 s -> 0.30/0.08 s with the defaults).
# Measured: with the 0.35/0.10 s timing the 0.36 m steps of 0.8 m/s straighten the stance knee and
# fall; at 0.30/0.08 s (0.30 m steps) 0.8 m/s walks with 0.1-0.4 cm/m of drift.
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
    """Timing, swing height and command limits of the gait. Ranges are in :data:`PARAMETER_RANGES`.

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

    Raises:
        InvalidGoalError: a value is not finite or is outside its range (the message names the range).
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

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            low, high, description = PARAMETER_RANGES[item.name]
            is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
            if not is_number or not math.isfinite(value) or not low <= value <= high:
                raise InvalidGoalError(
                    f"gait parameter {item.name}={value!r} is outside the allowed range [{low}, {high}] ({description})"
                )

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

    @property
    def speed_limits(self) -> tuple[float, float, float, float]:
        """Effective command limits (forward, backward, lateral [m/s], yaw [rad/s]).

        The configured maxima, further reduced so that one step never exceeds what the legs reach
        (0.40 m forward, 0.18 m backward, a 0.18 m sideways lead step, 0.45 rad of turn) and the
        swing foot never has to travel faster than it can (1.2 m of advance per second of swing),
        with the timing :meth:`timing` gives at that speed.
        """
        swing, double = self.timing(self.max_forward_speed)
        period = swing + double
        forward = min(self.max_forward_speed, min(MAX_STEP_FORWARD, MAX_ADVANCE_RATE * swing) / period)
        period = self.step_period
        swing_reach = MAX_ADVANCE_RATE * self.step_duration
        return (
            forward,
            min(self.max_backward_speed, min(MAX_STEP_BACKWARD, swing_reach) / period),
            min(self.max_lateral_speed, MAX_STEP_LATERAL / (2.0 * period)),
            min(self.max_yaw_rate, MAX_STEP_TURN / period),
        )

    @property
    def step_period(self) -> float:
        """Time from one lift-off to the next [s]."""
        return self.step_duration + self.double_support_duration
