"""The ``/arm`` node: MoveArm and PickPlace action servers and an IK query service.

The server plans, supervises and reports; the closed loops (tool tracking with mink IK, the
pick-and-place stages and the friction grasp) run inside the simulation's control step, in
``/sim``. Goals travel to ``/sim/arm_command``; progress comes back on ``/sim/arm_state``,
measured from the simulated state. One goal per arm: a new goal preempts the running one.
"""

from __future__ import annotations

import math
import os
import sys
from typing import Any

import numpy as np
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Odometry
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState

import robot_models
from nodes.common import ActiveGoal, GoalOwnership, GoalRejected, OnDemandTopic, finish_goal, goal_validator, guarded, spin_server
from nodes.conversions import duration_msg, pose_from_msg, pose_msg, seconds_of
from nodes.parameters import ParameterSpec, declare
from sim_bridge.arm import ArmKinematics
from sim_bridge.errors import SimError
from sim_bridge.state import Pose
from sim_interfaces.action import MoveArm, PickPlace
from sim_interfaces.msg import ArmCommand, ArmState, ObjectStates
from sim_interfaces.srv import ComputeIK

NODE_NAME = "arm"
ACK_TIMEOUT_S = 10.0  # wall seconds to wait for /sim to confirm a command
FRESH_TIMEOUT_S = 2.0  # wall seconds to wait for a first message of a stream subscribed on demand
WORLD_FRAMES = ("", "world", "odom")

PARAMETERS = (
    ParameterSpec("max_velocity_scaling", 0.5, "default fraction of the tool speed limits for MoveArm", 0.01, 1.0),
    ParameterSpec("max_linear_speed", 0.5, "tool speed at velocity scaling 1 [m/s]", 0.05, 2.0),
    ParameterSpec("max_angular_speed", 1.5, "tool angular speed at velocity scaling 1 [rad/s]", 0.1, 6.0),
    ParameterSpec("feedback_rate", 10.0, "action feedback rate [Hz of sim time]", 1.0, 100.0),
    ParameterSpec("gripper_force", 20.0, "squeeze force per finger for PickPlace [N]", 2.0, 70.0),
    ParameterSpec("approach_height", 0.10, "PickPlace approach height above the object [m]", 0.03, 0.30),
    ParameterSpec("lift_height", 0.15, "PickPlace lift height above the table [m]", 0.02, 0.30),
    ParameterSpec("placement_tolerance", 0.005, "PickPlace placement error counted as success [m]", 0.001, 0.05),
    ParameterSpec("move_timeout", 30.0, "MoveArm timeout when a goal gives 0 [s of sim time]", 1.0, 600.0),
    ParameterSpec("pick_place_timeout", 90.0, "PickPlace timeout when a goal gives 0 [s of sim time]", 5.0, 600.0),
)
PICK_PLACE_CODES = {
    "UNREACHABLE": PickPlace.Result.UNREACHABLE,
    "GRASP_MISSED": PickPlace.Result.GRASP_FAILED,
    "OBJECT_SLIPPED": PickPlace.Result.OBJECT_DROPPED,
    "OBJECT_DROPPED": PickPlace.Result.OBJECT_DROPPED,
    "PLACEMENT_INACCURATE": PickPlace.Result.PLACEMENT_FAILED,
    "TIMEOUT": PickPlace.Result.TIMEOUT,
    "CANCELED": PickPlace.Result.CANCELED,
    "INVALID_GOAL": PickPlace.Result.INVALID_GOAL,
}


