"""ROS side of the in-loop controllers: routes /cmd_vel and arm commands into the simulation.

The controllers live in ``sim_bridge`` and run inside the control step; this module converts
messages, applies the /cmd_vel timeout, declares the gait parameters, and publishes the
controllers' state (only while someone listens, so an idle robot costs nothing).
"""

from __future__ import annotations

import dataclasses
import math
import threading

from geometry_msgs.msg import Twist, TwistStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile

from nodes.conversions import pose_from_msg, set_pose, set_time
from nodes.parameters import ParameterSpec, declare
from nodes.skill_bridge import SkillBridge
from nodes.skill_protocol import SkillContext
from sim_bridge import SimError, Simulation, Slot
from sim_bridge.arm import ArmController, PickPlace, PickPlaceGoal, PickPlaceProgress
from sim_bridge.locomotion import PARAMETER_RANGES, GaitParameters, LocomotionMode, WalkingController
from sim_bridge.navigation import grid_from_obstacles
from sim_bridge.skills import LEGS, SkillHost
from sim_interfaces.msg import ArmCommand, ArmState, LocomotionState

COMMAND_QOS = QoSProfile(depth=50)
LOCOMOTION_MODES = {
    LocomotionMode.STANDING: LocomotionState.STANDING,
    LocomotionMode.WALKING: LocomotionState.WALKING,
    LocomotionMode.STOPPING: LocomotionState.STOPPING,
    LocomotionMode.FALLEN: LocomotionState.FALLEN,
}
GAIT_PREFIX = "gait."


