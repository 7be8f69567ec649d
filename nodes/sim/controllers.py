"""ROS side of the in-loop controllers: /cmd_vel, the gait parameters, and the goal skills' hosts.

The controllers live in ``sim_bridge`` and run inside the control step; this module installs them
(each behind a :class:`~sim_bridge.skills.SkillHost` that runs the goals of the action servers,
reached through :class:`~nodes.sim.skills.SkillBridge`), applies the /cmd_vel timeout, declares
the gait parameters, and publishes the controllers' state (only while someone listens, so an idle
robot costs nothing).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter

from nodes.runtime.parameters import ParameterSpec, declare
from nodes.servers.protocol import SkillContext
from nodes.sim.camera import CameraStreams
from nodes.sim.goal_visuals import GoalVisualsPublisher
from nodes.sim.handoff import HandOffLock
from nodes.sim.publication import RELIABLE
from nodes.sim.sensors import SensorStreams
from nodes.sim.skills import SkillBridge
from sim_bridge import SimError, Simulation, Slot
from sim_bridge.arm import ArmController, PickPlace
from sim_bridge.battery import Battery, BatteryConfig, BatteryMeter, Metered
from sim_bridge.locomotion import PARAMETER_RANGES, GaitParameters, LocomotionMode, WalkingController
from sim_bridge.navigation import grid_from_obstacles
from sim_bridge.skills import LEGS, SkillHost
from sim_interfaces.msg import LocomotionState
from sim_ros.names import CMD_VEL_STAMPED_TOPIC, CMD_VEL_TOPIC
from sim_ros.stamps import set_time

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

    def __init__(self, node: Node, sim: Simulation, lock: HandOffLock) -> None:
        self._node = node
        self._sim = sim
        self._lock = lock
        self._cmd_vel_time = -math.inf
        self._cmd_vel_live = False
        self._warned_no_locomotion = False
        self._warned_busy = False
        self._qp_fallbacks_reported = 0
        node.create_subscription(Twist, CMD_VEL_TOPIC, self._on_cmd_vel, RELIABLE, callback_group=ReentrantCallbackGroup())
        node.create_subscription(TwistStamped, CMD_VEL_STAMPED_TOPIC, self._on_cmd_vel_stamped, 10,
                                 callback_group=ReentrantCallbackGroup())

        self.walking: WalkingController | None = None
        hosts: dict[str, SkillHost] = {}
        context = SkillContext(sim)
        pack = sim.robot.sensors.battery
        # The battery is drained where the physics runs by a meter in the legs' slot: every control step while the legs
        # are driven, at the end of each batch of physics steps while they stand (deterministic).
        self.battery = Battery(BatteryConfig.of(pack)) if pack is not None and sim.robot.feet_sites else None
        context.battery = self.battery
        if sim.robot.feet_sites:
            self.walking = WalkingController(sim.model, sim.robot.biped)
            legs = SkillHost(self.walking)  # Walk, NavigateToPose and ResetPose run in front of the walker
            sim.set_controller(Slot.LOCOMOTION, legs if self.battery is None else Metered(legs, BatteryMeter(self.battery)))
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
        if sim.robot.end_effector_sites:
            self.arms = ArmController(sim.robot)
            context.arms = self.arms
            inner: ArmController | PickPlace = self.arms
            if sim.robot.objects and sim.robot.grasp is not None:  # objects and grippers to pick them with
                context.pick_place = inner = PickPlace(self.arms)
            arms = SkillHost(inner)  # MoveArm and PickPlace run in front of the arm controller; one goal per arm
            sim.set_controller(Slot.ARM, arms)
            hosts.update({arm: arms for arm in self.arms.arms})
        self.skills = SkillBridge(node, sim, lock, hosts, context)
        self.visuals = GoalVisualsPublisher(node)
        self.sensors = SensorStreams(node, sim, lock, self.battery)
        self.cameras = CameraStreams(node, sim, lock)

    # ----- /cmd_vel ----------------------------------------------------------------------
    def _on_cmd_vel(self, msg: Twist) -> None:
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
            self._cmd_vel_time = self._sim.time
            self._cmd_vel_live = True
            self.walking.set_velocity_command(vx, vy, wz)

    def before_step(self, now: float) -> None:
        """Under the lock, before each stretch of stepping: expire a stale /cmd_vel."""
        if self._cmd_vel_live and now - self._cmd_vel_time > float(self._node.get_parameter("cmd_vel_timeout").value):
            self._cmd_vel_live = False
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
        changes: dict[str, Any] = {p.name[len(GAIT_PREFIX):]: float(p.value) for p in parameters
                                   if p.name.startswith(GAIT_PREFIX)}
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
        self.sensors.on_parameters(parameters)

    # ----- state publishing and resets ---------------------------------------------------
    def after_step(self) -> int:
        """Under the lock, after each stretch of stepping: goals that started or ended are reported at once.

        Returns how many goals ended.
        """
        now = self._sim.time
        self.sensors.publish_due(now)
        self.cameras.publish_due(now)
        ended = self.skills.publish_changed()
        self.visuals.update(self.skills.runs(), now)
        return ended

    def publish_state(self, now: float) -> None:
        """Under the lock, when controller state topics are due."""
        self.skills.publish_all()
        self.sensors.publish_battery(now)
        if self.walking is not None and self.walking.qp_fallback_count != self._qp_fallbacks_reported:
            grew = self.walking.qp_fallback_count > self._qp_fallbacks_reported
            self._qp_fallbacks_reported = self.walking.qp_fallback_count  # a silent failure made visible
        else:
            grew = False
        if grew:
            self._node.get_logger().warning(
                f"the walking torque QP failed in {self._qp_fallbacks_reported} control steps so far "
                "(the previous contact forces were reused); see gait parameters or the last push")
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
            msg.qp_fallbacks = self.walking.qp_fallback_count
            self._locomotion_pub.publish(msg)

    def on_reset(self) -> None:
        """Under the lock, after the simulation was reset (the controllers were reset by it)."""
        self._cmd_vel_time = -math.inf
        self._cmd_vel_live = False
        self.sensors.on_reset()
        self.cameras.on_reset()
        self.skills.publish_changed()  # the goals the reset ended, at once
        self.visuals.update(self.skills.runs(), self._sim.time)

    def on_fault(self, reason: str) -> None:
        self.on_reset()
