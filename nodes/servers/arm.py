"""The ``/arm`` node: MoveArm and PickPlace action servers and an IK query service.

Both actions run as skills inside ``/sim``'s control step (:mod:`sim_bridge.skills.arm`: tool
tracking with mink IK, the pick-and-place stages and the friction grasp); this node validates,
relays and owns the parameters. One goal per arm: a new goal preempts the running one.
"""

from __future__ import annotations

import sys
import threading
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from nav_msgs.msg import Odometry
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from sensor_msgs.msg import JointState

import robot_models
from nodes.runtime.parameters import ParameterSpec, declare
from nodes.runtime.serve import SCENE_PARAMETER, spin_server
from nodes.runtime.startup import help_text
from nodes.runtime.streams import OnDemandTopic
from nodes.servers.actions import ARM_ACTIONS
from nodes.servers.protocol import ARM_SETTINGS, arm_name
from nodes.servers.server import end_goals_before_exit, skill_servers
from sim_bridge.errors import InvalidGoalError, SimError
from sim_bridge.frames import check_frame, to_world
from sim_bridge.state import Pose
from sim_interfaces.srv import ComputeIK
from sim_ros.conversions import pose_from_msg
from sim_ros.names import JOINT_STATES_TOPIC, ODOM_TOPIC

if TYPE_CHECKING:
    from sim_bridge.arm import ArmKinematics

NODE_NAME = "arm"
ACTIONS = ARM_ACTIONS  # skill -> the action that serves it
FRESH_TIMEOUT_S = 2.0  # wall seconds to wait for a first message of a stream subscribed on demand


class GoalRejected(Exception):
    """A query that cannot be answered now (no state from /sim); the message says why."""


def parameters(robot: robot_models.RobotSpec) -> tuple[ParameterSpec, ...]:
    """The node's parameters (defaults shared with the skills: ``ARM_SETTINGS``); grasp limits from the spec."""
    max_force = robot.grasp.max_force_n if robot.grasp is not None else 70.0
    default = ARM_SETTINGS
    return (
        ParameterSpec("max_velocity_scaling", default["max_velocity_scaling"],
                      "default fraction of the tool speed limits for MoveArm", 0.01, 1.0),
        ParameterSpec("max_linear_speed", default["max_linear_speed"], "tool speed at velocity scaling 1 [m/s]", 0.05, 2.0),
        ParameterSpec("max_angular_speed", default["max_angular_speed"], "tool angular speed at velocity scaling 1 [rad/s]",
                      0.1, 6.0),
        ParameterSpec("feedback_rate", 10.0, "action feedback rate [Hz of sim time]", 1.0, 100.0),
        ParameterSpec("gripper_force", robot.grasp.default_force_n if robot.grasp else default["gripper_force"],
                      "squeeze force per finger for PickPlace [N]", 2.0, max_force),
        ParameterSpec("approach_height", default["approach_height"], "PickPlace approach height above the object [m]",
                      0.03, 0.30),
        ParameterSpec("lift_height", default["lift_height"], "PickPlace lift height above the table [m]", 0.02, 0.30),
        ParameterSpec("placement_tolerance", default["placement_tolerance"], "PickPlace placement error counted as success [m]",
                      0.001, 0.05),
        ParameterSpec("move_timeout", default["move_timeout"], "MoveArm timeout when a goal gives 0 [s of sim time]", 1.0, 600.0),
        ParameterSpec("pick_place_timeout", default["pick_place_timeout"],
                      "PickPlace timeout when a goal gives 0 [s of sim time]", 5.0, 600.0),
    )


