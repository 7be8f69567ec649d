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

import numpy as np
from geometry_msgs.msg import Pose as PoseMsg, PoseStamped

from robot_models import RobotSpec, WalkingLimits
from sim_bridge import Simulation
from sim_bridge.arm import PickPlaceGoal
from sim_bridge.arm.pick_place import min_grip_force_n, place_problem
from sim_bridge.battery import Battery
from sim_bridge.errors import InvalidGoalError
from sim_bridge.fetch import FetchGoal, check_fetchable, check_place_on_a_table, fetch_skill
from sim_bridge.frames import check_frame, is_world, to_world
from sim_bridge.skills import LEGS, NavigateGoal, NavigateSkill, Skill, SkillOutcome, Values, WalkGoal, WalkSkill
from sim_bridge.skills.arm import MoveArmGoal, MoveArmSkill, PickPlaceSkill
from sim_bridge.skills.battery_guard import BatteryGuard
from sim_bridge.skills.reset_pose import ResetPoseGoal, ResetPoseSkill
from sim_bridge.state import Pose
from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, ResetPose, Walk
from sim_ros.conversions import set_pose, yaw_of
from sim_ros.stamps import duration_msg, set_time

PICK_POSE_RADIUS_M = 0.03  # a pick_pose names the object whose centre is this close
# The /arm parameters the arm skills read, with their defaults (a START without settings uses these).
ARM_SETTINGS = {
    "max_velocity_scaling": 0.5, "max_linear_speed": 0.5, "max_angular_speed": 1.5, "gripper_force": 20.0,
    "approach_height": 0.10, "lift_height": 0.15, "placement_tolerance": 0.005, "move_timeout": 30.0,
    "pick_place_timeout": 90.0,
}


@dataclass
class SkillContext:
    """What ``/sim`` offers a binding to build a skill: the simulation and its in-loop controllers."""

    sim: Simulation
    walker: Any = None  # WalkingController
    grid: Any = None  # OccupancyGrid of the scene's static obstacles
    arms: Any = None  # ArmController
    pick_place: Any = None  # PickPlace
    battery: Battery | None = None  # drained in the control step; Walk and NavigateToPose are guarded by it

    @property
    def robot(self) -> RobotSpec:
        return self.sim.robot


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


def _guarded(skill: Skill, context: SkillContext) -> Skill:
    """A locomotion skill that refuses to start, or stops, on a low battery (``BATTERY_LOW``)."""
    return skill if context.battery is None else BatteryGuard(skill, context.battery)


def _build_walk(goal: Walk.Goal, settings: Mapping[str, float], context: SkillContext) -> Skill:
    return _guarded(WalkSkill(context.walker, context.robot.base_body, _walk_goal(goal, context.robot), settings), context)


# ----- NavigateToPose ----------------------------------------------------------------------------
def _navigate_goal(goal: NavigateToPose.Goal, robot: RobotSpec, sim: Simulation | None = None) -> NavigateGoal:
    """The core goal; with ``sim``, in the world frame (a goal in a robot frame is resolved from its state now)."""
    _walking(robot)
    p, o = goal.pose.pose.position, goal.pose.pose.orientation
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z, o.x, o.y, o.z, o.w)):
        raise InvalidGoalError("goal pose has NaN or infinite values")
    if math.hypot(o.x, o.y, o.z, o.w) < 1e-6:
        raise InvalidGoalError("goal orientation quaternion cannot be normalised (norm 0)")
    check_frame(goal.pose.header.frame_id, robot, "goal pose")
    if sim is None:
        return NavigateGoal(p.x, p.y, yaw_of(np.array([o.w, o.x, o.y, o.z])))
    pose = _in_world(goal.pose.pose, goal.pose.header.frame_id, sim)
    return NavigateGoal(float(pose.position[0]), float(pose.position[1]), yaw_of(pose.orientation_wxyz))


def _build_navigate(goal: NavigateToPose.Goal, settings: Mapping[str, float], context: SkillContext) -> Skill:
    return _guarded(NavigateSkill(context.walker, context.robot.base_body, context.grid,
                                  _navigate_goal(goal, context.robot, context.sim), settings), context)


# ----- ResetPose (served as the /reset_pose service) ----------------------------------------------
def _reset_pose_goal(goal: ResetPose.Goal, robot: RobotSpec) -> ResetPoseGoal:
    _walking(robot)
    return ResetPoseGoal(goal.tolerance, goal.timeout)


