"""The ``/sim`` node: owns the MuJoCo simulation, steps it, and publishes what it measures.

One thread steps the physics (lock-stepped, paced to ``real_time_factor``) from one publication stop
to the next (:mod:`nodes.sim.stepping`, :mod:`nodes.sim.publication`) and publishes ``/clock``, ``/joint_states``, ``/odom``,
``/tf`` and the rest when they fall due in sim time. Services and subscriptions run on the executor
and change the simulation under one lock (through :class:`~nodes.sim.control.SimControl`), so each
change is atomic with respect to stepping.
"""

from __future__ import annotations

import gc
import sys
import threading
from typing import Any

import rclpy
from lifecycle_msgs.srv import ChangeState
from rcl_interfaces.msg import SetParametersResult
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import ExternalShutdownException
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter

import robot_models
from nodes.runtime.executor import ServerExecutor, drop_qos_event_handlers
from nodes.runtime.memory import map_large_buffers, release_build_memory
from nodes.runtime.parameters import ParameterSpec, StartupError, declare, guard_parameter_services, report_read_only
from nodes.runtime.startup import (
    StopRequest,
    bounded_cleanup,
    end_process,
    fail,
    help_requested,
    help_text,
    init_ros,
    program_name,
)
from nodes.sim.controllers import InLoopPlugins
from nodes.sim.handoff import HandOffLock
from nodes.sim.publication import Publications
from nodes.sim.services import SimServices
from nodes.sim.standard import SimulationStandard
from nodes.sim.stepping import Stepper
from nodes.sim.world import MadeEntities, WorldServices
from sim_bridge import Pacer, Simulation
from sim_bridge.skills import LEGS
from sim_ros.names import MAX_STREAM_RATE_HZ, SIM_NODE
from sim_ros.scheduling import physics_first
from sim_ros.teardown import destroy_node_fully

NODE_NAME = SIM_NODE
WORLD_COLLECT_AFTER_S = 1.0  # [s of wall time] after a world was loaded, when the old one is collected once more
HAND_OFF_TIMEOUT_S = 0.1  # [s of wall time] longest the physics thread waits for a waiting service to take its lock

PARAMETERS = (
    ParameterSpec("robot", robot_models.G1, f"robot scene to simulate, one of: {', '.join(robot_models.ROBOT_NAMES)}",
                  read_only=True),
    ParameterSpec("scene", "", f"scene variant ({robot_models.scenes_summary()}); empty = the robot's default", read_only=True),
    ParameterSpec("autostart", True, "configure and activate the lifecycle node on start", read_only=True),
    ParameterSpec("start_paused", False, "start with the physics paused (use ~/resume or ~/step)", read_only=True),
    ParameterSpec("real_time_factor", 1.0, "sim seconds per wall second; 0 = as fast as possible", 0.0, 1000.0),
    ParameterSpec("joint_state_rate", 200.0, "/joint_states publish rate [Hz of sim time]", 1.0, MAX_STREAM_RATE_HZ),
    # 20 Hz: twice the project's fastest sim-time timer (the servers' 10 Hz watchdog); Gazebo's gazebo_ros_init
    # publishes at 10 Hz by default. Each /clock wakes every node on sim time: at 100 Hz a G1 bring-up's servers
    # and device nodes took twice the CPU (a bring-up at rtf 2, idle: 31% of a core against 16% at 20 Hz).
    ParameterSpec("clock_rate", 20.0, "/clock publish rate [Hz of sim time]; keep >= the fastest timer of any node on sim time",
                  10.0, MAX_STREAM_RATE_HZ),
    ParameterSpec("odom_rate", 30.0, "/odom and odom->base /tf publish rate [Hz of sim time]", 1.0, 500.0),
    ParameterSpec("link_tf_rate", 10.0, "/tf rate of the link transforms [Hz of sim time]; 0 = off", 0.0, 500.0),
    ParameterSpec("state_rate", 30.0, "rate of /objects and controller state topics [Hz of sim time]", 1.0, 500.0),
    ParameterSpec("cmd_vel_timeout", 0.5, "a /cmd_vel older than this [s of sim time] counts as zero", 0.05, 10.0),
)
# stream of nodes.sim.publication -> the parameter that sets its rate
RATE_PARAMETERS = {"clock": "clock_rate", "joint_states": "joint_state_rate", "odom": "odom_rate",
                   "link_tf": "link_tf_rate", "state": "state_rate"}


