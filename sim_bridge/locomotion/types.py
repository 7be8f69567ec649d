"""Typed values the walking controller reports."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import NamedTuple


class LocomotionMode(enum.Enum):
    """What the walking controller is doing."""

    STANDING = "standing"
    WALKING = "walking"
    STOPPING = "stopping"
    FALLEN = "fallen"


class GaitPhase(NamedTuple):
    """Where the gait is: the phase's kind (idle, shift, single, double, settle, balance, fallen), the time
    spent in it and its planned duration [s]."""

    kind: str
    elapsed: float
    duration: float


@dataclass(frozen=True)
class Twist2D:
    """A planar velocity in the base heading frame (x forward, y left, z up).

    Attributes:
        vx: forward velocity [m/s].
        vy: leftward velocity [m/s].
        wz: yaw rate, counter-clockwise positive [rad/s].
    """

    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0


@dataclass(frozen=True)
class LocomotionStatus:
    """A snapshot of the walking controller.

    Attributes:
        mode: standing, walking, stopping or fallen.
        steps_taken: touchdowns since the last reset.
        commanded: the last velocity command after clamping to the gait limits.
        measured: the pelvis velocity in the heading frame, low-pass filtered over about 0.5 s.
        fallen: the robot has fallen; nothing is commanded until ``reset``.
        message: a short human-readable explanation of the mode.
    """

    mode: LocomotionMode
    steps_taken: int
    commanded: Twist2D
    measured: Twist2D
    fallen: bool
    message: str