def _build_reset_pose(goal: ResetPose.Goal, settings: Mapping[str, float], context: SkillContext) -> Skill:
    return ResetPoseSkill(context.walker, context.robot, _reset_pose_goal(goal, context.robot))


# ----- MoveArm and PickPlace ------------------------------------------------------------------
def arm_name(requested: str, robot: RobotSpec) -> str:
    name = requested or robot.default_end_effector
    if name not in robot.end_effector_sites:
        raise InvalidGoalError(f"unknown end_effector {requested!r}; known: {', '.join(robot.end_effector_sites) or 'none'} "
                               f"(empty = {robot.default_end_effector or 'none'})")
    return name


def _finite_numbers(**values: float) -> None:
    bad = [name for name, value in values.items() if not math.isfinite(value)]
    if bad:
        raise InvalidGoalError(f"{', '.join(bad)} must be finite numbers")


def _validate_move(goal: MoveArm.Goal, robot: RobotSpec) -> str:
    _finite_numbers(position_tolerance=goal.position_tolerance, orientation_tolerance=goal.orientation_tolerance,
                    max_velocity_scaling=goal.max_velocity_scaling, timeout=goal.timeout)
    if goal.position_tolerance <= 0.0:
        raise InvalidGoalError(f"position_tolerance must be > 0 m, got {goal.position_tolerance}")
    if goal.orientation_tolerance < 0.0:
        raise InvalidGoalError(f"orientation_tolerance must be >= 0 rad (0 = position only), got {goal.orientation_tolerance}")
    if not 0.0 <= goal.max_velocity_scaling <= 1.0:
        raise InvalidGoalError(f"max_velocity_scaling must be in (0, 1] (0 = default), got {goal.max_velocity_scaling}")
    if goal.timeout < 0.0:
        raise InvalidGoalError(f"timeout must be >= 0 s (0 = default), got {goal.timeout}")
    arm = arm_name(goal.end_effector, robot)
    p, o = goal.target.pose.position, goal.target.pose.orientation
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z, o.w, o.x, o.y, o.z)):
        raise InvalidGoalError("target pose has NaN or infinite values")
    if math.hypot(o.w, o.x, o.y, o.z) < 1e-6 and goal.orientation_tolerance != 0.0:
        raise InvalidGoalError("target orientation quaternion cannot be normalised (norm 0); "
                               "give a unit quaternion, or orientation_tolerance 0 for position only")
    check_frame(goal.target.header.frame_id, robot, "target")
    return arm


def _in_world(pose: PoseMsg, frame: str, sim: Simulation) -> Pose:
    """A pose given in ``frame`` (any frame of /tf: :mod:`sim_bridge.frames`), in the world frame, from the sim's state."""
    p, o = pose.position, pose.orientation
    quat = np.array([o.w, o.x, o.y, o.z])
    norm = float(np.linalg.norm(quat))
    local = Pose(np.array([p.x, p.y, p.z]), quat / norm if norm >= 1e-6 else np.array([1.0, 0.0, 0.0, 0.0]))
    return to_world(sim.model, sim.data, frame, local)


def _setting(settings: Mapping[str, float], name: str) -> float:
    return float(settings.get(name, ARM_SETTINGS[name]))


def _build_move(goal: MoveArm.Goal, settings: Mapping[str, float], context: SkillContext) -> Skill:
    arm = _validate_move(goal, context.robot)
    scaling = goal.max_velocity_scaling or _setting(settings, "max_velocity_scaling")
    target = _in_world(goal.target.pose, goal.target.header.frame_id, context.sim)
    return MoveArmSkill(context.arms, MoveArmGoal(
        arm, target, goal.position_tolerance, goal.orientation_tolerance, scaling * _setting(settings, "max_linear_speed"),
        scaling * _setting(settings, "max_angular_speed"), goal.timeout or _setting(settings, "move_timeout")))


