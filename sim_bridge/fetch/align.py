"""The last centimetres onto a stance: small steps forward, sideways and turning, on the walking controller.

Navigation ends within a few centimetres of its goal and a straight walk drifts sideways; the arms
reach a table's object from a stance only within a few centimetres. The aligner commands small
velocities toward the stance, measured at the midpoint between the feet (the pelvis sways while
stepping), stops once near, lets the walker close its feet and stand, and looks again.
"""

from __future__ import annotations

import math

import numpy as np

from sim_bridge.fetch.grip import GripConfig
from sim_bridge.fetch.stance import Stance, wrap
from sim_bridge.locomotion import WalkingController


class StanceAligner:
    """Steps a standing biped onto a stance.

    Args:
        walker: the walking controller (commanded with velocities).
        config: the ``align_*`` settings.
    """

    def __init__(self, walker: WalkingController, config: GripConfig) -> None:
        self.walker = walker
        self.config = config
        self.stepping = False

    def step(self, stance: Stance, feet: tuple[float, float, float], elapsed: float, standing: bool) -> bool:
        """One control step. ``feet``: midpoint between the soles (world x, y [m]) and heading [rad];
        ``elapsed``: time since the alignment began [s]; ``standing``: the walker has stopped.
        Returns True once standing on the stance within tolerance, or out of time."""
        config = self.config
        x, y, yaw = feet
        ahead = math.cos(yaw) * (stance.x - x) + math.sin(yaw) * (stance.y - y)
        lateral = -math.sin(yaw) * (stance.x - x) + math.cos(yaw) * (stance.y - y)
        turn = wrap(stance.yaw - yaw)
        distance = max(abs(ahead), abs(lateral))
        aligned = distance <= config.align_tolerance_m and abs(turn) <= config.align_tolerance_rad
        near = distance <= 0.5 * (config.align_tolerance_m + config.align_stop_lead_m) and \
            abs(turn) <= config.align_tolerance_rad
        out_of_time = elapsed > config.align_timeout_s
        if self.stepping and (near or out_of_time):
            self.stepping = False  # stop, stand, and look again
            self.walker.set_velocity_command(0.0, 0.0, 0.0)
        if not self.stepping:
            if not standing:
                return False
            if aligned or out_of_time:
                return True
            self.stepping = True
        vx, vy = (math.copysign(min(max(abs(error) * config.align_gain, config.align_min_speed_mps),
                                    config.align_max_speed_mps), error) if abs(error) > 0.5 * config.align_tolerance_m else 0.0
                  for error in (ahead, lateral))
        wz = float(np.clip(turn * config.align_gain, -config.align_max_yaw_rate, config.align_max_yaw_rate))
        self.walker.set_velocity_command(vx, vy, wz)
        return False
