"""All-in-one bringup: the sim node and every server that exists for the robot, in one process.

``bringup --robot g1|panda [--rtf X]``. Each node keeps its own name and interfaces, exactly as
when run as separate executables; one multi-threaded executor spins them all.
"""

from __future__ import annotations

import argparse
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.parameter import Parameter

import robot_models
from nodes.common import sim_time_overrides
from nodes.sim_node import SimNode


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bringup", description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=robot_models.ROBOT_NAMES, default="g1")
    parser.add_argument("--rtf", type=float, default=1.0, help="real-time factor; 0 = as fast as possible")
    parser.add_argument("--paused", action="store_true", help="start with the physics paused")
    return parser.parse_args(argv)


def server_nodes_for(robot: str, overrides: list[Parameter]) -> list:
    """The action-server nodes that exist for ``robot`` (all on sim time)."""
    from nodes.arm_server import ArmServer

    nodes = [ArmServer(robot, parameter_overrides=overrides)]
    return nodes


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ros_args = argv[argv.index("--ros-args"):] if "--ros-args" in argv else []
    own_args = argv[: argv.index("--ros-args")] if "--ros-args" in argv else argv
    options = parse_args(own_args)
    rclpy.init(args=["bringup", *ros_args])
    sim = SimNode(parameter_overrides=[
        Parameter("robot", value=options.robot),
        Parameter("real_time_factor", value=float(options.rtf)),
        Parameter("start_paused", value=bool(options.paused)),
    ])
    if sim.trigger_configure() != TransitionCallbackReturn.SUCCESS:
        sim.destroy()
        rclpy.try_shutdown()
        return 2
    sim.trigger_activate()
    nodes = [sim, *server_nodes_for(options.robot, sim_time_overrides(ros_args))]
    executor = MultiThreadedExecutor(num_threads=4)
    for node in nodes:
        executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for node in reversed(nodes):
            node.destroy() if hasattr(node, "destroy") else node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
