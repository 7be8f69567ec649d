"""What every server node of the project shares: sim time by default, the robot name from /sim,
streams subscribed on demand, and the ``main`` that builds and spins a server."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any, Generic, TypeVar

import rclpy
from rcl_interfaces.srv import GetParameters
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

MsgT = TypeVar("MsgT")
SIM_NODE = "sim"


def sim_time_overrides(args: list[str] | None) -> list[Parameter]:
    """``use_sim_time`` true unless the command line sets it (project convention: sim time everywhere)."""
    given = any("use_sim_time:=" in arg for arg in (args or []))
    return [] if given else [Parameter("use_sim_time", value=True)]


SIM_WAIT_LOG_S = 10.0  # a server waiting for /sim says so this often


def robot_of_sim(node: Node, timeout_s: float = 30.0) -> str:
    """Ask ``/sim`` which robot it simulates (its read-only ``robot`` parameter), waiting for /sim to come.

    A server started before the sim waits for it as long as it takes (Ctrl-C stops it), and says so
    every ``SIM_WAIT_LOG_S``. Call from ``main`` before spinning, never from a callback.

    Raises:
        RuntimeError: /sim is there but did not answer within ``timeout_s``.
    """
    client = node.create_client(GetParameters, f"/{SIM_NODE}/get_parameters")
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        waited = 0.0
        while not client.wait_for_service(timeout_sec=SIM_WAIT_LOG_S):
            waited += SIM_WAIT_LOG_S
            node.get_logger().warning(f"waiting for /{SIM_NODE} ({waited:.0f} s so far): start the sim node, or pass "
                                      "-p robot:=NAME to serve without asking it")
        if waited:
            node.get_logger().info(f"/{SIM_NODE} is up after {waited:.0f} s")
        future = client.call_async(GetParameters.Request(names=["robot"]))
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        if not future.done() or not future.result().values:
            raise RuntimeError(f"/{SIM_NODE} did not report its robot parameter")
        return str(future.result().values[0].string_value)
    finally:
        executor.remove_node(node)
        node.destroy_client(client)


class Latest(Generic[MsgT]):
    """The latest message of a topic, with a condition to wait for the next one."""

    def __init__(self) -> None:
        self._message: MsgT | None = None
        self._condition = threading.Condition()
        self._version = 0

    def put(self, msg: MsgT) -> None:
        with self._condition:
            self._message = msg
            self._version += 1
            self._condition.notify_all()

    def get(self) -> MsgT | None:
        with self._condition:
            return self._message

    def clear(self) -> None:
        with self._condition:
            self._message = None

    def wait_next(self, timeout_s: float) -> bool:
        """Block until a new message arrives or ``timeout_s`` wall seconds pass. True if one came."""
        with self._condition:
            version = self._version
            return self._condition.wait_for(lambda: self._version != version, timeout=timeout_s)


class OnDemandTopic(Generic[MsgT]):
    """A topic subscribed only while something needs it: idle servers receive nothing they do not use.

    Every message a Python node receives costs an executor wake-up (measured here: ~0.4 ms of CPU on
    an idle ``/arm``), and ``/sim`` publishes ``/joint_states`` at 200 Hz and its state topics at
    30 Hz. A server that needs a stream only for a goal or a query holds it for that time
    (:meth:`held`) or asks for a fresh message (:meth:`fresh`); the subscription then stays for
    ``linger_s`` wall seconds after the last use, so a burst of goals or queries subscribes once.
    Messages never outlive the subscription: after it ends, nothing stale is handed out.
    """

    def __init__(self, node: Node, msg_type: Any, topic: str, qos: Any, callback_group: Any,
                 linger_s: float = 5.0) -> None:
        self.latest: Latest[MsgT] = Latest()
        self._node = node
        self._args = (msg_type, topic, self.latest.put, qos)
        self._group = callback_group
        self._linger_s = linger_s
        self._lock = threading.Lock()
        self._holders = 0
        self._last_use = 0.0
        self._subscription: Any = None
        self._timer: Any = None

    def _acquire(self) -> None:
        with self._lock:
            self._holders += 1
            if self._subscription is None:
                self.latest.clear()
                self._subscription = self._node.create_subscription(
                    *self._args, callback_group=self._group,
                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
                self._timer = self._node.create_timer(1.0, self._expire, callback_group=self._group,
                                                      clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _release(self) -> None:
        with self._lock:
            self._holders -= 1
            self._last_use = time.monotonic()

    def _expire(self) -> None:
        """Unsubscribe once nobody holds the topic and ``linger_s`` passed since the last use."""
        with self._lock:
            if self._subscription is None or self._holders > 0 or time.monotonic() - self._last_use < self._linger_s:
                return
            self._node.destroy_subscription(self._subscription)
            self._node.destroy_timer(self._timer)
            self._subscription = self._timer = None
            self.latest.clear()

    @contextlib.contextmanager
    def held(self) -> Iterator[Latest[MsgT]]:
        """Subscribed for the duration of a ``with`` block (and ``linger_s`` after); yields the box."""
        self._acquire()
        try:
            yield self.latest
        finally:
            self._release()

    def fresh(self, timeout_s: float) -> MsgT | None:
        """The latest message since subscribing, waiting up to ``timeout_s`` wall seconds for one."""
        with self.held() as latest:
            deadline = time.monotonic() + timeout_s
            while (msg := latest.get()) is None and time.monotonic() < deadline:
                latest.wait_next(min(0.1, max(0.0, deadline - time.monotonic())))
            return msg


class GoalRejected(Exception):
    """A goal that can never be executed; the message says why and what is allowed."""


def spin_server(node_factory: Callable[[str, list[Parameter]], Node], node_name: str, args: list[str] | None,
                help_page: Callable[[str], str] | None = None) -> int:
    """``main`` of a server node: find the robot (parameter or /sim), build the node, spin it.

    ``-h``/``--help`` prints ``help_page(program)`` and returns at once, without ROS. A bad start-up
    parameter or params file ends it with one line and code 2. Ctrl-C (or SIGTERM) ends it with
    code 0 at any point, while it starts up as while it serves.
    """
    from nodes.cli import StartupError, fail, help_requested, init_ros, program_name

    argv = sys.argv if args is None else args
    program = program_name(argv)
    if help_requested(argv):
        sys.stdout.write(help_page(program) if help_page is not None else
                         f"usage: {program} [-h] [--ros-args ...]\n\nThe /{node_name} node; "
                         f"`ros2 param describe /{node_name} NAME` shows its parameters.\n")
        return 0
    try:
        init_ros(argv, own_signals=True)
    except StartupError as error:
        return fail(program, error)
    try:
        return _serve(node_factory, node_name, argv)
    except StartupError as error:
        return fail(program, error)
    except KeyboardInterrupt:  # interrupted while starting up (asking /sim, building the node)
        return 0
    finally:
        rclpy.try_shutdown()


GOODBYE_WALL_S = 2.0  # [s] a stopping server spends at most this long getting its goals' results out
RESULT_GRACE_S = 0.2  # [s] after its goals' callbacks returned, for the result responses to go out


def _end_goals_before_exit(node: Node, executor: Any) -> None:
    """End the running goals ABORTED "server shutting down" and spin until their results have gone out."""
    from nodes.skill_server import end_goals_of, goals_pending

    if not rclpy.ok():
        return
    ended = end_goals_of(node, f"server shutting down: /{node.get_name()} was stopped while the goal ran")
    if not ended:
        return
    node.get_logger().warning(f"stopping: ended {ended} running goal(s) ABORTED (server shutting down)")
    deadline = time.monotonic() + GOODBYE_WALL_S
    while goals_pending(node) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)  # the goals' execute callbacks return
    grace = time.monotonic() + RESULT_GRACE_S
    while time.monotonic() < grace:
        executor.spin_once(timeout_sec=0.02)  # and the result requests they release are answered


def _serve(node_factory: Callable[[str, list[Parameter]], Node], node_name: str, argv: list[str]) -> int:
    from rclpy.executors import ExternalShutdownException

    import robot_models
    from nodes.cli import StartupError, StopRequest, bounded_cleanup
    from nodes.executor import ServerExecutor, drop_qos_event_handlers
    from nodes.parameters import ParameterSpec, declare, guard_parameter_services

    overrides = sim_time_overrides(argv)
    probe = Node(f"{node_name}_setup", parameter_overrides=overrides)
    try:
        declare(probe, (ParameterSpec("robot", "", "robot of the running /sim (empty = ask /sim)", read_only=True),))
        robot = str(probe.get_parameter("robot").value) or robot_of_sim(probe)
    except RuntimeError as error:
        probe.get_logger().fatal(str(error))
        rclpy.try_shutdown()
        return 2
    finally:
        probe.destroy_node()
    try:
        node = node_factory(robot, overrides)
    except robot_models.RobotModelError as error:
        raise StartupError(str(error)) from None
    drop_qos_event_handlers(node)
    guard_parameter_services(node)
    executor = ServerExecutor(num_threads=4)
    executor.add_node(node)
    stop = StopRequest.install()  # from here a signal is a flag, never an exception inside rclpy
    # Spun in short waits, so SIGINT/SIGTERM is seen within 0.2 s while the ROS context stays up: the
    # running goals can still be ended and their results sent.
    try:
        while not stop.requested and rclpy.ok():
            executor.spin_once(timeout_sec=0.2)
    except ExternalShutdownException:
        pass
    finally:
        with bounded_cleanup():
            _end_goals_before_exit(node, executor)
            node.destroy_node()
            executor.shutdown()
            rclpy.try_shutdown()
    return 0
