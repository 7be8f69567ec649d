"""Idle CPU of every node of a bringup (figures for the closing note; not a test).

For each robot, the nodes ``bringup`` would start (``sim_node``, ``arm_server`` and, for the G1,
``locomotion_server``) run as separate processes on a ROS domain of their own, with nobody
subscribed and no goal. Once every server answers (its action servers are discoverable), each
process's CPU time (user + system, from ``/proc/<pid>/stat``) is read over a window of wall time:

- "running": ``/sim`` steps the physics at real_time_factor 1 and publishes its default streams
  (the servers are idle; the sim node does the physics and its publication work);
- "paused": after ``/sim/pause`` (the sim node is idle too).

Next to them, the floor of any node on sim time: a bare rclpy node that only receives ``/clock``
(at the sim's default 100 Hz) in a process of its own.

Figures are percent of one core; the median of ``--rounds`` windows is printed.

Usage: ``make bench-idle`` or ``.venv/bin/python benchmarks/idle_bench.py [--robots g1 panda] [--seconds 5]``.
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import time

# A domain of this run's own, on this machine only: set before rclpy is imported.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + random.randrange(101)))  # 1..101: safe for Fast DDS ports
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

# Imported once the ROS environment above is fixed.
from std_srvs.srv import Trigger

import robot_models
from nodes.launch.bringup import commands_for, parse_args
from sim_ros.processes import ChildProcess
from sim_ros.session import RosSession

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far [s]."""
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def cpu_percent(children: list[ChildProcess], seconds: float) -> dict[str, float]:
    """Percent of one core each child used over ``seconds`` of wall time."""
    start_wall = time.perf_counter()
    start = {c.args[0]: cpu_seconds(c.process.pid) for c in children}
    time.sleep(seconds)  # a measurement window, not a wait for a condition
    wall = time.perf_counter() - start_wall
    return {c.args[0]: 100.0 * (cpu_seconds(c.process.pid) - start[c.args[0]]) / wall for c in children}


def wait_ready(session: RosSession, robot: str, deadline_s: float = 60.0) -> None:
    """Until every server of ``robot`` has its action servers discoverable."""
    wanted = {"/move_arm", "/pick_place"}
    if robot_models.load(robot).feet_sites:
        wanted |= {"/walk", "/navigate_to_pose"}
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        actions = {name.removesuffix("/_action/send_goal") for name, _ in session.node.get_service_names_and_types()}
        if wanted <= actions:
            return
        time.sleep(0.2)  # polling the ROS graph, bounded by the deadline
    raise RuntimeError(f"servers of {robot} not up within {deadline_s:.0f} s: want {sorted(wanted)}")


def median_table(rounds: list[dict[str, float]]) -> dict[str, float]:
    return {name: statistics.median(r[name] for r in rounds) for name in rounds[0]}


# The floor: a bare rclpy node on sim time (subscribed to /clock only, nothing else), spun by rclpy's
# single-threaded executor, in its own process.
CLOCK_FLOOR = """
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
rclpy.init()
node = Node("idle_bench_clock_floor", parameter_overrides=[Parameter("use_sim_time", value=True)])
try:
    rclpy.spin(node)
except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
    pass
"""


def bench_robot(robot: str, seconds: float, rounds: int) -> None:
    children = [ChildProcess(command) for command in commands_for(parse_args(["--robot", robot]), [])]
    children.append(ChildProcess(["python", "-c", CLOCK_FLOOR]))
    children[-1].args[0] = "floor: bare node"
    try:
        with RosSession(f"idle_bench_{robot}", use_sim_time=False) as session:
            wait_ready(session, robot)
            time.sleep(2.0)  # let start-up transients (discovery, first messages) pass before measuring
            running = median_table([cpu_percent(children, seconds) for _ in range(rounds)])
            session.call(Trigger, "/sim/pause", Trigger.Request(), timeout=10.0)
            paused = median_table([cpu_percent(children, seconds) for _ in range(rounds)])
    finally:
        for child in children:
            child.stop()
    for name in running:
        print(f"  {robot:6s} {name:18s} running: {running[name]:5.1f} %   paused: {paused[name]:5.1f} %", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(robot_models.ROBOT_NAMES))
    parser.add_argument("--seconds", type=float, default=5.0, help="wall seconds per measurement window")
    parser.add_argument("--rounds", type=int, default=3, help="windows per state; the median is printed")
    options = parser.parse_args()
    print(f"idle CPU per node, % of one core (median of {options.rounds} x {options.seconds:.0f} s; "
          f"goal <= 2 % for servers; the running sim node does physics at real time)")
    for robot in options.robots:
        bench_robot(robot, options.seconds, options.rounds)


if __name__ == "__main__":
    main()
