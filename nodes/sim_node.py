"""The ``/sim`` node: owns the MuJoCo simulation, steps it, and publishes what it measures.

One thread steps the physics (lock-stepped, paced to ``real_time_factor``) and publishes
``/clock``, ``/joint_states``, ``/odom``, ``/tf`` and the rest when they fall due in sim time.
Services and subscriptions run on the executor and change the simulation under one lock, so
each change is atomic with respect to stepping.
"""

from __future__ import annotations

import array
import math
import sys
import threading
import time
import traceback
from dataclasses import dataclass
from typing import Any

import numpy as np
import rclpy
from geometry_msgs.msg import Pose as PoseMsg, TransformStamped, Twist
from lifecycle_msgs.srv import ChangeState
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg, Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy._rclpy_pybind11 import RCLError
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage

import robot_models
from nodes.cli import StartupError, StopRequest, bounded_cleanup, fail, help_requested, help_text, init_ros, program_name
from nodes.conversions import occupancy_grid_msg, set_pose, set_time
from nodes.executor import ServerExecutor, drop_qos_event_handlers
from nodes.parameters import ParameterSpec, declare, guard_parameter_services
from nodes.plugins import InLoopPlugins
from nodes.serialized import ClockTemplate, JointStateTemplate, TemplateError
from nodes.sim_standard import SimulationStandard
from nodes.tf_builder import TransformSet, link_pairs
from sim_bridge import Pacer, SimError, Simulation, SimulationFaultError, UnknownNameError
from sim_bridge.navigation import grid_from_obstacles
from sim_interfaces.msg import ObjectStates
from sim_interfaces.srv import Push, Reset, Step

NODE_NAME = "sim"
MAX_CHUNK_S = 0.05  # longest stretch of sim time stepped without releasing the lock [s]
MAX_STEP_REQUEST = 1_000_000
MAX_STREAM_RATE_HZ = 500.0  # the upper bound of joint_state_rate and clock_rate [Hz of sim time]
STREAM_HISTORY_S = 10.0  # /clock and /joint_states a reliable writer keeps for a stalled reader [s of sim time]
STREAM_HISTORY_DEPTH = int(STREAM_HISTORY_S * MAX_STREAM_RATE_HZ)  # 5000 samples: Fast DDS's default max_samples

PARAMETERS = (
    ParameterSpec("robot", "g1", f"robot scene to simulate, one of: {', '.join(robot_models.ROBOT_NAMES)}", read_only=True),
    ParameterSpec("scene", "", "scene variant (g1: open, course; panda: table); empty = the robot's default", read_only=True),
    ParameterSpec("autostart", True, "configure and activate the lifecycle node on start", read_only=True),
    ParameterSpec("start_paused", False, "start with the physics paused (use ~/resume or ~/step)", read_only=True),
    ParameterSpec("real_time_factor", 1.0, "sim seconds per wall second; 0 = as fast as possible", 0.0, 1000.0),
    ParameterSpec("joint_state_rate", 200.0, "/joint_states publish rate [Hz of sim time]", 1.0, MAX_STREAM_RATE_HZ),
    ParameterSpec("clock_rate", 100.0, "/clock publish rate [Hz of sim time]; keep >= the fastest timer of any node on sim time",
                  10.0, MAX_STREAM_RATE_HZ),
    ParameterSpec("odom_rate", 30.0, "/odom and odom->base /tf publish rate [Hz of sim time]", 1.0, 500.0),
    ParameterSpec("link_tf_rate", 10.0, "/tf rate of the link transforms [Hz of sim time]; 0 = off", 0.0, 500.0),
    ParameterSpec("state_rate", 30.0, "rate of /objects and controller state topics [Hz of sim time]", 1.0, 500.0),
    ParameterSpec("cmd_vel_timeout", 0.5, "a /cmd_vel older than this [s of sim time] counts as zero", 0.05, 10.0),
)
RATE_PARAMETERS = ("joint_state_rate", "clock_rate", "odom_rate", "link_tf_rate", "state_rate")


