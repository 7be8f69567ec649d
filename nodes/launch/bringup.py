"""All-in-one bringup: the sim node and every server that exists for the robot, as a launch file would.

``bringup --robot g1|panda [--scene course|tables] [--rtf X] [--paused] [--clock-rate HZ] [--joint-state-rate HZ]``.
Each node runs in its own process (so the physics thread never waits for a server's Python), with the same names and
interfaces as when started one by one. Ctrl-C (or SIGTERM) stops them all.

A node that dies (a non-zero exit) is reported (which, its exit code, its last lines of output) and started again, as
a launch file's ``respawn`` does, after ``--respawn-delay`` seconds and at most ``--respawn-limit``
times per node; the others keep running (the servers serve a restarted /sim, which starts from its
keyframe). A restarted node talks over Fast DDS's UDP transport only (:func:`restart_environment`: a killed process's
shared-memory port can leave the next one unreachable). With ``--no-respawn`` a dying node stops the others and
bringup exits with an error.
A client waiting on a goal of a server that died gets its result from bringup all the same
(:mod:`nodes.launch.result_keeper`): ABORTED, ``SIM_FAULT``, naming the dead server.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
import threading
from typing import Any

import robot_models
from nodes.devices import devices_of
from nodes.launch.result_keeper import ResultKeeper
from nodes.servers.actions import ACTION_TYPES, SERVED_BY
from sim_ros.names import MAX_STREAM_RATE_HZ
from sim_ros.processes import ChildProcess

FASTDDS_TRANSPORTS_VARIABLE = "FASTDDS_BUILTIN_TRANSPORTS"  # Fast DDS's choice of its built-in transports
MIN_CLOCK_RATE_HZ = 10.0  # /sim's clock_rate range: this to sim_ros.names.MAX_STREAM_RATE_HZ
MIN_JOINT_STATE_RATE_HZ = 1.0  # /sim's joint_state_rate range: this to sim_ros.names.MAX_STREAM_RATE_HZ
NAMESPACE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bringup", description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=robot_models.ROBOT_NAMES, default=robot_models.G1)
    parser.add_argument("--scene", default="", help=f"scene variant ({robot_models.scenes_summary()}); default: the robot's own")
    parser.add_argument("--rtf", type=float, default=1.0, help="real-time factor; 0 = as fast as possible")
    parser.add_argument("--paused", action="store_true", help="start with the physics paused")
    parser.add_argument("--clock-rate", type=float, default=None,
                        help="/sim's /clock rate [Hz of sim time] (default: its clock_rate parameter's, 20)")
    parser.add_argument("--joint-state-rate", type=float, default=None,
                        help="/sim's /joint_states rate [Hz of sim time] (default: its joint_state_rate parameter's, 200)")
    parser.add_argument("--no-respawn", dest="respawn", action="store_false",
                        help="a node that dies stops the others (default: it is started again)")
    parser.add_argument("--respawn-limit", type=int, default=5, help="restarts allowed per node (default 5)")
    parser.add_argument("--respawn-delay", type=float, default=1.0, help="wall seconds before a restart (default 1)")
    parser.add_argument("--namespace", default="",
                        help="start every node under this namespace (e.g. r1: /r1/sim, /r1/walk, /r1/joint_states, its "
                             "own /r1/clock and /r1/tf); default: the root")
    parser.add_argument("--foxglove", action="store_true",
                        help="serve the watched topics to the Foxglove app (WebSocket, foxglove_bridge)")
    parser.add_argument("--foxglove-port", type=int, default=8765, help="its TCP port (default 8765)")
    parser.add_argument("--foxglove-host", default="127.0.0.1",
                        help="its address (default 127.0.0.1: this machine only; 0.0.0.0 exposes it to the network)")
    options = parser.parse_args(argv)
    options.namespace = options.namespace.strip("/")
    if options.namespace and not NAMESPACE.fullmatch(options.namespace):
        parser.error(f"--namespace {options.namespace!r}: letters, digits and _ in /-separated parts, "
                     "not starting with a digit (e.g. r1 or team/r1)")
    if not 0 <= options.foxglove_port <= 65535:
        parser.error("--foxglove-port must be in [0, 65535]")
    if options.clock_rate is not None and not MIN_CLOCK_RATE_HZ <= options.clock_rate <= MAX_STREAM_RATE_HZ:
        parser.error(f"--clock-rate must be in [{MIN_CLOCK_RATE_HZ:g}, {MAX_STREAM_RATE_HZ:g}] Hz of sim time")
    if options.joint_state_rate is not None and not MIN_JOINT_STATE_RATE_HZ <= options.joint_state_rate <= MAX_STREAM_RATE_HZ:
        parser.error(f"--joint-state-rate must be in [{MIN_JOINT_STATE_RATE_HZ:g}, {MAX_STREAM_RATE_HZ:g}] Hz of sim time")
    if options.respawn_limit < 0 or not 0.0 <= options.respawn_delay <= 60.0:
        parser.error("--respawn-limit must be >= 0 and --respawn-delay in [0, 60] s")
    return options


def commands_for(options: argparse.Namespace, ros_args: list[str]) -> list[list[str]]:
    """The executables to run, with their arguments."""
    scene = ["-p", f"scene:={options.scene}"] if options.scene else []  # /sim's, and the servers' (goals name its objects)
    sim = ["sim_node", "--ros-args", "-p", f"robot:={options.robot}", "-p", f"real_time_factor:={float(options.rtf)}",
           "-p", f"start_paused:={str(bool(options.paused)).lower()}", *scene]
    if options.clock_rate is not None:
        sim += ["-p", f"clock_rate:={float(options.clock_rate)}"]
    if options.joint_state_rate is not None:
        sim += ["-p", f"joint_state_rate:={float(options.joint_state_rate)}"]
    servers = [["arm_server", "--ros-args", "-p", f"robot:={options.robot}", *scene]]
    if robot_models.walks(options.robot):
        servers.append(["locomotion_server", "--ros-args", "-p", f"robot:={options.robot}", *scene])
    if devices_of(options.robot):  # /power, /hand_sensors, /camera, /head: one process (nodes/devices/container.py)
        servers.append(["device_nodes", "--ros-args", "-p", f"robot:={options.robot}"])
    if options.foxglove:
        servers.append(["foxglove_bridge", "--ros-args", "-p", f"robot:={options.robot}",
                        "-p", f"host:={options.foxglove_host}", "-p", f"port:={options.foxglove_port}"])
    extra = ros_args[1:] if ros_args else []
    if options.namespace:
        extra = ["-r", f"__ns:=/{options.namespace}", *extra]
    return [command + extra for command in [sim, *servers]]


def namespace_of(options: argparse.Namespace, ros_args: list[str]) -> str:
    """The bring-up's namespace: ``--namespace``, else a ``__ns:=`` among the ROS arguments, else "" (the root)."""
    if options.namespace:
        return str(options.namespace)
    return next((a.split(":=", 1)[1].strip("/") for a in ros_args if a.startswith("__ns:=")), "")