def _validate_pick(goal: PickPlace.Goal, robot: RobotSpec) -> str:
    if fetches(robot):
        return _validate_fetch(goal, robot)
    if not robot.objects or robot.grasp is None:
        raise InvalidGoalError(f"robot {robot.name!r} has " + ("no grippers to pick objects with" if robot.objects
                                                                 else "no objects to pick"))
    arm = arm_name(goal.end_effector, robot)
    numbers = {"grasp_force": goal.grasp_force, "approach_height": goal.approach_height,
               "lift_height": goal.lift_height, "timeout": goal.timeout}
    bad = [name for name, value in numbers.items() if not math.isfinite(value) or value < 0.0]
    if bad:
        raise InvalidGoalError(f"{', '.join(bad)} must be finite and >= 0 (0 = the parameter's default)")
    if goal.grasp_force > robot.grasp.max_force_n:
        raise InvalidGoalError(f"grasp_force must be <= {robot.grasp.max_force_n:g} N per finger, got {goal.grasp_force}")
    if goal.object_id:
        if goal.object_id not in robot.objects:
            raise InvalidGoalError(f"unknown object {goal.object_id!r}; objects: {', '.join(robot.objects)}")
    else:
        p = goal.pick_pose.pose.position
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
            raise InvalidGoalError("give object_id, or a finite pick_pose")
        check_frame(goal.pick_pose.header.frame_id, robot, "pick_pose")
    if goal.grasp_force > 0.0:  # 0 = the parameter's default
        candidates = [goal.object_id] if goal.object_id else list(robot.objects)
        needed = max(min_grip_force_n(robot.model, name) for name in candidates)
        if goal.grasp_force < needed:
            raise InvalidGoalError(f"grasp_force {goal.grasp_force:g} N per finger cannot hold "
                                   f"{goal.object_id or 'the objects'}: at least {needed:.2f} N "
                                   f"(up to {robot.grasp.max_force_n:g} N; 0 = the default)")
    check_frame(goal.place_pose.header.frame_id, robot, "place_pose")
    p = goal.place_pose.pose.position
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
        raise InvalidGoalError("place_pose has NaN or infinite values")
    if is_world(goal.place_pose.header.frame_id):  # in a robot frame it is judged in /sim, from the frame's pose
        problem = place_problem(robot.arm_scene, (p.x, p.y, p.z))
        if problem:
            raise InvalidGoalError(problem)
    return arm


# ----- PickPlace on a walking robot with palms: the whole fetch (walk, squeeze, carry, place) -------------
FETCH_DEFAULTS = FetchGoal("", 0.0, 0.0)  # grip force, lift height, timeout when a goal gives 0


def fetches(robot: RobotSpec) -> bool:
    """Whether PickPlace on this robot is a fetch: it walks and holds objects between its palms."""
    return bool(robot.palms) and robot.walking is not None


def _pick_resource(goal: PickPlace.Goal, robot: RobotSpec) -> str:
    """A fetch owns the legs (and drives both arms); a fixed arm's pick owns that arm."""
    return LEGS if fetches(robot) else arm_name(goal.end_effector, robot)


def _validate_fetch(goal: PickPlace.Goal, robot: RobotSpec) -> str:
    if not robot.objects:
        raise InvalidGoalError(f"robot {robot.name!r} has no objects to pick in this scene (scene 'tables' has a box "
                               "on a table: bringup --scene tables)")
    if goal.end_effector:
        raise InvalidGoalError(f"robot {robot.name!r} chooses its hands (both palms, or one hand for a small "
                               "object): leave end_effector empty "
                               f"(got {goal.end_effector!r})")
    _finite_numbers(grasp_force=goal.grasp_force, approach_height=goal.approach_height, lift_height=goal.lift_height,
                    timeout=goal.timeout)
    if goal.approach_height != 0.0:
        raise InvalidGoalError(f"approach_height is a fixed arm's; robot {robot.name!r} plans its own stances: "
                               f"leave it 0 (got {goal.approach_height})")
    for name, value in (("grasp_force", goal.grasp_force), ("lift_height", goal.lift_height), ("timeout", goal.timeout)):
        if value < 0.0:
            raise InvalidGoalError(f"{name} must be >= 0 (0 = the default), got {value}")
    task = FetchGoal("", 0.0, 0.0, grip_force_n=goal.grasp_force or FETCH_DEFAULTS.grip_force_n,
                     lift_height_m=goal.lift_height or FETCH_DEFAULTS.lift_height_m,
                     timeout_s=goal.timeout or FETCH_DEFAULTS.timeout_s)  # checks the ranges
    if goal.object_id:
        check_fetchable(robot, goal.object_id, task.grip_force_n)
    else:
        p = goal.pick_pose.pose.position
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
            raise InvalidGoalError("give object_id, or a finite pick_pose")
        check_frame(goal.pick_pose.header.frame_id, robot, "pick_pose")
    p, o = goal.place_pose.pose.position, goal.place_pose.pose.orientation
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z, o.x, o.y, o.z, o.w)):
        raise InvalidGoalError("place_pose has NaN or infinite values")
    check_frame(goal.place_pose.header.frame_id, robot, "place_pose")
    if is_world(goal.place_pose.header.frame_id):  # in another frame it is judged in /sim, from the frame's pose
        check_place_on_a_table(robot, p.x, p.y)
    return LEGS