@dataclass
class _Schedule:
    """Next sim time [s] at which each stream is due."""

    clock: float = 0.0
    joint_states: float = 0.0
    odom: float = 0.0
    link_tf: float = 0.0
    state: float = 0.0


class SimNode(LifecycleNode):
    """Lifecycle node ``/sim``: configure builds the scene, activate starts the physics thread."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        declare(self, PARAMETERS)
        self.sim: Simulation | None = None
        self.plugins: InLoopPlugins | None = None
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._paused = bool(self.get_parameter("start_paused").value)
        self._pacer = Pacer(self._param("real_time_factor"))
        self._periods: dict[str, float] = {}
        self._stops: tuple[str, ...] = ()
        self._schedule = _Schedule()
        self._fault_count = 0
        self.configure_error = ""  # why the last configure failed, as the user should read it
        self._last_rtf = 0.0
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.context.on_shutdown(self._stop_thread)
        _refuse_unavailable_transitions(self)

    def _param(self, name: str) -> Any:
        return self.get_parameter(name).value

    # ----- parameters --------------------------------------------------------------------
    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name in RATE_PARAMETERS and self.sim is not None and parameter.value > 0:
                if 1.0 / parameter.value < self.sim.physics_timestep - 1e-12:
                    return SetParametersResult(
                        successful=False,
                        reason=f"{parameter.name} {parameter.value} Hz is faster than the physics rate "
                        f"({1.0 / self.sim.physics_timestep:.0f} Hz); allowed: up to that rate",
                    )
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        with self._lock:
            for parameter in parameters:
                if parameter.name == "real_time_factor":
                    self._pacer.set_factor(float(parameter.value))
                elif parameter.name in RATE_PARAMETERS:
                    self._update_periods()
            if self.plugins is not None:
                self.plugins.on_parameters(parameters)

    def _update_periods(self) -> None:
        def period(name: str) -> float:
            rate = float(self._param(name))
            return 1.0 / rate if rate > 0 else math.inf

        self._periods = {
            "clock": period("clock_rate"),
            "joint_states": period("joint_state_rate"),
            "odom": period("odom_rate"),
            "link_tf": period("link_tf_rate"),
            "state": period("state_rate"),
        }
        # /clock and /joint_states set the stepping stops. A slower stream rides along: it is
        # published at the first stop at or after it falls due (stamped with that exact sim
        # time, its mean rate unchanged), so it adds no stop, no Python loop turn of its own.
        fastest = min(self._periods["clock"], self._periods["joint_states"])
        self._stops = tuple(name for name, p in self._periods.items() if name in ("clock", "joint_states") or p < fastest)

    # ----- lifecycle ---------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        if self.sim is not None:  # configured before, then cleaned up: the same scene from its keyframe
            with self._lock:
                self.sim.reset()
                assert self.plugins is not None
                self.plugins.on_reset()
            self._pacer.reanchor()
            return TransitionCallbackReturn.SUCCESS
        try:
            robot = self._configure()
        except Exception as error:  # noqa: BLE001 - any cause is reported as it is, and the node stays unconfigured
            self.configure_error = str(error) if isinstance(error, (StartupError, robot_models.RobotModelError)) \
                else f"{type(error).__name__}: {error}"
            self.get_logger().error(f"cannot configure: {self.configure_error}")
            self.sim = None
            self.plugins = None
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info(
            f"robot {robot.name}: {len(robot.actuated_joints)} actuated joints, physics step "
            f"{robot.physics_timestep * 1e3:.1f} ms, control step {robot.control_timestep * 1e3:.1f} ms"
        )
        return TransitionCallbackReturn.SUCCESS

    def _configure(self) -> robot_models.RobotSpec:
        """Build the scene, the interfaces and the in-loop plugins (raises on any failure)."""
        robot = robot_models.load(str(self._param("robot")), str(self._param("scene")) or None)
        self.sim = Simulation(robot)
        self._update_periods()
        self._create_interfaces()
        self.plugins = InLoopPlugins(self, self.sim, self._lock)
        drop_qos_event_handlers(self)  # cheap executor wake-ups: the physics thread shares the GIL
        return robot

    def _create_interfaces(self) -> None:
        assert self.sim is not None
        sim = self.sim
        # A reliable writer keeps this many samples for a slow reader: stepped as fast as possible, /sim
        # publishes in bursts a recorder on a busy machine must not lose. /clock and /joint_states keep
        # STREAM_HISTORY_S of sim time at their fastest rate (a reader stalled for less loses nothing),
        # the other streams 1000 samples (5 s at 200 Hz).
        reliable = QoSProfile(depth=1000)
        streams = QoSProfile(depth=STREAM_HISTORY_DEPTH)
        self._clock_pub = self.create_publisher(Clock, "/clock", streams)
        self._joint_pub = self.create_publisher(JointState, "/joint_states", streams)
        self._odom_pub = self.create_publisher(Odometry, "/odom", reliable)
        self._tf_pub = self.create_publisher(TFMessage, "/tf", QoSProfile(depth=100))
        static_qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._tf_static_pub = self.create_publisher(TFMessage, "/tf_static", static_qos)
        self._rtf_pub = self.create_publisher(Float64, "~/real_time_factor", reliable)
        self._objects_pub = self.create_publisher(ObjectStates, "/objects", reliable)

        self._clock_msg = Clock()
        self._joint_msg = JointState()
        self._joint_msg.name = list(sim.robot.actuated_joints)
        try:  # the two streams published at every stop: serialized once, numbers patched in
            self._clock_template: ClockTemplate | None = ClockTemplate()
            self._joint_template: JointStateTemplate | None = JointStateTemplate(list(sim.robot.actuated_joints))
        except TemplateError as error:
            self.get_logger().warning(f"{error}; publishing /clock and /joint_states the ordinary way")
            self._clock_template = self._joint_template = None
        self._odom_msg = Odometry()
        robot = sim.robot
        self._odom_frame = "odom" if robot.floating_base else "world"
        self._odom_msg.header.frame_id = self._odom_frame
        self._odom_msg.child_frame_id = robot.base_body
        base_tf = TransformStamped()
        base_tf.header.frame_id = self._odom_frame
        base_tf.child_frame_id = robot.base_body
        self._base_tf_msg = TFMessage(transforms=[base_tf])
        self._object_tf = TransformSet(sim, [("world", name) for name in robot.objects])
        self._link_tf = TransformSet(sim, link_pairs(sim))
        if robot.floating_base:
            self._map_pub = self.create_publisher(OccupancyGridMsg, "/map", static_qos)
            self._map_pub.publish(occupancy_grid_msg(grid_from_obstacles(robot.obstacles)))
        self._objects_msg = ObjectStates(names=list(robot.objects), poses=[PoseMsg() for _ in robot.objects])
        self._objects_msg.header.frame_id = "world"
        if robot.floating_base:
            static = TFMessage()
            identity = TransformStamped()
            identity.header.frame_id = "world"
            identity.child_frame_id = "odom"
            identity.transform.rotation.w = 1.0
            static.transforms = [identity]
            self._tf_static_pub.publish(static)

        services = MutuallyExclusiveCallbackGroup()
        self.create_service(Reset, "~/reset", self._on_reset, callback_group=services)
        self.create_service(Step, "~/step", self._on_step, callback_group=services)
        self.create_service(Push, "~/push", self._on_push, callback_group=services)
        self.create_service(Trigger, "~/pause", self._on_pause, callback_group=services)
        self.create_service(Trigger, "~/resume", self._on_resume, callback_group=services)
        self.create_subscription(Twist, "/cmd_vel", self._on_cmd_vel, reliable, callback_group=ReentrantCallbackGroup())
        self.create_timer(1.0, self._publish_rtf)
        self.standard = SimulationStandard(self)  # the ROS simulation standard's services and action, under ~/

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop.clear()
        self._pacer.reanchor()
        self._thread = threading.Thread(target=self._run, name="physics", daemon=True)
        self._thread.start()
        self.get_logger().info("active: physics running" + (" (paused)" if self._paused else ""))
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop_thread()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop_thread()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop_thread()
        return TransitionCallbackReturn.SUCCESS

    def _stop_thread(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    # ----- the physics loop --------------------------------------------------------------
    def _run(self) -> None:
        try:
            self._loop()
        except RCLError:
            if self.context.ok():
                raise
            # The context was shut down (Ctrl-C / SIGTERM) while publishing: end quietly.
        finally:
            if self.plugins is not None:
                self.plugins.cameras.close()  # their GL contexts belong to this thread

    def _loop(self) -> None:
        assert self.sim is not None
        while not self._stop.is_set() and self.context.ok():
            if self._paused:
                self._wake.wait(0.1)
                self._wake.clear()
                self._pacer.reanchor()
                continue
            with self._lock:
                self._advance_to_next_event()
            self._pacer.pace(self.sim.time)
            # Let a service or timer waiting for the lock have it: behind real time (or at rtf 0) the
            # pacer does not sleep, and this thread would take the lock straight back, again and again.
            time.sleep(0)

    def _advance_to_next_event(self) -> None:
        """Step whole control steps up to the next publication due, then publish what is due."""
        sim = self.sim
        assert sim is not None and self.plugins is not None
        now = sim.time
        due = self._next_stop()
        dt = sim.physics_timestep
        chunk = min(MAX_CHUNK_S, self.plugins.max_chunk)
        steps = max(1, min(int(chunk / dt), math.ceil((due - now) / dt - 1e-6)))
        self.plugins.before_step(now)
        try:
            sim.step_physics(steps)
        except Exception as error:  # noqa: BLE001 - the physics thread must survive a controller failure
            self._recover(error)
        self.plugins.after_step()
        self._publish_due(sim.time)

    def _next_stop(self) -> float:
        """Sim time [s] of the next publication that stepping must stop for."""
        schedule = self._schedule
        return min(getattr(schedule, name) for name in self._stops)

    def _recover(self, error: Exception) -> None:
        """After the physics diverged or a controller failed: log why, reset to the keyframe."""
        assert self.sim is not None and self.plugins is not None
        self._fault_count += 1
        if isinstance(error, SimulationFaultError):
            self.get_logger().error(f"{error}; resetting to keyframe {self.sim.robot.default_keyframe!r}")
        else:
            self.get_logger().error(
                f"in-loop controller failed: {''.join(traceback.format_exception(error))}"
                f"resetting to keyframe {self.sim.robot.default_keyframe!r}")
        self.sim.reset()
        self.plugins.on_fault(str(error))

    def _publish_due(self, now: float, force: bool = False) -> None:
        sim = self.sim
        assert sim is not None and self.plugins is not None
        schedule = self._schedule
        periods = self._periods
        eps = 1e-9
        # A stream is published when due or forced; only a due one moves on along its grid (a forced
        # publication off the grid, e.g. at a reset, leaves the grid alone).
        due = now + eps >= schedule.clock
        if force or due:
            if self._clock_template is not None:
                self._clock_pub.publish(self._clock_template.serialize(now))
            else:
                set_time(self._clock_msg.clock, now)
                self._clock_pub.publish(self._clock_msg)
            if due:
                schedule.clock = _next_due(schedule.clock, periods["clock"], now)
        due = now + eps >= schedule.joint_states
        if force or due:
            self._publish_joint_states(now)
            if due:
                schedule.joint_states = _next_due(schedule.joint_states, periods["joint_states"], now)
        # The streams below are built and published only while someone subscribes (the checks
        # cost ~1 us); /clock and /joint_states are always published.
        due = now + eps >= schedule.odom
        if force or due:
            self._publish_odom(now)
            if due:
                schedule.odom = _next_due(schedule.odom, periods["odom"], now)
        due = now + eps >= schedule.link_tf
        if len(self._link_tf) and (force or due):
            if self._tf_pub.get_subscription_count() > 0:
                self._tf_pub.publish(self._link_tf.update(sim.data, now))
            if due:
                schedule.link_tf = _next_due(schedule.link_tf, periods["link_tf"], now)
        due = now + eps >= schedule.state
        if force or due:
            if len(self._object_tf):
                self._publish_objects(now)
            self.plugins.publish_state(now)
            if due:
                schedule.state = _next_due(schedule.state, periods["state"], now)

    def _publish_joint_states(self, now: float) -> None:
        assert self.sim is not None
        positions, velocities, efforts = self.sim.joint_arrays()
        if self._joint_template is not None:
            self._joint_pub.publish(self._joint_template.serialize(now, positions, velocities, efforts))
            return
        msg = self._joint_msg
        set_time(msg.header.stamp, now)
        # array.array takes the generated setters' fast path (no per-element checks).
        msg.position = _float64_array(positions)
        msg.velocity = _float64_array(velocities)
        msg.effort = _float64_array(efforts)
        self._joint_pub.publish(msg)

    def _publish_odom(self, now: float) -> None:
        """/odom and the odom -> base transform on /tf, each while someone subscribes."""
        assert self.sim is not None
        odom_wanted = self._odom_pub.get_subscription_count() > 0
        tf_wanted = self._tf_pub.get_subscription_count() > 0
        if not (odom_wanted or tf_wanted):
            return
        base = self.sim.base_state()
        msg = self._odom_msg
        set_time(msg.header.stamp, now)
        set_pose(msg.pose.pose, base.pose.position, base.pose.orientation_wxyz)
        v = base.linear_velocity_body.tolist()
        w = base.angular_velocity_body.tolist()
        twist = msg.twist.twist
        twist.linear.x, twist.linear.y, twist.linear.z = v[0], v[1], v[2]
        twist.angular.x, twist.angular.y, twist.angular.z = w[0], w[1], w[2]
        if odom_wanted:
            self._odom_pub.publish(msg)
        if not tf_wanted:
            return
        transform = self._base_tf_msg.transforms[0]
        set_time(transform.header.stamp, now)
        position, orientation = msg.pose.pose.position, msg.pose.pose.orientation
        translation, rotation = transform.transform.translation, transform.transform.rotation
        translation.x, translation.y, translation.z = position.x, position.y, position.z
        rotation.w, rotation.x, rotation.y, rotation.z = orientation.w, orientation.x, orientation.y, orientation.z
        self._tf_pub.publish(self._base_tf_msg)

    def _publish_objects(self, now: float) -> None:
        """World -> object transforms on /tf and /objects, each while someone subscribes."""
        assert self.sim is not None
        tf_wanted = self._tf_pub.get_subscription_count() > 0
        objects_wanted = self._objects_pub.get_subscription_count() > 0
        if not (tf_wanted or objects_wanted):
            return
        tf = self._object_tf.update(self.sim.data, now)
        if tf_wanted:
            self._tf_pub.publish(tf)
        if not objects_wanted:
            return
        msg = self._objects_msg
        set_time(msg.header.stamp, now)
        for pose, transform in zip(msg.poses, tf.transforms, strict=False):
            t, r = transform.transform.translation, transform.transform.rotation
            pose.position.x, pose.position.y, pose.position.z = t.x, t.y, t.z
            pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z = r.w, r.x, r.y, r.z
        self._objects_pub.publish(msg)

    def _publish_rtf(self) -> None:
        if self._thread is None:
            return
        self._last_rtf = 0.0 if self._paused else self._pacer.achieved_factor()
        self._rtf_pub.publish(Float64(data=self._last_rtf))

    # ----- control, for the services here and in nodes/sim_standard.py (each under the lock) ----
    @property
    def lock(self) -> threading.RLock:
        """The lock every change of the simulation is made under (the physics thread steps under it)."""
        return self._lock

    @property
    def paused(self) -> bool:
        return self._paused

    @property
    def physics_running(self) -> bool:
        """Whether the physics thread runs (the node is active); paused or not."""
        return self._thread is not None

    def set_paused(self, paused: bool) -> bool:
        """Pause or resume the physics thread; returns whether it was paused before."""
        was = self._paused
        self._paused = paused  # the physics thread reads it before every stretch of stepping
        with self._lock:  # the stretch under way (if any) ends before this returns
            if not paused:
                self._pacer.reanchor()
        if not paused:
            self._wake.set()
        return was

    def reset_scene(self, keyframe: str | None = None, keep_time: bool = True) -> None:
        """Restore a keyframe, end the running goals and publish at once; sim time restarts at 0 unless ``keep_time``.

        Raises:
            UnknownNameError: no such keyframe (nothing is changed).
        """
        assert self.sim is not None and self.plugins is not None
        with self._lock:
            self.sim.reset(keyframe, keep_time=keep_time)
            if not keep_time:  # every stream falls due again from t = 0
                self._schedule = _Schedule()
                self._pacer.reanchor()
            self.plugins.on_reset()
            self._publish_due(self.sim.time, force=True)

    def publish_now(self) -> None:
        """Publish every stream at the present sim time (after the state was changed from outside)."""
        assert self.sim is not None
        with self._lock:
            self._publish_due(self.sim.time, force=True)

    def step_while_paused(self, physics_steps: int) -> int:
        """Advance a paused simulation by whole physics steps, publishing what falls due; returns goals ended.

        Raises:
            SimError: stepping failed (the physics diverged, a controller failed): the simulation was
                reset to its keyframe before this is raised.
        """
        sim = self.sim
        assert sim is not None
        with self._lock:
            target = sim.time + physics_steps * sim.physics_timestep - 1e-9
            ended = 0
            try:
                while sim.time < target:
                    ended += self._advance_to_next_event_bounded(target)
            except Exception as error:  # a failed step is reported, the node keeps serving
                self._recover(error)
                raise SimError(f"{error}; the simulation was reset to its keyframe") from error
            return ended

    # ----- inputs and services -----------------------------------------------------------
    def _on_cmd_vel(self, msg: Twist) -> None:
        if self.plugins is not None:
            self.plugins.on_cmd_vel(msg)

    def _on_reset(self, request: Reset.Request, response: Reset.Response) -> Reset.Response:
        assert self.sim is not None and self.plugins is not None
        with self._lock:
            try:
                self.reset_scene(request.keyframe or None)
            except UnknownNameError as error:
                response.success = False
                response.message = str(error)
                response.sim_time = self.sim.time
                return response
            response.success = True
            response.message = f"reset to keyframe {request.keyframe or self.sim.robot.default_keyframe!r}"
            response.sim_time = self.sim.time
        self.get_logger().info(response.message)
        return response

    def _on_push(self, request: Push.Request, response: Push.Response) -> Push.Response:
        assert self.sim is not None
        body = request.body or self.sim.robot.base_body
        force, torque = request.wrench.force, request.wrench.torque
        with self._lock:
            response.sim_time = self.sim.time
            try:
                response.end_time = self.sim.push(body, (force.x, force.y, force.z), (torque.x, torque.y, torque.z),
                                                  request.duration)
            except (UnknownNameError, ValueError) as error:
                response.success = False
                response.message = str(error)
                return response
        response.success = True
        response.message = f"pushing {body} until t={response.end_time:.3f} s"
        return response

    def _on_pause(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        was = self.set_paused(True)
        response.success = True
        response.message = "already paused" if was else "paused"
        return response

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        was = self.set_paused(False)
        response.success = True
        response.message = "running" if was else "already running"
        return response

    def _on_step(self, request: Step.Request, response: Step.Response) -> Step.Response:
        assert self.sim is not None
        with self._lock:
            if not self._paused:
                response.success = False
                response.message = "step is only allowed while paused; call ~/pause first"
            elif not 1 <= request.steps <= MAX_STEP_REQUEST:
                response.success = False
                response.message = f"steps must be in [1, {MAX_STEP_REQUEST}], got {request.steps}"
            else:
                target = self.sim.time + request.steps * self.sim.control_timestep - 1e-9
                try:
                    while self.sim.time < target:
                        response.goals_ended += self._advance_to_next_event_bounded(target)
                except Exception as error:  # noqa: BLE001 - a failed step is answered, never left hanging
                    self._recover(error)
                    response.success = False
                    response.message = f"{error}; the simulation was reset"
                    response.sim_time = self.sim.time
                    return response
                response.success = True
                response.message = f"stepped {request.steps} control steps"
            response.sim_time = self.sim.time
        return response

    def _advance_to_next_event_bounded(self, target: float) -> int:
        """One stretch of stepping toward ``target`` [s]; returns how many skill goals ended in it."""
        sim = self.sim
        assert sim is not None and self.plugins is not None
        due = min(self._next_stop(), target)
        dt = sim.physics_timestep
        steps = max(1, math.ceil((due - sim.time) / dt - 1e-6))
        self.plugins.before_step(sim.time)
        sim.step_physics(steps)
        ended = self.plugins.after_step()
        self._publish_due(sim.time)
        return ended

    def destroy(self) -> None:
        self._stop_thread()
        self.destroy_node()


def _refuse_unavailable_transitions(node: LifecycleNode) -> None:
    """Answer a transition the current state does not have with success=false, and log what is allowed.

    rclpy's ``~/change_state`` raises inside the executor on a transition id that is not
    available (``ros2 lifecycle`` checks first; other clients may not), which ends the process.
    """
    service = next(s for s in node.services if s.srv_name.endswith("/change_state"))
    handle = service.callback

    def change_state(request: ChangeState.Request, response: ChangeState.Response) -> ChangeState.Response:
        available = {t[0]: t[1] for t in node._state_machine.available_transitions}
        label = request.transition.label
        if (label and label not in available.values()) or (not label and request.transition.id not in available):
            state = node._state_machine.current_state[1]
            node.get_logger().warning(
                f"refused lifecycle transition {label or request.transition.id!r} from state {state!r}; "
                f"available: {', '.join(f'{name} ({tid})' for tid, name in available.items())}")
            response.success = False
            return response
        return handle(request, response)

    service.callback = change_state


def _float64_array(values: np.ndarray) -> array.array:
    result = array.array("d")
    result.frombytes(values.tobytes())  # MuJoCo's arrays are float64; tobytes copies in C order
    return result


def _next_due(previous: float, period: float, now: float) -> float:
    """Next due time on the period grid, skipping slots already in the past."""
    if math.isinf(period):
        return math.inf
    nxt = previous + period
    if nxt <= now:
        nxt = now + period - ((now - previous) % period)
    return nxt


def help_page(program: str) -> str:
    """``sim_node --help``: what /sim does and its parameters."""
    return help_text(program, NODE_NAME, """\
