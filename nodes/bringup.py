"""All-in-one bringup: the sim node and every server that exists for the robot, as a launch file would.

``bringup --robot g1|panda [--scene course] [--rtf X] [--paused]``. Each node runs in its own
process (so the physics thread never waits for a server's Python), with the same names and
interfaces as when started one by one. Ctrl-C (or SIGTERM) stops them all; if one node dies,
the others are stopped too and bringup exits with an error.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

import robot_models
from nodes.processes import ChildProcess


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bringup", description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=robot_models.ROBOT_NAMES, default="g1")
    parser.add_argument("--scene", default="", help="scene variant (g1: open, course); default: the robot's own")
    parser.add_argument("--rtf", type=float, default=1.0, help="real-time factor; 0 = as fast as possible")
    parser.add_argument("--paused", action="store_true", help="start with the physics paused")
    return parser.parse_args(argv)


def commands_for(options: argparse.Namespace, ros_args: list[str]) -> list[list[str]]:
    """The executables to run, with their arguments."""
    sim = ["sim_node", "--ros-args", "-p", f"robot:={options.robot}", "-p", f"real_time_factor:={float(options.rtf)}",
           "-p", f"start_paused:={str(bool(options.paused)).lower()}"]
    if options.scene:
        sim += ["-p", f"scene:={options.scene}"]
    servers = [["arm_server", "--ros-args", "-p", f"robot:={options.robot}"]]
    robot = robot_models.load(options.robot)
    if robot.feet_sites:
        servers.append(["locomotion_server", "--ros-args", "-p", f"robot:={options.robot}"])
    if robot.sensors.battery is not None:
        servers.append(["power_node", "--ros-args", "-p", f"robot:={options.robot}"])
    if robot.sensors.wrists:
        servers.append(["hand_sensors", "--ros-args", "-p", f"robot:={options.robot}"])
    extra = ros_args[1:] if ros_args else []
    return [command + extra for command in [sim, *servers]]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    split = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    options = parse_args(argv[:split])
    try:
        robot_models.load(options.robot, options.scene or None)
    except robot_models.RobotModelError as error:
        print(f"bringup: {error}", file=sys.stderr)
        return 2
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    children = []
    try:
        for command in commands_for(options, argv[split:]):
            children.append(ChildProcess(command, inherit_output=True, own_group=False))
        print(f"bringup: running {', '.join(c.args[0] for c in children)} for {options.robot}; Ctrl-C stops them",
              flush=True)
        while not stop.wait(0.2):
            dead = [c for c in children if not c.alive()]
            if dead:
                print(f"bringup: {dead[0].args[0]} exited with {dead[0].process.returncode}; stopping the others",
                      file=sys.stderr, flush=True)
                return 1
        return 0
    finally:
        for child in children:  # signal all first, then wait: they shut down in parallel
            child.send_signal(signal.SIGINT)
        for child in reversed(children):
            child.stop(interrupt=False)


if __name__ == "__main__":
    sys.exit(main())
