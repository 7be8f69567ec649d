"""What a walking controller needs to know about a biped: names, walking posture, step geometry, limits.

A robot-agnostic description: ``sim_bridge.locomotion`` walks any robot given one. Each biped's
module ``robot_models.<name>_gait`` builds its own as ``BIPED``; its :class:`RobotSpec` carries it
(``spec.biped``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from robot_models.validation import check_range

Vec3 = tuple[float, float, float]

@dataclass(frozen=True)
class StepLimits:
    """How far one step may go; the gait's command limits follow from these.

    Attributes:
        forward_m: forward advance of the walking frame in one step [m].
        backward_m: backward advance in one step (a magnitude) [m].
        lateral_m: sideways displacement of the leading foot in one step [m].
        turn_rad: turn in one step [rad].
        advance_rate_mps: step advance per second of swing, i.e. half the mean swing-foot speed [m/s].
    """

    forward_m: float
    backward_m: float
    lateral_m: float
    turn_rad: float
    advance_rate_mps: float

    def __post_init__(self) -> None:
        for name in ("forward_m", "backward_m", "lateral_m", "turn_rad", "advance_rate_mps"):
            check_range(f"step limit {name}", getattr(self, name), 0.0, low_open=True)


@dataclass(frozen=True)
class BipedDescription:
    """A biped's facts for walking: which bodies, sites and joints, its walking crouch, how far its legs reach.

    Attributes:
        base_body: the floating base (pelvis), whose subtree CoM is the robot's CoM.
        torso_body: the upper body kept upright with the base.
        foot_bodies: (left, right) foot bodies, which carry the sole sites.
        sole_sites: (left, right) sites at the sole centres, on the floor when standing.
        sole_center_in_foot: centre of the sole box in the foot body's frame [m].
        sole_half_size: half sizes of the sole box (length, width, thickness) [m].
        leg_joints: both legs' joints (left leg, then right leg); torque-driven while walking.
        knee_joints: (left, right) knee joints, which the walk keeps bent.
        waist_joints: waist joints; torque-driven while walking, after the legs.
        servo_joints: joints left on their position servos while walking (arms, head mounts).
        walk_posture: joint name -> angle of the walking crouch [rad]; unlisted torque-driven joints are at 0.
        stand_keyframe: the keyframe the robot stands in (its CoM height sets the walking crouch's).
        half_step_width_m: lateral distance from the walking frame (midpoint between the feet) to
            each sole centre [m].
        reach_forward_m: (min, max) of the swing sole's x relative to the stance sole, in the
            stance sole's frame [m].
        reach_outward_m: (min, max) outward distance between the sole centres [m].
        steps: the longest steps the gait plans.
        fall_height_m: base height above the floor below which the robot has fallen [m].
        fall_tilt_rad: tilt of the base's z axis from the vertical beyond which it has fallen [rad].
    """

    base_body: str
    torso_body: str
    foot_bodies: tuple[str, str]
    sole_sites: tuple[str, str]
    sole_center_in_foot: Vec3
    sole_half_size: Vec3
    leg_joints: tuple[str, ...]
    knee_joints: tuple[str, str]
    waist_joints: tuple[str, ...]
    servo_joints: tuple[str, ...]
    walk_posture: Mapping[str, float]
    stand_keyframe: str
    half_step_width_m: float
    reach_forward_m: tuple[float, float]
    reach_outward_m: tuple[float, float]
    steps: StepLimits
    fall_height_m: float
    fall_tilt_rad: float

    def __post_init__(self) -> None:
        motors = self.motor_joints
        if len(set(motors + self.servo_joints)) != len(motors) + len(self.servo_joints):
            raise ValueError("a joint is listed twice among the leg, waist and servo joints")
        if not set(self.knee_joints) <= set(self.leg_joints):
            raise ValueError(f"knee joints {self.knee_joints} must be leg joints")
        if not set(self.walk_posture) <= set(motors):
            raise ValueError(f"walk posture joints {sorted(set(self.walk_posture) - set(motors))} are not leg or waist joints")
        for axis, half in zip("xyz", self.sole_half_size, strict=True):
            check_range(f"sole half size {axis}", half, 0.0, low_open=True, unit="m")
        check_range("half step width", self.half_step_width_m, 0.0, low_open=True, unit="m")
        for name, (low, high) in (("reach_forward_m", self.reach_forward_m), ("reach_outward_m", self.reach_outward_m)):
            check_range(f"{name} upper bound", high, low, low_open=True, unit="m")
        check_range("fall height", self.fall_height_m, 0.0, low_open=True, unit="m")
        check_range("fall tilt", self.fall_tilt_rad, 0.0, math.pi, low_open=True, high_open=True, unit="rad")

    @property
    def motor_joints(self) -> tuple[str, ...]:
        """The joints driven by torque while walking: legs, then waist."""
        return self.leg_joints + self.waist_joints