The /sim node: a headless MuJoCo simulation of one robot scene as a lifecycle node. It steps the
physics (paced by real_time_factor, or on /sim/step), publishes /clock, /joint_states, /odom, /tf,
/tf_static and /objects, consumes /cmd_vel, runs the skills of the action servers in its control
step and serves reset, pause, resume, step and push under /sim/, and the ROS simulation standard
(simulation_interfaces: get/set_simulation_state, step_simulation, simulate_steps, get/set_entity_state, ...).""", PARAMETERS,
                     f"Known robots: {', '.join(robot_models.ROBOT_NAMES)}. The gait parameters (gait.*) are declared "
                     "once a walking robot is configured: `ros2 param list /sim` shows them.")


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``sim_node --ros-args -p robot:=g1``."""
    argv = sys.argv if args is None else args
    program = program_name(argv)
    if help_requested(argv):
        sys.stdout.write(help_page(program))
        return 0
    try:
        init_ros(argv, own_signals=True)  # SIGINT/SIGTERM raise KeyboardInterrupt until the node is built
        node = SimNode()
    except StartupError as error:
        rclpy.try_shutdown()
        return fail(program, error)
    except KeyboardInterrupt:  # Ctrl-C while it starts: end as quietly as when running
        rclpy.try_shutdown()
        return 0
    stop = StopRequest.install()
    guard_parameter_services(node)
    executor = ServerExecutor(num_threads=4)
    executor.add_node(node)
    try:
        if node.get_parameter("autostart").value:
            if node.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                return fail(program, StartupError(f"cannot configure /sim: {node.configure_error or 'unknown cause'}"))
            node.trigger_activate()
        while not stop.requested and rclpy.ok():  # short waits: the signal is seen within 0.2 s
            executor.spin_once(timeout_sec=0.2)
    except ExternalShutdownException:
        pass
    finally:
        with bounded_cleanup():
            node.destroy()
            executor.shutdown()
            rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