class ArmServer(Node):
    """Serves ``/move_arm``, ``/pick_place`` and ``/arm/compute_ik`` for the robot of ``/sim``."""

    def __init__(self, robot: str, scene: str = "", **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        # Goals are validated and frames resolved on the light model (the scene's objects: goals may name
        # them); the IK runs on its own model, built from the robot with its visuals, which is let go.
        self.robot = robot_models.load(robot, scene or None, visuals=False)
        self._robot_name, self._scene = robot, scene
        declare(self, (ParameterSpec("robot", robot, "robot whose arms are served", read_only=True),
                       ParameterSpec("scene", scene, "scene of /sim (its objects); empty = the robot's default", read_only=True),
                       *parameters(self.robot)))
        self.arms = tuple(self.robot.end_effector_sites)
        # Built at the first IK query (it compiles the robot twice more: about half this node's start-up CPU
        # and 90 MB), which most runs never send: the actions' IK runs inside /sim.
        self._kinematics: ArmKinematics | None = None
        self._kinematics_lock = threading.Lock()
        self._servers = skill_servers(self, self.robot, ACTIONS,
                                      self._settings, lambda: 1.0 / float(self.get_parameter("feedback_rate").value),
                                      self._scene_loaded)
        group = ReentrantCallbackGroup()
        # The IK query starts from the current state: streams of /sim subscribed only while a query needs them.
        self._joints: OnDemandTopic[JointState] = OnDemandTopic(self, JointState, JOINT_STATES_TOPIC, 10, group)
        self._odom: OnDemandTopic[Odometry] = OnDemandTopic(self, Odometry, ODOM_TOPIC, 10, group)
        self.create_service(ComputeIK, "~/compute_ik", self._compute_ik, callback_group=group)
        self.get_logger().info(f"serving /move_arm and /pick_place for {robot} arms: {', '.join(self.arms)}")

    def _settings(self) -> dict[str, float]:
        return {name: float(self.get_parameter(name).value) for name in ARM_SETTINGS}

    def _scene_loaded(self, spec: robot_models.RobotSpec) -> None:
        """/sim loaded another scene: goals and IK queries use it (the IK model is built again when next asked)."""
        with self._kinematics_lock:
            self.robot, self._scene, self._kinematics = spec, spec.scene, None

    # ----- IK query ----------------------------------------------------------------------
    @property
    def kinematics(self) -> ArmKinematics:
        """The IK model and problems of the robot's arms, built at the first use."""
        with self._kinematics_lock:
            if self._kinematics is None:
                from sim_bridge.arm import ArmKinematics  # imports mink: only a node that answers IK needs it

                self._kinematics = ArmKinematics(robot_models.load(self._robot_name, self._scene or None))
            return self._kinematics

    def _compute_ik(self, request: ComputeIK.Request, response: ComputeIK.Response) -> ComputeIK.Response:
        response.success = False
        try:
            arm = arm_name(request.end_effector, self.robot)
            qpos = self._current_qpos()
            target = self._target_in_world(request, qpos)
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

    def _target_in_world(self, request: ComputeIK.Request, qpos: np.ndarray) -> Pose:
        pose = pose_from_msg(request.target.pose)
        if not np.all(np.isfinite(np.concatenate([pose.position, pose.orientation_wxyz]))):
            raise InvalidGoalError("target pose has NaN or infinite values")
        norm = float(np.linalg.norm(pose.orientation_wxyz))
        if norm < 1e-6 and not request.position_only:
            raise InvalidGoalError("target orientation quaternion cannot be normalised (norm 0); "
                                   "give a unit quaternion, or position_only")
        local = Pose(pose.position, pose.orientation_wxyz / norm if norm >= 1e-6 else np.array([1.0, 0.0, 0.0, 0.0]))
        frame = request.target.header.frame_id
        check_frame(frame, self.robot, "target")
        if frame in self.robot.objects:
            raise InvalidGoalError(f"frame {frame!r} is an object's: an IK query resolves the robot's frames from "
                                   "/joint_states only; give the target in world or in a link of the robot")
        data = mujoco.MjData(self.robot.model)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(self.robot.model, data)
        return to_world(self.robot.model, data, frame, local)

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


def help_page(program: str) -> str:
    """``arm_server --help``: what it serves and its parameters (the Panda's defaults)."""
    robot = robot_models.load(robot_models.PANDA, visuals=False)
    specs = (ParameterSpec("robot", "", "robot of the running /sim (empty = ask /sim)", read_only=True), SCENE_PARAMETER,
             *parameters(robot))
    return help_text(program, NODE_NAME, """\
The /arm node: the MoveArm (/move_arm) and PickPlace (/pick_place) action servers and the
/arm/compute_ik service, for the Panda or the G1's arms. The actions run as skills inside /sim's
control step; start the sim node first (it waits for /sim up to 30 s and asks it for the robot).""", specs,
                     "Defaults shown are the Panda's; the grip force limits follow the robot.")


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``arm_server [--ros-args -p robot:=panda]``."""
    return spin_server(lambda robot, scene, overrides: ArmServer(robot, scene, parameter_overrides=overrides), NODE_NAME, args,
                       help_page, end_goals_before_exit)


if __name__ == "__main__":
    sys.exit(main())
