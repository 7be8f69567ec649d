"""Tuning of the fetch's arm motions and squeeze (defaults in code, validated)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from robot_models.validation import check_range
from sim_bridge.errors import InvalidGoalError


@dataclass(frozen=True)
class GripConfig:
    """How the palms move and squeeze.

    Attributes:
        clearance_m: the palms approach the box sides this far short of them [m].
        grip_back_m: the palms take the box this far behind its centre (toward the robot) [m], at most
            so far that a palm of half length ``palm_half_length_m`` [m] stays on the box's side.
        grip_up_m: ... and this far above its centre [m] (the arms reach a low place more easily), at
            most so far that a palm of half height ``palm_half_height_m`` [m] stays on the side.
        ready_clearance_m: ... and are raised ready this far outside them [m].
        ready_forward_m: the ready grip centre is this far ahead of the pelvis [m].
        ready_rise_m: ... and this far above the object's resting centre [m].
        hand_pitch_rad: the hands point this much down from horizontal, along the box's sides [rad]
            (the arms' natural reach forward and down; the palms stay flat on the sides).
        reach_speed_mps: hand speed of the reaching moves [m/s].
        carry_speed_mps: speed of the grip centre while holding (lift, place) [m/s].
        grip_period_s: the grip is regulated and re-targeted this often [s of sim time].
        squeeze_gain: squeeze depth rate per newton of force error [m/(N s)].
        max_squeeze_step_m: largest change of a palm's depth per period [m].
        max_depth_m: deepest a palm target goes past the box surface [m].
        grasp_fraction: the grasp is made when both palms measure this fraction of the grip force.
        grasp_settle_s: ... for this long [s].
        contact_force_n: a palm measuring less does not touch [N].
        drop_after_s: no palm holding for this long while carrying is a drop [s].
        place_press_m: the box is lowered this far below resting height (negative: above) [m].
        rest_tolerance_m: a box this close to its resting height rests [m].
        release_s: the palms open for at least this long [s].
        retreat_rise_m: the hands rise this much after the release [m].
        retreat_speed_mps: ... this fast [m/s] (the robot stands on its servos: a quick swing tips it).
        ready_tolerance_m, reach_tolerance_m, place_tolerance_m: arrival tolerances of the moves [m].
        move_timeout_s: longest time for one arm move [s].
        unreachable_s: an arm refusing its targets this long fails the fetch [s].
        grasp_timeout_s: longest time for the squeeze [s].
        lift_settle_s: least time of the lift and of the lowering [s].
        min_walk_m: shorter walks are skipped [m].
        robot_radius_m, obstacle_margin_m: the navigation's inflation (their sum) [m].
        xy_tolerance_m, yaw_tolerance_rad: the navigation's arrival tolerances.
        max_place_tilt_rad: a placed box tilted more is not placed.
        align_*: the side-step onto the stance's line before walking onto it: tolerances [m, rad], gain
            [1/s], speeds [m/s], yaw rate [rad/s], time limit [s].
    """

    clearance_m: float = 0.04
    grip_back_m: float = 0.04
    palm_half_length_m: float = 0.05
    grip_up_m: float = 0.03
    hand_pitch_rad: float = 0.0
    palm_half_height_m: float = 0.04
    ready_clearance_m: float = 0.07
    ready_forward_m: float = 0.28
    ready_rise_m: float = 0.05
    reach_speed_mps: float = 0.2
    carry_speed_mps: float = 0.08
    grip_period_s: float = 0.04
    squeeze_gain: float = 0.002
    max_squeeze_step_m: float = 0.003
    max_depth_m: float = 0.05
    grasp_fraction: float = 0.8
    grasp_settle_s: float = 0.3
    contact_force_n: float = 1.0
    drop_after_s: float = 0.3
    place_press_m: float = 0.005
    rest_tolerance_m: float = 0.004
    release_s: float = 0.6
    retreat_rise_m: float = 0.12
    retreat_speed_mps: float = 0.06
    ready_tolerance_m: float = 0.01
    reach_tolerance_m: float = 0.01
    place_tolerance_m: float = 0.01
    move_timeout_s: float = 5.0
    unreachable_s: float = 1.0
    grasp_timeout_s: float = 5.0
    lift_settle_s: float = 0.5
    min_walk_m: float = 0.02
    robot_radius_m: float = 0.30
    obstacle_margin_m: float = 0.10
    xy_tolerance_m: float = 0.05
    yaw_tolerance_rad: float = 0.05
    max_place_tilt_rad: float = math.radians(3.0)
    align_tolerance_m: float = 0.03
    align_tolerance_rad: float = 0.03
    align_gain: float = 0.5
    align_stop_lead_m: float = 0.02
    align_min_speed_mps: float = 0.03
    align_max_speed_mps: float = 0.08
    align_max_yaw_rate: float = 0.25
    align_timeout_s: float = 12.0

    def navigation_settings(self, walking_speed_mps: float) -> dict[str, float]:
        """The settings of the fetch's navigations (NavigateSkill's parameters)."""
        return {"walking_speed": walking_speed_mps, "robot_radius": self.robot_radius_m,
                "obstacle_detection_threshold": self.obstacle_margin_m, "xy_goal_tolerance": self.xy_tolerance_m,
                "yaw_goal_tolerance": self.yaw_tolerance_rad}

    def __post_init__(self) -> None:
        for item in fields(self):
            if item.name not in ("place_press_m", "hand_pitch_rad"):
                check_range(item.name, getattr(self, item.name), 0.0, low_open=True, error=InvalidGoalError)