class InLoopPlugins:
    """Connects the simulation's controller slots to topics, for one robot.

    Args:
        node: the sim node (publishers and subscriptions are created on it).
        sim: the simulation whose controller slots are used.
        lock: the lock that guards ``sim``. ``before_step``/``publish_state``/``on_*`` hooks are
            called with it held; message callbacks take it themselves.
    """

    def __init__(self, node: Node, sim: Simulation, lock: threading.RLock) -> None:
        self._node = node
        self._sim = sim
        self._lock = lock
        self._cmd_vel = (0.0, 0.0, 0.0)
        self._cmd_vel_time = -math.inf
        self._cmd_vel_live = False
        self._warned_no_locomotion = False
        self._warned_busy = False
        group = ReentrantCallbackGroup()
        node.create_subscription(TwistStamped, "/cmd_vel_stamped", self._on_cmd_vel_stamped, 10, callback_group=group)

        self.walking: WalkingController | None = None
        hosts: dict[str, SkillHost] = {}
        context = SkillContext(sim.robot)
        if sim.robot.feet_sites:
            self.walking = WalkingController(sim.model)
            legs = SkillHost(self.walking)  # Walk and NavigateToPose run in front of the walker
            sim.set_controller(Slot.LOCOMOTION, legs)
            hosts[LEGS] = legs
            context.walker = self.walking
            context.grid = grid_from_obstacles(sim.robot.obstacles)
            declare(node, tuple(
                ParameterSpec(GAIT_PREFIX + name, float(getattr(self.walking.params, name)), description, low, high)
                for name, (low, high, description) in PARAMETER_RANGES.items()
            ))
            node.add_on_set_parameters_callback(self._validate_gait)
            self._locomotion_pub = node.create_publisher(LocomotionState, "~/locomotion_state", 10)
            self._locomotion_msg = LocomotionState()

        self.arms: ArmController | None = None
        self.skill: PickPlace | None = None
        self._arm_seq: dict[str, int] = {}
        self._arm_mode: dict[str, int] = {}
        self._skill_arm: str | None = None
        self._skill_error: dict[str, str] = {}
        if sim.robot.end_effector_sites:
            self.arms = ArmController(sim.robot)
            if sim.robot.objects:
                self.skill = PickPlace(self.arms)
                sim.set_controller(Slot.ARM, self.skill)
            else:
                sim.set_controller(Slot.ARM, self.arms)
            self._arm_seq = {arm: 0 for arm in self.arms.arms}
            self._arm_mode = {arm: ArmCommand.HOLD for arm in self.arms.arms}
            node.create_subscription(ArmCommand, "~/arm_command", self._on_arm_command, COMMAND_QOS, callback_group=group)
            self._arm_pub = node.create_publisher(ArmState, "~/arm_state", 10)
        self.skills = SkillBridge(node, sim, lock, hosts, context)

    # ----- /cmd_vel ----------------------------------------------------------------------
    def on_cmd_vel(self, msg: Twist) -> None:
        self._take_cmd_vel(msg.linear.x, msg.linear.y, msg.angular.z)

    def _on_cmd_vel_stamped(self, msg: TwistStamped) -> None:
        self._take_cmd_vel(msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z)

    def _take_cmd_vel(self, vx: float, vy: float, wz: float) -> None:
        if self.walking is None:
            if not self._warned_no_locomotion:
                self._warned_no_locomotion = True
                self._node.get_logger().warning(
                    f"/cmd_vel received but robot {self._sim.robot.name!r} has no locomotion controller; ignored")
            return
        if not all(math.isfinite(v) for v in (vx, vy, wz)):
            self._node.get_logger().warning(f"/cmd_vel ({vx}, {vy}, {wz}) is not finite; ignored")
            return
        with self._lock:
            if self.skills.busy(LEGS):
                if not self._warned_busy:
                    self._warned_busy = True
                    self._node.get_logger().warning(
                        "/cmd_vel ignored: a Walk or NavigateToPose goal drives the legs (cancel it to teleoperate)")
                return
            self._warned_busy = False
            self._cmd_vel = (vx, vy, wz)
            self._cmd_vel_time = self._sim.time
            self._cmd_vel_live = True
            self.walking.set_velocity_command(vx, vy, wz)

    def before_step(self, now: float) -> None:
        """Under the lock, before each stretch of stepping: expire a stale /cmd_vel."""
        if self._cmd_vel_live and now - self._cmd_vel_time > float(self._node.get_parameter("cmd_vel_timeout").value):
            self._cmd_vel_live = False
            self._cmd_vel = (0.0, 0.0, 0.0)
            if self.walking is not None and not self.skills.busy(LEGS):
                self.walking.set_velocity_command(0.0, 0.0, 0.0)

    @property
    def max_chunk(self) -> float:
        """Longest sim time [s] to step before ``before_step`` must run again."""
        if self._cmd_vel_live:
            return float(self._node.get_parameter("cmd_vel_timeout").value) / 4.0
        return math.inf

    # ----- gait parameters ---------------------------------------------------------------
    def _gait_from(self, parameters: list[Parameter]) -> GaitParameters | None:
        assert self.walking is not None
        changes = {p.name[len(GAIT_PREFIX):]: float(p.value) for p in parameters if p.name.startswith(GAIT_PREFIX)}
        if not changes:
            return None
        return dataclasses.replace(self.walking.params, **changes)

    def _validate_gait(self, parameters: list[Parameter]) -> SetParametersResult:
        try:
            self._gait_from(parameters)
        except (SimError, TypeError, ValueError) as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def on_parameters(self, parameters: list[Parameter]) -> None:
        """Under the lock, after parameters of the sim node changed."""
        if self.walking is not None:
            params = self._gait_from(parameters)
            if params is not None:
                self.walking.set_gait_parameters(params)

    # ----- arm commands ------------------------------------------------------------------
    def _on_arm_command(self, msg: ArmCommand) -> None:
        assert self.arms is not None
        arm = msg.arm
        with self._lock:
            self._skill_error.pop(arm, None)
            try:
                self._apply_arm_command(msg)
            except SimError as error:
                self._skill_error[arm] = str(error)
                self._node.get_logger().warning(f"arm command {msg.goal_seq} on {arm!r} refused: {error}")
            if arm in self._arm_seq:
                self._arm_seq[arm] = msg.goal_seq
                self._arm_mode[arm] = msg.mode
            if self._arm_pub.get_subscription_count() > 0:
                self._publish_arm(arm, self._sim.time)

    def _apply_arm_command(self, msg: ArmCommand) -> None:
        assert self.arms is not None
        arm = msg.arm
        if self._skill_arm == arm and msg.mode != ArmCommand.PICK_PLACE and self.skill is not None:
            self.skill.cancel()
            self._skill_arm = None
        if msg.mode == ArmCommand.TRACK:
            self.arms.set_target(arm, pose_from_msg(msg.target), msg.position_only,
                                 msg.max_linear_speed or None, msg.max_angular_speed or None)
            if msg.gripper_width >= 0.0:
                self.arms.set_gripper(arm, msg.gripper_width, msg.gripper_force or 20.0)
        elif msg.mode == ArmCommand.HOLD:
            self.arms.hold(arm)
        elif msg.mode == ArmCommand.GRIPPER:
            self.arms.set_gripper(arm, msg.gripper_width, msg.gripper_force or 20.0)
        elif msg.mode == ArmCommand.PICK_PLACE:
            if self.skill is None:
                raise SimError(f"robot {self._sim.robot.name!r} has no objects to pick")
            p = msg.place_position
            goal = PickPlaceGoal(
                object_name=msg.object_id, place_position=(p.x, p.y, p.z), arm=arm,
                **{k: v for k, v in (("approach_height", msg.approach_height), ("lift_height", msg.lift_height),
                                      ("grip_force", msg.gripper_force), ("placement_tolerance", msg.placement_tolerance),
                                      ("transport_speed", msg.max_linear_speed)) if v > 0.0},
            )
            self.skill.start(goal)
            self._skill_arm = arm
        else:
            raise SimError(f"unknown arm command mode {msg.mode}; modes: TRACK=0, HOLD=1, GRIPPER=2, PICK_PLACE=3")

    def _publish_arm(self, arm: str, now: float) -> None:
        assert self.arms is not None
        status = self.arms.status(arm)
        msg = ArmState(arm=arm, goal_seq=self._arm_seq[arm], mode=self._arm_mode[arm])
        set_time(msg.header.stamp, now)
        set_pose(msg.current, status.tool_pose.position, status.tool_pose.orientation_wxyz)
        set_pose(msg.target, status.target_pose.position, status.target_pose.orientation_wxyz)
        msg.position_error = status.position_error
        msg.orientation_error = status.orientation_error
        msg.settled = status.settled
        msg.unreachable = status.unreachable
        msg.message = status.reason
        msg.percent_complete = float(100.0 * status.progress)
        msg.gripper_width = status.gripper.width if status.gripper is not None else 0.0
        msg.placement_error = math.nan
        error = self._skill_error.get(arm)
        if error is not None:
            msg.done, msg.success, msg.failure, msg.message = True, False, "INVALID_GOAL", error
        elif self.skill is not None and self._skill_arm == arm:
            self._fill_skill(msg, self.skill.progress())
        self._arm_pub.publish(msg)

    @staticmethod
    def _fill_skill(msg: ArmState, progress: PickPlaceProgress) -> None:
        msg.stage = int(progress.stage)
        msg.stage_name = progress.stage.name
        msg.stage_progress = float(progress.stage_progress)
        msg.percent_complete = float(progress.percent)
        msg.done = progress.done
        msg.success = progress.success
        msg.failure = "" if progress.success or not progress.done else progress.failure.name
        if progress.reason:
            msg.message = progress.reason
        set_pose(msg.object_pose, progress.object_pose.position, progress.object_pose.orientation_wxyz)
        msg.placement_error = float(progress.placement_error)
        msg.object_lift = float(progress.object_lift)

    # ----- state publishing and resets ---------------------------------------------------
    def after_step(self) -> int:
        """Under the lock, after each stretch of stepping: goals that started or ended are reported at once.

        Returns how many goals ended.
        """
        return self.skills.publish_changed()

    def publish_state(self, now: float) -> None:
        """Under the lock, when controller state topics are due."""
        self.skills.publish_all()
        if self.walking is not None and self._locomotion_pub.get_subscription_count() > 0:
            status = self.walking.status()
            msg = self._locomotion_msg
            set_time(msg.header.stamp, now)
            msg.mode = LOCOMOTION_MODES[status.mode]
            msg.mode_name = status.mode.name
            msg.steps_taken = int(status.steps_taken)
            msg.command.linear.x, msg.command.linear.y = status.commanded.vx, status.commanded.vy
            msg.command.angular.z = status.commanded.wz
            msg.measured.linear.x, msg.measured.linear.y = status.measured.vx, status.measured.vy
            msg.measured.angular.z = status.measured.wz
            msg.message = status.message
            self._locomotion_pub.publish(msg)
        if self.arms is not None and self._arm_pub.get_subscription_count() > 0:
            for arm in self.arms.arms:
                self._publish_arm(arm, now)

    def on_reset(self) -> None:
        """Under the lock, after the simulation was reset (the controllers were reset by it)."""
        self._cmd_vel = (0.0, 0.0, 0.0)
        self._cmd_vel_time = -math.inf
        self._cmd_vel_live = False
        self._skill_arm = None
        self._skill_error.clear()
        for arm in self._arm_seq:
            self._arm_seq[arm] = 0
            self._arm_mode[arm] = ArmCommand.HOLD
        self.skills.publish_changed()  # the goals the reset ended, at once

    def on_fault(self, reason: str) -> None:
        self.on_reset()