def _build_fetch(goal: PickPlace.Goal, context: SkillContext) -> Skill:
    _validate_fetch(goal, context.robot)
    name = goal.object_id or _object_at(goal, context.sim)
    place = _in_world(goal.place_pose.pose, goal.place_pose.header.frame_id, context.sim)
    o = goal.place_pose.pose.orientation
    identity = (o.x, o.y, o.z) == (0.0, 0.0, 0.0)  # no yaw asked: square to the table's edge
    task = FetchGoal(name, float(place.position[0]), float(place.position[1]),
                     None if identity else yaw_of(place.orientation_wxyz),
                     grip_force_n=goal.grasp_force or FETCH_DEFAULTS.grip_force_n,
                     lift_height_m=goal.lift_height or FETCH_DEFAULTS.lift_height_m,
                     timeout_s=goal.timeout or FETCH_DEFAULTS.timeout_s)
    check_fetchable(context.robot, name, task.grip_force_n)  # an object picked by pick_pose is judged here
    # A small object with one hand, the others with both palms.
    return _guarded(fetch_skill(context.robot, context.walker, context.arms, context.grid, task), context)


def _object_at(goal: PickPlace.Goal, sim: Simulation) -> str:
    """The object whose centre is within PICK_POSE_RADIUS_M of the goal's pick_pose."""
    pick = _in_world(goal.pick_pose.pose, goal.pick_pose.header.frame_id, sim).position
    distances = {name: float(math.dist(pick, sim.body_pose(name).position)) for name in sim.robot.objects}
    name, distance = min(distances.items(), key=lambda item: item[1])
    if distance > PICK_POSE_RADIUS_M:
        raise InvalidGoalError(f"no object within {PICK_POSE_RADIUS_M * 100:g} cm of pick_pose "
                               f"(nearest: {name} at {distance:.3f} m)")
    return name


def _build_pick(goal: PickPlace.Goal, settings: Mapping[str, float], context: SkillContext) -> Skill:
    if fetches(context.robot):
        return _build_fetch(goal, context)
    arm = _validate_pick(goal, context.robot)
    if context.pick_place is None:
        raise InvalidGoalError(f"robot {context.robot.name!r} has no objects to pick")
    place = _in_world(goal.place_pose.pose, goal.place_pose.header.frame_id, context.sim).position
    task = PickPlaceGoal(
        object_name=goal.object_id or _object_at(goal, context.sim),
        place_position=(float(place[0]), float(place[1]), float(place[2])), arm=arm,
        approach_height=goal.approach_height or _setting(settings, "approach_height"),
        lift_height=goal.lift_height or _setting(settings, "lift_height"),
        grip_force=goal.grasp_force or _setting(settings, "gripper_force"),
        placement_tolerance=_setting(settings, "placement_tolerance"))
    return PickPlaceSkill(context.pick_place, task, goal.timeout or _setting(settings, "pick_place_timeout"))


BINDINGS: dict[str, SkillBinding] = {
    binding.name: binding
    for binding in (
        SkillBinding("walk", Walk, lambda _goal, _robot: LEGS, _walk_goal, _build_walk),
        SkillBinding("navigate_to_pose", NavigateToPose, lambda _goal, _robot: LEGS, _navigate_goal, _build_navigate),
        SkillBinding("reset_pose", ResetPose, lambda _goal, _robot: LEGS, _reset_pose_goal, _build_reset_pose),
        SkillBinding("move_arm", MoveArm, lambda goal, robot: arm_name(goal.end_effector, robot), _validate_move, _build_move),
        SkillBinding("pick_place", PickPlace, _pick_resource, _validate_pick, _build_pick),
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
