"""The ``main`` of every node but ``/sim``: find the robot and its scene (parameters, or ask /sim), build the node, spin it."""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter

import robot_models
from nodes.runtime.executor import ServerExecutor, drop_qos_event_handlers, events_executor, spin_once_logging
from nodes.runtime.memory import map_large_buffers, release_build_memory
from nodes.runtime.parameters import ParameterSpec, StartupError, declare, guard_parameter_services
from nodes.runtime.sim_link import robot_of_sim, share_sim_clock, sim_time_overrides
from nodes.runtime.startup import StopRequest, bounded_cleanup, end_process, fail, help_requested, init_ros, program_name
from sim_ros.teardown import destroy_node_fully

NodeFactory = Callable[[str, str, list[Parameter]], Node]  # (robot, scene ("" = its default), parameter overrides) -> the node
SCENE_PARAMETER = ParameterSpec("scene", "", "scene of the running /sim (empty = the one /sim reports when asked for "
                                "its robot, else the robot's default)", read_only=True)
BeforeExit = Callable[[Node, Executor], None]  # runs while the context is still up, before the node is destroyed
Served = tuple[Node, bool]  # a node, and whether it spins on the events executor (else on a ServerExecutor)
NodesFactory = Callable[[str, str, list[Parameter]], list[Served]]  # (robot, scene, overrides) -> the nodes of a process


def spin_server(node_factory: NodeFactory, node_name: str, args: list[str] | None,
                help_page: Callable[[str], str] | None = None, before_exit: BeforeExit | None = None,
                events: bool = False) -> int:
    """``main`` of a server node: find the robot (parameter or /sim), build the node, spin it.

    ``-h``/``--help`` prints ``help_page(program)`` and returns at once, without ROS. A bad start-up
    parameter or params file ends it with one line and code 2. Ctrl-C (or SIGTERM) ends it with
    code 0 at any point, while it starts up as while it serves; ``before_exit`` then gets the node and
    its executor while ROS still runs (an action server ends its goals and sends their results).

    ``events``: spin on rclpy's C++ events executor (one thread) instead of :class:`ServerExecutor`.
    It handles each message without rebuilding a wait set in Python: an idle node on sim time costs less
    than half as much per /clock message (see :data:`nodes.runtime.executor`'s measures). For nodes
    whose callbacks are short and that run no action server (the device nodes).
    """
    def default_help(program: str) -> str:
        return (f"usage: {program} [-h] [--ros-args ...]\n\nThe /{node_name} node; "
                f"`ros2 param describe /{node_name} NAME` shows its parameters.\n")

    return _main(args, help_page or default_help,
                 lambda argv: _serve(lambda robot, scene, overrides: [(node_factory(robot, scene, overrides), events)],
                                     node_name, argv, before_exit))


def spin_nodes(nodes_factory: NodesFactory, process_name: str, args: list[str] | None,
               help_page: Callable[[str], str]) -> int:
    """``main`` of a process of several nodes (as a ROS 2 component container holds them): as :func:`spin_server`,
    the nodes that spin on the events executor share one in the main thread, the others a :class:`ServerExecutor`
    in a second thread. Each node keeps its own name, parameters and services."""
    return _main(args, help_page, lambda argv: _serve(nodes_factory, process_name, argv, None))


def _main(args: list[str] | None, help_page: Callable[[str], str], serve: Callable[[list[str]], int]) -> int:
    """``--help`` without ROS; else ROS up, ``serve(argv)``, ROS down. A start-up error ends it with one line and
    code 2; Ctrl-C while starting up (asking /sim, building the nodes) with code 0."""
    argv = sys.argv if args is None else args
    program = program_name(argv)
    if help_requested(argv):
        sys.stdout.write(help_page(program))
        return 0
    try:
        init_ros(argv, own_signals=True)
    except StartupError as error:
        return fail(program, error)
    try:
        return serve(argv)
    except StartupError as error:
        return fail(program, error)
    except KeyboardInterrupt:
        return 0
    finally:
        rclpy.try_shutdown()


def _serve(nodes_factory: NodesFactory, node_name: str, argv: list[str], before_exit: BeforeExit | None) -> int:
    overrides = sim_time_overrides(argv)
    probe = Node(f"{node_name}_setup", parameter_overrides=overrides)
    try:
        declare(probe, (ParameterSpec("robot", "", "robot of the running /sim (empty = ask /sim)", read_only=True),
                        SCENE_PARAMETER))
        robot, scene = str(probe.get_parameter("robot").value), str(probe.get_parameter("scene").value)
        if not robot:
            robot, scene_of_sim = robot_of_sim(probe)
            scene = scene or scene_of_sim
    except RuntimeError as error:
        probe.get_logger().fatal(str(error))
        rclpy.try_shutdown()
        return 2
    finally:
        probe.destroy_node()
    # From here a signal is a flag, never an exception inside rclpy. Installed before the node is built:
    # a node says it serves from its constructor, and a Ctrl-C right after that (as soon as a client saw
    # it serving) must not land as a KeyboardInterrupt between the constructor and the spin loop.
    stop = StopRequest.install()
    map_large_buffers()
    try:
        served = nodes_factory(robot, scene, overrides)
    except robot_models.RobotModelError as error:
        raise StartupError(str(error)) from None
    release_build_memory()
    share_sim_clock([node for node, _ in served])  # one /clock subscription in the process, not one per node
    for node, _ in served:
        drop_qos_event_handlers(node)
        guard_parameter_services(node)
    spinners: list[tuple[Executor, Node]] = []
    for events in (True, False):
        nodes = [node for node, on_events in served if on_events == events]
        if nodes:
            executor: Executor = events_executor() if events else ServerExecutor(num_threads=4)
            for node in nodes:
                executor.add_node(node)
            spinners.append((executor, nodes[0]))

    def spin(executor: Executor, node: Node) -> None:
        # Spun in short waits, so SIGINT/SIGTERM is seen within 0.2 s while the ROS context stays up: the
        # running goals can still be ended and their results sent.
        try:
            while not stop.requested and rclpy.ok():
                spin_once_logging(executor, node)
        except ExternalShutdownException:
            pass

    others = [threading.Thread(target=spin, args=spinner, name="executor", daemon=True) for spinner in spinners[1:]]
    try:
        for thread in others:
            thread.start()
        spin(*spinners[0])
    finally:
        for thread in others:
            thread.join(timeout=1.0)
        with bounded_cleanup():
            if before_exit is not None and rclpy.ok():
                before_exit(served[0][0], spinners[0][0])
            for node, _ in served:
                destroy_node_fully(node)
            for executor, _ in spinners:
                executor.shutdown()
            rclpy.try_shutdown()
    end_process(0)