class ArmServer(Node):
    """Serves ``/move_arm``, ``/pick_place`` and ``/arm/compute_ik`` for the robot of ``/sim``."""

    def __init__(self, robot: str, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        declare(self, (ParameterSpec("robot", robot, "robot whose arms are served", read_only=True), *PARAMETERS))
        self.robot = robot_models.load(robot)
        self.kinematics = ArmKinematics(self.robot)
        self.arms = tuple(self.kinematics.arms)
        self._ownership = GoalOwnership(first_seq=1 + (os.getpid() % 1000) * 100_000)
        group = ReentrantCallbackGroup()
        # Streams of /sim, subscribed only while a goal or a query needs them: an idle /arm receives nothing.
        self._arm_state: OnDemandTopic[ArmState] = OnDemandTopic(self, ArmState, "/sim/arm_state", 50, group,
                                                                 key=lambda msg: msg.arm)
        self._objects: OnDemandTopic[ObjectStates] = OnDemandTopic(self, ObjectStates, "/objects", 10, group)
        self._joints: OnDemandTopic[JointState] = OnDemandTopic(self, JointState, "/joint_states", 10, group)
        self._odom: OnDemandTopic[Odometry] = OnDemandTopic(self, Odometry, "/odom", 10, group)
        self._command_pub = self.create_publisher(ArmCommand, "/sim/arm_command", QoSProfile(depth=50))
        self._move_server = ActionServer(
            self, MoveArm, "/move_arm", execute_callback=guarded(self, MoveArm, self._execute_move),
            goal_callback=goal_validator(self, "MoveArm", self._validate_move), handle_accepted_callback=self._start,
            cancel_callback=lambda _goal: CancelResponse.ACCEPT, callback_group=group,
        )
        self._pick_server = ActionServer(
            self, PickPlace, "/pick_place", execute_callback=guarded(self, PickPlace, self._execute_pick),
            goal_callback=goal_validator(self, "PickPlace", self._validate_pick), handle_accepted_callback=self._start,
            cancel_callback=lambda _goal: CancelResponse.ACCEPT, callback_group=group,
        )
        self.create_service(ComputeIK, "~/compute_ik", self._compute_ik, callback_group=group)
        self.get_logger().info(f"serving /move_arm and /pick_place for {robot} arms: {', '.join(self.arms)}")

    def _param(self, name: str) -> Any:
        return self.get_parameter(name).value

    # ----- validation --------------------------------------------------------------------
    def _arm_name(self, requested: str) -> str:
        name = requested or self.robot.default_end_effector
        if name not in self.arms:
            raise GoalRejected(f"unknown end_effector {requested!r}; known: {', '.join(self.arms)} "
                               f"(empty = {self.robot.default_end_effector})")
        return name

    def _target_in_world(self, target: PoseStamped, position_only: bool) -> Pose:
        pose = pose_from_msg(target.pose)
        values = np.concatenate([pose.position, pose.orientation_wxyz])
        if not np.all(np.isfinite(values)):
            raise GoalRejected("target pose has NaN or infinite values")
        norm = float(np.linalg.norm(pose.orientation_wxyz))
        if norm < 1e-6:
            if not position_only:
                raise GoalRejected("target orientation quaternion cannot be normalised (norm 0); "
                                   "give a unit quaternion, or orientation_tolerance 0 for position only")
            quat = np.array([1.0, 0.0, 0.0, 0.0])
        else:
            quat = pose.orientation_wxyz / norm
        frame = target.header.frame_id
        if frame in WORLD_FRAMES:
            return Pose(pose.position, quat)
        if frame == self.robot.base_body:
            odom = self._odom.fresh(FRESH_TIMEOUT_S)
            if odom is None:
                raise GoalRejected(f"frame {frame!r} needs /odom, which /sim did not publish within "
                                   f"{FRESH_TIMEOUT_S:g} s (is it running, not paused?)")
            base = pose_from_msg(odom.pose.pose)
            return _compose(base, Pose(pose.position, quat))
        raise GoalRejected(f"unknown frame {frame!r}; allowed: world (or empty), odom, {self.robot.base_body}")

    def _validate_move(self, goal: MoveArm.Goal) -> tuple[str, Pose]:
        numbers = {"position_tolerance": goal.position_tolerance, "orientation_tolerance": goal.orientation_tolerance,
                   "max_velocity_scaling": goal.max_velocity_scaling, "timeout": goal.timeout}
        bad = [name for name, value in numbers.items() if not math.isfinite(value)]
        if bad:
            raise GoalRejected(f"{', '.join(bad)} must be finite numbers")
        if goal.position_tolerance <= 0.0:
            raise GoalRejected(f"position_tolerance must be > 0 m, got {goal.position_tolerance}")
        if goal.orientation_tolerance < 0.0:
            raise GoalRejected(f"orientation_tolerance must be >= 0 rad (0 = position only), got {goal.orientation_tolerance}")
        if not 0.0 <= goal.max_velocity_scaling <= 1.0:
            raise GoalRejected(f"max_velocity_scaling must be in (0, 1] (0 = default), got {goal.max_velocity_scaling}")
        if goal.timeout < 0.0:
            raise GoalRejected(f"timeout must be >= 0 s (0 = default), got {goal.timeout}")
        arm = self._arm_name(goal.end_effector)
        return arm, self._target_in_world(goal.target, goal.orientation_tolerance == 0.0)

    def _validate_pick(self, goal: PickPlace.Goal) -> tuple[str, str, Point]:
        if not self.robot.objects:
            raise GoalRejected(f"robot {self.robot.name!r} has no objects to pick")
        arm = self._arm_name(goal.end_effector)
        numbers = {"grasp_force": goal.grasp_force, "approach_height": goal.approach_height,
                   "lift_height": goal.lift_height, "timeout": goal.timeout}
        bad = [name for name, value in numbers.items() if not math.isfinite(value) or value < 0.0]
        if bad:
            raise GoalRejected(f"{', '.join(bad)} must be finite and >= 0 (0 = the parameter's default)")
        if goal.grasp_force > 70.0:
            raise GoalRejected(f"grasp_force must be <= 70 N per finger, got {goal.grasp_force}")
        name = goal.object_id
        if name:
            if name not in self.robot.objects:
                raise GoalRejected(f"unknown object {name!r}; objects: {', '.join(self.robot.objects)}")
        else:
            name = self._object_at(goal.pick_pose)
        place = goal.place_pose
        if place.header.frame_id not in WORLD_FRAMES:
            raise GoalRejected(f"place_pose frame {place.header.frame_id!r} is not allowed; use world (or empty)")
        p = place.pose.position
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
            raise GoalRejected("place_pose has NaN or infinite values")
        return arm, name, Point(x=p.x, y=p.y, z=p.z)

    def _object_at(self, pick_pose: PoseStamped) -> str:
        p = pick_pose.pose.position
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
            raise GoalRejected("give object_id, or a finite pick_pose")
        objects = self._objects.fresh(FRESH_TIMEOUT_S)
        if objects is None:
            raise GoalRejected(f"no /objects from /sim within {FRESH_TIMEOUT_S:g} s (is it running?); give object_id")
        distances = {name: math.dist((p.x, p.y, p.z), (o.position.x, o.position.y, o.position.z))
                     for name, o in zip(objects.names, objects.poses, strict=False)}
        name, distance = min(distances.items(), key=lambda item: item[1])
        if distance > 0.03:
            raise GoalRejected(f"no object within 3 cm of pick_pose (nearest: {name} at {distance:.3f} m)")
        return name

    # ----- goal ownership and preemption --------------------------------------------------
    def _start(self, goal_handle: ServerGoalHandle) -> None:
        goal_handle.execute()

    def _send(self, command: ArmCommand) -> None:
        command.header.stamp = self.get_clock().now().to_msg()
        self._command_pub.publish(command)

    def _hold(self, arm: str, seq: int) -> None:
        self._send(ArmCommand(arm=arm, goal_seq=seq, mode=ArmCommand.HOLD, gripper_width=-1.0))

    def _wait_state(self, arm: str, seq: int, timeout_s: float, command: ArmCommand) -> ArmState | None:
        """The first state that reflects command ``seq`` (None if /sim did not answer).

        The command is sent again every second until /sim confirms it: a command published
        before discovery matched this publisher with /sim's subscription is lost.
        """
        for tick in range(1, int(timeout_s / 0.1) + 1):
            state = self._arm_state.latest.get(arm)
            if state is not None and state.goal_seq == seq:
                return state
            self._arm_state.latest.wait_next(0.1)
            if tick % 10 == 0:
                self._send(command)
        return None

    # ----- MoveArm -----------------------------------------------------------------------
    def _execute_move(self, goal_handle: ServerGoalHandle) -> MoveArm.Result:
        goal: MoveArm.Goal = goal_handle.request
        result = MoveArm.Result()
        try:
            arm, target = self._validate_move(goal)
        except GoalRejected as reason:  # the world changed since acceptance (e.g. /odom frame)
            return self._finish(goal_handle, result, MoveArm.Result.INVALID_GOAL, str(reason), abort=True)
        scaling = goal.max_velocity_scaling or float(self._param("max_velocity_scaling"))
        timeout = goal.timeout or float(self._param("move_timeout"))
        position_only = goal.orientation_tolerance == 0.0
        owner = self._ownership.claim(arm)
        command = ArmCommand(arm=arm, goal_seq=owner.seq, mode=ArmCommand.TRACK, position_only=position_only,
                             max_linear_speed=scaling * float(self._param("max_linear_speed")),
                             max_angular_speed=scaling * float(self._param("max_angular_speed")), gripper_width=-1.0)
        command.target = pose_msg(target)
        try:
            with self._arm_state.held():
                self._send(command)
                return self._supervise_move(goal_handle, goal, arm, owner, target, timeout, result, command)
        finally:
            self._ownership.release(arm, owner)

    def _supervise_move(self, goal_handle: ServerGoalHandle, goal: MoveArm.Goal, arm: str, owner: ActiveGoal,
                        target: Pose, timeout: float, result: MoveArm.Result, command: ArmCommand) -> MoveArm.Result:
        first = self._wait_state(arm, owner.seq, ACK_TIMEOUT_S, command)
        if first is None:
            return self._finish(goal_handle, result, MoveArm.Result.SIM_FAULT,
                                "no answer from /sim on /sim/arm_state: is the sim node running?", abort=True)
        start_time = seconds_of(first.header.stamp)
        start_distance = max(float(np.linalg.norm(_position(first.current) - target.position)), 1e-9)
        feedback_period = 1.0 / float(self._param("feedback_rate"))
        last_feedback = -math.inf
        within = 0
        state = first
        while True:
            self._fill_move(result, state)
            interrupted = self._interrupted(goal_handle, arm, owner, state, result, MoveArm.Result)
            if interrupted is not None:
                return interrupted
            now = seconds_of(state.header.stamp)
            if state.unreachable:
                self._fill_move(result, state)
                return self._finish(goal_handle, result, MoveArm.Result.UNREACHABLE, f"unreachable: {state.message}", abort=True)
            orientation_ok = goal.orientation_tolerance == 0.0 or state.orientation_error <= goal.orientation_tolerance
            within = within + 1 if (state.percent_complete >= 100.0 and state.position_error <= goal.position_tolerance
                                    and orientation_ok) else 0
            if within >= 2:
                self._fill_move(result, state)
                return self._finish(goal_handle, result, MoveArm.Result.SUCCESS, "reached the target")
            if now - start_time > timeout:
                self._hold(arm, owner.seq)
                self._fill_move(result, state)
                return self._finish(goal_handle, result, MoveArm.Result.TIMEOUT,
                                    f"timed out after {timeout:.1f} s of sim time, "
                                    f"{state.position_error * 1e3:.1f} mm from the target",
                                    abort=True)
            if now - last_feedback >= feedback_period:
                last_feedback = now
                feedback = MoveArm.Feedback()
                feedback.current_pose = _stamped(state.current, state.header.stamp)
                feedback.position_error = state.position_error
                feedback.orientation_error = state.orientation_error
                feedback.distance_remaining = state.position_error
                feedback.percent_complete = float(min(100.0, max(0.0, 100.0 * (1.0 - state.position_error / start_distance))))
                feedback.elapsed = duration_msg(now - start_time)
                goal_handle.publish_feedback(feedback)
            self._arm_state.latest.wait_next(1.0)
            state = self._arm_state.latest.get(arm) or state

    def _interrupted(self, goal_handle: ServerGoalHandle, arm: str, owner: ActiveGoal, state: ArmState, result: Any,
                     codes: Any) -> Any:
        """End the goal if it was preempted, canceled (the arm then holds) or the sim was reset; else None."""
        if owner.preempted.is_set():
            return self._finish(goal_handle, result, codes.PREEMPTED, "preempted by a newer goal on this arm", abort=True)
        if goal_handle.is_cancel_requested:
            self._hold(arm, owner.seq)
            return self._finish(goal_handle, result, codes.CANCELED, "canceled: the arm holds where it is", cancel=True)
        if state.goal_seq != owner.seq:
            return self._finish(goal_handle, result, codes.SIM_FAULT, "the simulation was reset during the goal", abort=True)
        return None

    @staticmethod
    def _fill_move(result: MoveArm.Result, state: ArmState) -> None:
        result.final_pose = _stamped(state.current, state.header.stamp)
        result.final_position_error = state.position_error
        result.final_orientation_error = state.orientation_error

    def _finish(self, goal_handle: ServerGoalHandle, result: Any, code: int, message: str,
                abort: bool = False, cancel: bool = False) -> Any:
        return finish_goal(self, goal_handle, result, code, message, abort=abort, cancel=cancel)

    # ----- PickPlace ---------------------------------------------------------------------
    def _execute_pick(self, goal_handle: ServerGoalHandle) -> PickPlace.Result:
        goal: PickPlace.Goal = goal_handle.request
        result = PickPlace.Result()
        try:
            arm, name, place = self._validate_pick(goal)
        except GoalRejected as reason:
            return self._finish(goal_handle, result, PickPlace.Result.INVALID_GOAL, str(reason), abort=True)
        timeout = goal.timeout or float(self._param("pick_place_timeout"))
        owner = self._ownership.claim(arm)
        command = ArmCommand(
            arm=arm, goal_seq=owner.seq, mode=ArmCommand.PICK_PLACE, object_id=name, place_position=place,
            gripper_force=goal.grasp_force or float(self._param("gripper_force")),
            approach_height=goal.approach_height or float(self._param("approach_height")),
            lift_height=goal.lift_height or float(self._param("lift_height")),
            placement_tolerance=float(self._param("placement_tolerance")), gripper_width=-1.0,
        )
        try:
            with self._arm_state.held():
                self._send(command)
                return self._supervise_pick(goal_handle, arm, owner, place, timeout, result, command)
        finally:
            self._ownership.release(arm, owner)

    def _supervise_pick(self, goal_handle: ServerGoalHandle, arm: str, owner: ActiveGoal, place: Point,
                        timeout: float, result: PickPlace.Result, command: ArmCommand) -> PickPlace.Result:
        state = self._wait_state(arm, owner.seq, ACK_TIMEOUT_S, command)
        if state is None:
            return self._finish(goal_handle, result, PickPlace.Result.SIM_FAULT,
                                "no answer from /sim on /sim/arm_state: is the sim node running?", abort=True)
        start_time = seconds_of(state.header.stamp)
        feedback_period = 1.0 / float(self._param("feedback_rate"))
        last_feedback = -math.inf
        last_stage = -1  # every stage change is reported, whatever the feedback rate
        while True:
            self._fill_pick(result, state)
            interrupted = self._interrupted(goal_handle, arm, owner, state, result, PickPlace.Result)
            if interrupted is not None:
                return interrupted
            now = seconds_of(state.header.stamp)
            if state.done or now - last_feedback >= feedback_period or state.stage != last_stage:
                last_feedback, last_stage = now, state.stage
                feedback = PickPlace.Feedback(stage=state.stage, stage_name=state.stage_name,
                                              stage_progress=state.stage_progress, percent_complete=state.percent_complete)
                feedback.object_pose = _stamped(state.object_pose, state.header.stamp)
                feedback.elapsed = duration_msg(now - start_time)
                goal_handle.publish_feedback(feedback)
            if state.done:
                self._fill_pick(result, state)
                if state.success:
                    return self._finish(goal_handle, result, PickPlace.Result.SUCCESS,
                                        f"placed within {state.placement_error * 1e3:.1f} mm")
                code = PICK_PLACE_CODES.get(state.failure, PickPlace.Result.SIM_FAULT)
                return self._finish(goal_handle, result, code, f"{state.failure.lower()}: {state.message}", abort=True)
            if now - start_time > timeout:
                self._hold(arm, owner.seq)
                self._fill_pick(result, state)
                return self._finish(goal_handle, result, PickPlace.Result.TIMEOUT,
                                    f"timed out after {timeout:.1f} s of sim time in stage {state.stage_name}", abort=True)
            self._arm_state.latest.wait_next(1.0)
            state = self._arm_state.latest.get(arm) or state

    @staticmethod
    def _fill_pick(result: PickPlace.Result, state: ArmState) -> None:
        result.final_object_pose = _stamped(state.object_pose, state.header.stamp)
        result.placement_error = state.placement_error

    # ----- IK query ----------------------------------------------------------------------
    def _compute_ik(self, request: ComputeIK.Request, response: ComputeIK.Response) -> ComputeIK.Response:
        response.success = False
        try:
            arm = self._arm_name(request.end_effector)
            target = self._target_in_world(request.target, request.position_only)
            qpos = self._current_qpos()
            solution = self.kinematics.solve(arm, qpos, target, request.position_only)
        except (GoalRejected, SimError) as error:
            response.message = str(error)
            return response
        response.success = solution.success
        response.message = solution.reason or "solved"
        response.joint_names = list(solution.joint_names)
        response.positions = [float(v) for v in solution.positions]
        response.position_error = float(solution.position_error)
        response.orientation_error = float(solution.orientation_error)
        return response

    def _current_qpos(self) -> np.ndarray:
        """Full qpos of the robot from /joint_states (and /odom for a floating base)."""
        model = self.robot.model
        qpos = model.key(self.robot.default_keyframe).qpos.copy()
        joints = self._joints.fresh(FRESH_TIMEOUT_S)
        if joints is None:
            raise GoalRejected(f"no /joint_states from /sim within {FRESH_TIMEOUT_S:g} s: is it running, not paused? "
                               "(the IK starts from the current joint state)")
        for name, value in zip(joints.name, joints.position, strict=False):
            qpos[model.joint(name).qposadr[0]] = value
        if self.robot.floating_base:
            odom = self._odom.fresh(FRESH_TIMEOUT_S)
            if odom is None:
                raise GoalRejected(f"no /odom from /sim within {FRESH_TIMEOUT_S:g} s: is it running, not paused?")
            adr = model.joint(model.body(self.robot.base_body).jntadr[0]).qposadr[0]
            base = pose_from_msg(odom.pose.pose)
            qpos[adr:adr + 3] = base.position
            qpos[adr + 3:adr + 7] = base.orientation_wxyz
        return qpos


def _position(pose_msg_: Any) -> np.ndarray:
    return np.array([pose_msg_.position.x, pose_msg_.position.y, pose_msg_.position.z])


def _stamped(pose: Any, stamp: Any) -> PoseStamped:
    msg = PoseStamped(pose=pose)
    msg.header.frame_id = "world"
    msg.header.stamp = stamp
    return msg


def _compose(parent: Pose, child: Pose) -> Pose:
    """``child`` given in ``parent``'s frame, expressed in the world frame."""
    import mujoco

    rotation = np.empty(9)
    mujoco.mju_quat2Mat(rotation, parent.orientation_wxyz)
    quat = np.empty(4)
    mujoco.mju_mulQuat(quat, parent.orientation_wxyz, child.orientation_wxyz)
    return Pose(parent.position + rotation.reshape(3, 3) @ child.position, quat)


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``arm_server [--ros-args -p robot:=panda]``."""
    return spin_server(lambda robot, overrides: ArmServer(robot, parameter_overrides=overrides), NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
