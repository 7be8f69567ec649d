"""The swing foot: its trajectory from lift-off to the landing, and the state of the current swing."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from sim_bridge.locomotion.geometry import Footstep, Side, Vec3, wrap_angle


class SwingSample(NamedTuple):
    """Swing sole reference: position (3,), velocity (3,), acceleration (3,) [m, m/s, m/s^2], yaw [rad], yaw rate [rad/s]."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw: float
    yaw_rate: float


def swing_sample(
    start: Sequence[float], start_yaw: float, target: Footstep, height: float, elapsed: float, duration: float
) -> SwingSample:
    """Swing sole reference: quintic in x, y and yaw, height ``64 h s^3 (1 - s)^3`` (zero speed at both ends).

    Args:
        start: sole position at lift-off (x, y, z) [m].
        start_yaw: sole yaw at lift-off [rad].
        target: where the sole lands.
        height: apex height above the floor [m].
        elapsed: time since lift-off [s].
        duration: swing time [s].
    """
    s = min(max(elapsed / duration, 0.0), 1.0)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    blend_d = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    blend_dd = (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    x0, y0, z0 = start[0], start[1], start[2]
    dx, dy = target.x - x0, target.y - y0
    z = 64.0 * height * s**3 * (1 - s) ** 3
    z_d = 64.0 * height * 3 * s**2 * (1 - s) ** 2 * (1 - 2 * s) / duration
    z_dd = 64.0 * height * 6 * s * (1 - s) * ((1 - 2 * s) ** 2 - s * (1 - s)) / duration**2
    yaw_delta = wrap_angle(target.yaw - start_yaw)
    return SwingSample(
        position=np.array([x0 + dx * blend, y0 + dy * blend, z + z0 * (1 - blend)]),
        velocity=np.array([dx * blend_d, dy * blend_d, z_d - z0 * blend_d]),
        acceleration=np.array([dx * blend_dd, dy * blend_dd, z_dd - z0 * blend_dd]),
        yaw=start_yaw + yaw_delta * blend,
        yaw_rate=yaw_delta * blend_d,
    )


_NO_TARGET = Footstep(Side.LEFT, 0.0, 0.0, 0.0)  # the target before the first swing


@dataclass
class SwingState:
    """The current swing: where its trajectory starts and where it lands.

    Attributes:
        start: sole position when the trajectory (re)started, world (x, y, z) [m].
        start_yaw: sole yaw then [rad].
        origin: phase time at which the trajectory (re)started [s] (0 at lift-off).
        height: apex of the trajectory above its start [m].
        target: the nominal landing, from the footstep plan.
        landing: the landing after step adjustment (None until the first adjustment of the swing).
        closing: the nominal landing closes the feet (a zero-velocity step).
    """

    start: Vec3 = (0.0, 0.0, 0.0)
    start_yaw: float = 0.0
    origin: float = 0.0
    height: float = 0.06
    target: Footstep = _NO_TARGET
    landing: Footstep | None = None
    closing: bool = False

    def restart(self, start: Vec3, start_yaw: float, origin: float, height: float) -> None:
        """Start the trajectory again from ``start`` [m] at phase time ``origin`` [s], rising ``height`` [m]."""
        self.start = start
        self.start_yaw = start_yaw
        self.origin = origin
        self.height = height

    def sample(self, landing: Footstep, elapsed: float, duration: float) -> SwingSample:
        """The reference ``elapsed`` seconds into a swing phase of ``duration`` [s], toward ``landing``."""
        origin = self.origin
        return swing_sample(self.start, self.start_yaw, landing, self.height, elapsed - origin, duration - origin)