def served_actions(commands: list[list[str]]) -> dict[str, list[tuple[str, Any]]]:
    """The actions each of these executables serves: executable -> [(action name, action type)]."""
    return {command[0]: [(name, ACTION_TYPES[skill]) for skill, name in SERVED_BY[command[0]].items()]
            for command in commands if command[0] in SERVED_BY}


def restart_environment() -> dict[str, str]:
    """The environment of a node started again after it died: Fast DDS on UDP only, unless the user chose transports.

    A process that dies by a signal leaves its shared-memory port behind. The next process that opens the same port
    (it may be the restarted node, taking the freed participant index) finds it a zombie, removes its segment and makes
    a new one, while the processes that had written to the old one go on writing there: they discover the restarted
    node but none of their messages reach it (eProsima/Fast-DDS#5053, #4728; Fast DDS 2.14 of the PyPI wheels). A
    restarted server was once reached by no goal for 3 minutes. On UDP only it opens no shared-memory port, and the
    others reach it over the loopback interface (each side uses the locators the other announced).
    """
    return {**os.environ, FASTDDS_TRANSPORTS_VARIABLE: os.environ.get(FASTDDS_TRANSPORTS_VARIABLE, "UDPv4")}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    split = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    options = parse_args(argv[:split])
    try:
        robot_models.check_scene(options.robot, options.scene or None)  # names only: bringup builds no model
    except robot_models.RobotModelError as error:
        print(f"bringup: {error}", file=sys.stderr)
        return 2
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    children: list[ChildProcess] = []
    restarts: dict[int, int] = {}
    commands = commands_for(options, argv[split:])
    # first: discovered by the time any client sends a goal
    keeper = ResultKeeper(served_actions(commands), namespace_of(options, argv[split:]))
    try:
        for command in commands:
            children.append(ChildProcess(command, own_group=False, relay_output=True))
        print(f"bringup: running {', '.join(c.args[0] for c in children)} for {options.robot}; Ctrl-C stops them",
              flush=True)
        while not stop.wait(0.2):
            for index, child in enumerate(children):
                if child.alive():
                    continue
                code = child.process.returncode
                if code == 0:  # it was asked to stop (Ctrl-C reaches the whole process group): so is everything
                    print(f"bringup: {child.args[0]} exited cleanly; stopping the others", flush=True)
                    return 0
                last = "\n".join(f"    {line}" for line in list(child.last_lines)[-10:])
                print(f"bringup: {child.args[0]} died with exit code {code}; its last output:\n{last}",
                      file=sys.stderr, flush=True)
                try:
                    answered = keeper.server_died(child.args[0], code)
                except Exception as error:  # noqa: BLE001  a keeper that cannot answer must not end bringup
                    print(f"bringup: could not answer the clients of {child.args[0]}'s goals: {error}", file=sys.stderr)
                    answered = 0
                if answered:
                    print(f"bringup: answered {answered} request(s) of clients waiting on {child.args[0]}'s goals "
                          "(ABORTED, SIM_FAULT)", file=sys.stderr, flush=True)
                if not options.respawn or restarts.get(index, 0) >= options.respawn_limit:
                    why = "respawn is off" if not options.respawn else f"it was restarted {options.respawn_limit} times"
                    print(f"bringup: {why}; stopping the others", file=sys.stderr, flush=True)
                    return 1
                if stop.wait(options.respawn_delay):
                    return 0
                restarts[index] = restarts.get(index, 0) + 1
                keeper.server_restarting(child.args[0])
                note = " (it starts from its keyframe)" if child.args[0] == "sim_node" else ""
                print(f"bringup: restarting {child.args[0]}{note}, restart {restarts[index]} of {options.respawn_limit}",
                      file=sys.stderr, flush=True)
                children[index] = ChildProcess(commands[index], own_group=False, relay_output=True, env=restart_environment())
        return 0
    finally:
        for child in children:  # signal all first, then wait: they shut down in parallel
            child.send_signal(signal.SIGINT)
        for child in reversed(children):
            child.stop(interrupt=False)
        keeper.close()


if __name__ == "__main__":
    sys.exit(main())
