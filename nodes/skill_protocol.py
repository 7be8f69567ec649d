"""The one goal protocol between the action servers and the skills inside ``/sim``.

An action server validates a goal and sends it, CDR-serialized as the action's own Goal message, in
a ``SkillCommand`` (START, CANCEL, UPDATE) on ``/sim/skill_command``. ``/sim`` builds the skill from
it (:data:`BINDINGS`), runs it in the control step and reports ``SkillState`` on
``/sim/skill_state``: the goal's sequence number, the reset epoch, the status, and the action's own
Feedback and Result messages filled from the skill's measured values. A server only relays.

Each binding says, for one action: its resource, its validation (run by the server before accepting
and by ``/sim`` before starting, one function), and how ``/sim`` builds the core skill. Result codes
are looked up by name in the action definition (``Walk.Result.FELL``), never copied.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import Pose as PoseMsg, PoseStamped

from nodes.conversions import duration_msg, set_pose, set_time, yaw_of
from robot_models import RobotSpec, WalkingLimits
from sim_bridge.errors import InvalidGoalError
from sim_bridge.skills import LEGS, NavigateGoal, NavigateSkill, Skill, SkillOutcome, Values, WalkGoal, WalkSkill
from sim_bridge.state import Pose
from sim_interfaces.action import NavigateToPose, Walk

SKILL_COMMAND_TOPIC = "/sim/skill_command"
SKILL_STATE_TOPIC = "/sim/skill_state"
WORLD_FRAMES = ("", "world", "odom", "map")


class SkillContext:
    """What ``/sim`` offers a binding to build a skill: the robot and its in-loop controllers."""

    def __init__(self, robot: RobotSpec, walker: Any = None, grid: Any = None, arms: Any = None, pick_place: Any = None) -> None:
        self.robot = robot
        self.walker = walker
        self.grid = grid
        self.arms = arms
        self.pick_place = pick_place


@dataclass(frozen=True)
class SkillBinding:
    """One action carried by the protocol.

    Attributes:
        name: the skill's name in SkillCommand/SkillState.
        action_type: the generated action type (its Goal, Feedback and Result are used).
        resource: the resource a goal owns (validates names it refers to).
        validate: static validation of a goal (raises InvalidGoalError with what is allowed).
        build: ``/sim`` side: the core skill for a validated goal and the server's settings.
    """

    name: str
    action_type: Any
    resource: Callable[[Any, RobotSpec], str]
    validate: Callable[[Any, RobotSpec], object]
    build: Callable[[Any, Mapping[str, float], SkillContext], Skill]


# ----- Walk ------------------------------------------------------------------------------------
def _walking(robot: RobotSpec) -> WalkingLimits:
    if robot.walking is None:
        raise InvalidGoalError(f"robot {robot.name!r} cannot walk (it has no legs)")
    return robot.walking


def _walk_goal(goal: Walk.Goal, robot: RobotSpec) -> WalkGoal:
    return WalkGoal(goal.distance, goal.speed, goal.timeout, _walking(robot))


def _build_walk(goal: Walk.Goal, settings: Mapping[str, float], context: SkillContext) -> Skill:
    return WalkSkill(context.walker, context.robot.base_body, _walk_goal(goal, context.robot), settings)


# ----- NavigateToPose ----------------------------------------------------------------------------
def _navigate_goal(goal: NavigateToPose.Goal, robot: RobotSpec) -> NavigateGoal:
    _walking(robot)
    p, o = goal.pose.pose.position, goal.pose.pose.orientation
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z, o.x, o.y, o.z, o.w)):
        raise InvalidGoalError("goal pose has NaN or infinite values")
    if math.sqrt(o.x ** 2 + o.y ** 2 + o.z ** 2 + o.w ** 2) < 1e-6:
        raise InvalidGoalError("goal orientation quaternion cannot be normalised (norm 0)")
    if goal.pose.header.frame_id not in WORLD_FRAMES:
        raise InvalidGoalError(f"unknown frame {goal.pose.header.frame_id!r}; "
                               f"allowed: {', '.join(f or '(empty)' for f in WORLD_FRAMES)}")
    import numpy as np

    return NavigateGoal(p.x, p.y, yaw_of(np.array([o.w, o.x, o.y, o.z])))


def _build_navigate(goal: NavigateToPose.Goal, settings: Mapping[str, float], context: SkillContext) -> Skill:
    return NavigateSkill(context.walker, context.robot.base_body, context.grid, _navigate_goal(goal, context.robot), settings)


BINDINGS: dict[str, SkillBinding] = {
    binding.name: binding
    for binding in (
        SkillBinding("walk", Walk, lambda _goal, _robot: LEGS, _walk_goal, _build_walk),
        SkillBinding("navigate_to_pose", NavigateToPose, lambda _goal, _robot: LEGS, _navigate_goal, _build_navigate),
    )
}


# ----- messages ------------------------------------------------------------------------------------
def fill_message(msg: Any, values: Values, stamp_s: float, frame: str) -> Any:
    """Set the fields of an action Feedback/Result message from a skill's named values.

    Poses go into ``Pose``/``PoseStamped`` fields (stamped with ``stamp_s`` in ``frame``), seconds
    into ``Duration`` fields; numbers and strings are converted to the field's type.
    """
    types = msg.get_fields_and_field_types()
    for name, value in values.items():
        kind = types.get(name)
        if kind is None:
            raise KeyError(f"{type(msg).__name__} has no field {name!r}; fields: {', '.join(types)}")
        if isinstance(value, Pose):
            pose = PoseMsg()
            set_pose(pose, value.position, value.orientation_wxyz)
            if kind == "geometry_msgs/PoseStamped":
                stamped = PoseStamped(pose=pose)
                stamped.header.frame_id = frame
                set_time(stamped.header.stamp, stamp_s)
                setattr(msg, name, stamped)
            else:
                setattr(msg, name, pose)
        elif kind == "builtin_interfaces/Duration":
            setattr(msg, name, duration_msg(float(value)))
        elif kind in ("float", "double"):
            setattr(msg, name, float(value))
        elif kind == "string":
            setattr(msg, name, str(value))
        elif kind == "boolean":
            setattr(msg, name, bool(value))
        else:  # the integer types
            setattr(msg, name, int(value))
    return msg


def result_message(action_type: Any, outcome: SkillOutcome | None, values: Values, stamp_s: float, frame: str) -> Any:
    """The action's Result message: its values, and the code looked up by name in the action definition."""
    result = fill_message(action_type.Result(), values, stamp_s, frame)
    if outcome is not None:
        result.error_code = int(getattr(action_type.Result, outcome.code, action_type.Result.SIM_FAULT))
        result.error_msg = outcome.message
    return result


def result_codes(action_type: Any) -> dict[int, str]:
    """The action's result codes (number -> name), read from its definition."""
    return {int(v): k for k, v in vars(action_type.Result).items() if k.isupper() and isinstance(v, int)}