class SimNode(LifecycleNode):
    """Lifecycle node ``/sim``: configure builds the scene, activate starts the physics thread.

    It is the :class:`~nodes.sim.control.SimControl` of its services.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        declare(self, PARAMETERS)
        self.sim: Simulation | None = None
        self.plugins: InLoopPlugins | None = None
        self._publications: Publications | None = None
        self._stepper: Stepper | None = None
        self._lock = HandOffLock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._paused = bool(self.get_parameter("start_paused").value)
        self._pacer = Pacer(self._param("real_time_factor"))
        self.configure_error = ""  # why the last configure failed, as the user should read it
        self._made = MadeEntities()  # what the scene's configure made on this node (destroyed when the world changes)
        self.world = WorldServices(self, str(self._param("robot")), self._scene_loaded, self.load_world)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.context.on_shutdown(self._stop_thread)
        _refuse_unavailable_transitions(self)

    def _param(self, name: str) -> Any:
        return self.get_parameter(name).value

    # ----- parameters --------------------------------------------------------------------
    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name in RATE_PARAMETERS.values() and self.sim is not None and parameter.value > 0:
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
                elif parameter.name in RATE_PARAMETERS.values() and self._publications is not None:
                    self._publications.set_rates(self._rates())
            if self.plugins is not None:
                self.plugins.on_parameters(parameters)

    def _rates(self) -> dict[str, float]:
        return {stream: float(self._param(name)) for stream, name in RATE_PARAMETERS.items()}

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
            map_large_buffers()
            robot = robot_models.load(str(self._param("robot")), str(self._param("scene")) or None)
            self._configure(robot)
            release_build_memory()
        except Exception as error:  # noqa: BLE001 - any cause is reported as it is, and the node stays unconfigured
            self.configure_error = str(error) if isinstance(error, (StartupError, robot_models.RobotModelError)) \
                else f"{type(error).__name__}: {error}"
            self.get_logger().error(f"cannot configure: {self.configure_error}")
            self.sim = None
            self.plugins = None
            self._publications = self._stepper = None
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info(
            f"robot {robot.name} in scene {robot.scene}: {len(robot.actuated_joints)} actuated joints, physics step "
            f"{robot.physics_timestep * 1e3:.1f} ms, control step {robot.control_timestep * 1e3:.1f} ms"
        )
        self.world.announce()
        return TransitionCallbackReturn.SUCCESS

    def _configure(self, robot: robot_models.RobotSpec) -> None:
        """Build the scene of ``robot``, its publications, services and in-loop plugins (raises on any failure);
        what it makes on the node is kept in ``_made``."""
        _, self._made = MadeEntities.made_by(self, lambda: self._build(robot))

    def _build(self, robot: robot_models.RobotSpec) -> None:
        sim = self.sim = Simulation(robot)
        plugins = self.plugins = InLoopPlugins(self, sim, self._lock)
        publications = self._publications = Publications(self, sim, plugins.publish_state)
        publications.set_rates(self._rates())
        self._stepper = Stepper(sim, plugins, publications, self.get_logger())
        self._sim_services = SimServices(self, sim, self)  # ~/reset, ~/step, ~/pause, ~/resume, ~/push
        self.standard = SimulationStandard(self, sim, self)  # the ROS simulation standard's services and action, under ~/
        self.create_timer(1.0, self._publish_rtf)
        drop_qos_event_handlers(self)  # cheap executor wake-ups: the physics thread shares the GIL

    def _scene_loaded(self) -> str:
        return self.sim.robot.scene if self.sim is not None else ""

    def load_world(self, scene: str) -> None:
        """Replace the scene by another of the robot's, as a fresh /sim would start it (see :mod:`nodes.sim.world`).

        Raises:
            RuntimeError: /sim is not configured yet (nothing is changed).
            robot_models.RobotModelError: the scene could not be built (nothing is changed).
        """
        if self.sim is None:
            raise RuntimeError("/sim is not configured: configure it first (or start it with -p scene:=...)")
        robot = robot_models.load(self.sim.robot.name, scene)  # the slow part, and the one that may fail: first
        old = self.sim.robot
        running = self._thread is not None
        self.reset_scene(keep_time=False)  # the running goals end, and their servers hear it
        self._stop_thread()
        try:
            with self._lock:
                self._made.destroy(self)
                self._configure_scene(robot)
        except Exception:
            with self._lock:  # nothing of the new scene is left (made_by, or here), and the old scene is back, afresh
                self._made.destroy(self)
                self._configure_scene(old)
            raise
        finally:
            if running:
                self._start_thread()
        self.get_logger().info(f"world replaced: {robot.name} in scene {scene}, sim time 0")
        # The old scene's objects hold one another in cycles (~180 MB for the G1), which only the cyclic collector
        # frees, and it seldom runs a full collection; the executor lets go of the destroyed entities (and with them
        # the last references) at its next waits, so a collection runs again a moment later.
        gc.collect()
        collect_later = threading.Timer(WORLD_COLLECT_AFTER_S, gc.collect)
        collect_later.daemon = True
        collect_later.start()

    def _configure_scene(self, robot: robot_models.RobotSpec) -> None:
        """Under the lock: build ``robot``'s scene on a node whose last scene was destroyed, with the node's settings."""
        report_read_only(self, "scene", robot.scene)  # it says what is loaded
        self._configure(robot)
        assert self.plugins is not None
        self.plugins.on_parameters(list(self._parameters.values()))  # the node's settings carry over
        release_build_memory()

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._start_thread()
        self.get_logger().info("active: physics running" + (" (paused)" if self._paused else ""))
        return super().on_activate(state)

    def _start_thread(self) -> None:
        self._stop.clear()
        self._pacer.reanchor()
        self._thread = threading.Thread(target=self._run, name="physics", daemon=True)
        self._thread.start()

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

    def destroy(self) -> None:
        self._stop_thread()
        destroy_node_fully(self)

    # ----- the physics loop --------------------------------------------------------------
    def _run(self) -> None:
        try:
            with physics_first():  # ahead of the threads its publications wake (sim_ros.scheduling)
                self._loop()
        except RCLError:
            if self.context.ok():
                raise
            # The context was shut down (Ctrl-C / SIGTERM) while publishing: end quietly.
        finally:
            if self.plugins is not None:
                self.plugins.cameras.close()  # their GL contexts belong to this thread

    def _loop(self) -> None:
        assert self.sim is not None and self._stepper is not None
        sim, stepper, pacer, lock = self.sim, self._stepper, self._pacer, self._lock
        while not self._stop.is_set() and self.context.ok():
            if self._paused:
                self._wake.wait(0.1)
                self._wake.clear()
                pacer.reanchor()
                continue
            lock.acquire()
            try:
                stepper.advance()
            finally:
                # Behind real time (or at rtf 0) the pacer does not sleep and this thread would take the
                # lock straight back: a service or timer waiting for it gets it first (and nobody waiting
                # costs nothing).
                lock.hand_off(HAND_OFF_TIMEOUT_S)
            pacer.pace(sim.time)

    def _publish_rtf(self) -> None:
        if self._thread is None or self._publications is None:
            return
        self._publications.publish_rtf(0.0 if self._paused else self._pacer.achieved_factor())

    # ----- SimControl: for the services (each under the lock) ----------------------------
    @property
    def lock(self) -> HandOffLock:
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
        assert self.sim is not None and self.plugins is not None and self._publications is not None
        with self._lock:
            self.sim.reset(keyframe, keep_time=keep_time)
            if not keep_time:  # every stream falls due again from t = 0
                self._publications.restart()
                self._pacer.reanchor()
            self.plugins.on_reset()
            self._publications.publish_due(self.sim.time, force=True)

    def publish_now(self) -> None:
        """Publish every stream at the present sim time (after the state was changed from outside)."""
        assert self.sim is not None and self._publications is not None
        with self._lock:
            self._publications.publish_due(self.sim.time, force=True)

    def step_while_paused(self, until_s: float, stop_at_goal_end: bool = False) -> int:
        """Step a paused simulation up to sim time ``until_s`` [s], publishing what falls due; returns goals ended.

        With ``stop_at_goal_end``, it stops at the first publication stop after a skill goal ended.

        Raises:
            SteppingError: a step failed (the physics diverged, a controller failed): the simulation was
                reset to its keyframe before this is raised.
        """
        assert self._stepper is not None
        with self._lock, physics_first():  # the stepping thread ahead of those its publications wake
            return self._stepper.advance_to(until_s, stop_at_goal_end)

    def legs_busy(self) -> bool:
        """Whether a skill goal (Walk, NavigateToPose, ResetPose) drives the legs."""
        return self.plugins is not None and self.plugins.skills.busy(LEGS)

    def robot_moved(self) -> None:
        """Under the lock, after the robot's base was moved: the walking controller starts again from there."""
        plugins = self.plugins
        assert self.sim is not None and plugins is not None
        if plugins.walking is not None:
            # The gait and balance references are in world coordinates: start them again from here.
            plugins.walking.reset(self.sim.model, self.sim.data)
            plugins.on_reset()


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


def help_page(program: str) -> str:
    """``sim_node --help``: what /sim does and its parameters."""
    return help_text(program, NODE_NAME, """\
The /sim node: a headless MuJoCo simulation of one robot scene as a lifecycle node. It steps the
physics (paced by real_time_factor, or on /sim/step), publishes /clock, /joint_states, /odom, /tf,
/tf_static and /objects, consumes /cmd_vel, runs the skills of the action servers in its control
step and serves reset, pause, resume, step and push under /sim/, and the ROS simulation standard
(simulation_interfaces: get/set_simulation_state, step_simulation, simulate_steps, get/set_entity_state, ...,
load_world: another scene of the robot, by name).""", PARAMETERS,
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
    end_process(0)


if __name__ == "__main__":
    sys.exit(main())
