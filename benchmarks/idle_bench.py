"""Idle CPU of every node of a bringup (figures for the closing note; not a test).

For each robot, the nodes ``bringup`` would start (``sim_node``, ``arm_server`` and, for the G1,
``locomotion_server`` and the device nodes) run under ``bringup``, each in its process, on a ROS
domain of their own, with nobody subscribed and no goal. Once every server answers (its action
servers are discoverable), each process's CPU time (user + system, from ``/proc/<pid>/stat``) is read over a window of wall time:

- "running": ``/sim`` steps the physics at real_time_factor 1 and publishes its default streams
  (the servers are idle; the sim node does the physics and its publication work);
- "paused": after ``/sim/pause`` (the sim node is idle too).

Next to them, the floor of any node on sim time: a bare rclpy node that only receives ``/clock``
(at the sim's default 100 Hz) in a process of its own.

Figures are percent of one core; the median of ``--rounds`` windows is printed.

First, the start-up: the wall time from starting ``bringup`` until every server answers, and the CPU
time each process used until then (compiled models read from ``robot_models.model_cache`` where a
run before wrote them; ``SIM_MODEL_CACHE=off`` compiles them).

Then each process's memory, read once every server answers: resident (RSS, from
``/proc/<pid>/status``) and, where ``/proc/<pid>/smaps_rollup`` is readable, proportional (PSS:
a shared library counts once, split among the processes that map it), summed over the robot's
processes (the floor's bare node is listed, not summed); for the G1, next to the goal of issue 24
(a whole bringup <= 1.2 GB resident) with the margin or the excess.

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
MEMORY_GOAL_MB = 1200.0  # [MB] resident memory of a whole G1 bringup (issue 24)


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far [s]."""
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def cpu_percent(pids: dict[str, int], seconds: float) -> dict[str, float]:
    """Percent of one core each process (name -> pid) used over ``seconds`` of wall time."""
    start_wall = time.perf_counter()
    start = {name: cpu_seconds(pid) for name, pid in pids.items()}
    time.sleep(seconds)  # a measurement window, not a wait for a condition
    wall = time.perf_counter() - start_wall
    return {name: 100.0 * (cpu_seconds(pid) - start[name]) / wall for name, pid in pids.items()}


def child_pids(parent: int) -> dict[str, int]:
    """The processes ``parent`` started, by executable name (from ``/proc/*/stat`` and ``cmdline``)."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as stat:
                ppid = int(stat.read().rsplit(")", 1)[1].split()[1])
            with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                args = cmdline.read().split(b"\0")
        except (OSError, ValueError, IndexError):  # it ended meanwhile
            continue
        if ppid == parent and len(args) > 1:
            found[os.path.basename(args[1].decode())] = int(entry)  # args[0] is the venv's python
    return found


def wait_ready(session: RosSession, robot: str, deadline_s: float = 60.0) -> None:
    """Until every server of ``robot`` has its action servers discoverable."""
    wanted = {"/move_arm", "/pick_place"}
    if robot_models.walks(robot):
        wanted |= {"/walk", "/navigate_to_pose"}
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        actions = {name.removesuffix("/_action/send_goal") for name, _ in session.node.get_service_names_and_types()}
        if wanted <= actions:
            return
        time.sleep(0.2)  # polling the ROS graph, bounded by the deadline
    raise RuntimeError(f"servers of {robot} not up within {deadline_s:.0f} s: want {sorted(wanted)}")


def memory_mb(pid: int) -> tuple[float, float | None]:
    """(RSS, PSS) of a process [MB]; PSS is None when ``smaps_rollup`` cannot be read."""
    with open(f"/proc/{pid}/status") as status:
        rss_kb = next(int(line.split()[1]) for line in status if line.startswith("VmRSS:"))
    try:
        with open(f"/proc/{pid}/smaps_rollup") as rollup:
            pss_kb: int | None = next(int(line.split()[1]) for line in rollup if line.startswith("Pss:"))
    except (OSError, StopIteration):
        pss_kb = None
    return rss_kb / 1024.0, None if pss_kb is None else pss_kb / 1024.0


def print_memory(robot: str, memory: dict[str, tuple[float, float | None]]) -> None:
    """Each process's RSS and PSS, and the robot's processes summed next to the goal (a G1 bringup's)."""
    goal = robot == robot_models.G1  # the goal is a G1 bringup's (issue 24)
    print(f"  {robot:6s} memory per process" + (f" (goal: all of them <= {MEMORY_GOAL_MB:.0f} MB resident)" if goal else ""),
          flush=True)
    for name, (rss, pss) in memory.items():
        print(f"  {robot:6s} {name:18s} RSS: {rss:6.0f} MB   PSS: {'-' if pss is None else f'{pss:.0f}':>6s} MB", flush=True)
    nodes = [value for name, value in memory.items() if not name.startswith("floor")]
    total_rss = sum(rss for rss, _ in nodes)
    pss_values = [pss for _, pss in nodes if pss is not None]
    total_pss = f"{sum(pss_values):.0f} MB" if len(pss_values) == len(nodes) else "-"
    verdict = ""
    if goal:
        margin = MEMORY_GOAL_MB - total_rss
        verdict = (f"   goal <= {MEMORY_GOAL_MB:.0f} MB: " +
                   (f"met, {margin:.0f} MB to spare" if margin >= 0 else f"MISSED by {-margin:.0f} MB"))
    print(f"  {robot:6s} {'all ' + str(len(nodes)) + ' processes':18s} RSS: {total_rss:6.0f} MB   PSS: {total_pss:>9s}{verdict}",
          flush=True)


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
    expected = [command[0] for command in commands_for(parse_args(["--robot", robot]), [])]
    floor = ChildProcess(["python", "-c", CLOCK_FLOOR])
    try:
        with RosSession(f"idle_bench_{robot}", use_sim_time=False) as session:
            started = time.perf_counter()
            bringup = ChildProcess(["bringup", "--robot", robot])
            wait_ready(session, robot)
            ready_s = time.perf_counter() - started
            at_ready = {name: cpu_seconds(pid) for name, pid in child_pids(bringup.process.pid).items()}
            at_ready["bringup"] = cpu_seconds(bringup.process.pid)
            time.sleep(2.0)  # let start-up transients (discovery, first messages) pass before measuring
            nodes = child_pids(bringup.process.pid)
            if sorted(nodes) != sorted(expected):
                raise RuntimeError(f"bringup runs {sorted(nodes)}, expected {sorted(expected)}")
            pids = {name: nodes[name] for name in expected} | {"bringup": bringup.process.pid,
                                                                  "floor: bare node": floor.process.pid}
            memory = {name: memory_mb(pid) for name, pid in pids.items()}
            running = median_table([cpu_percent(pids, seconds) for _ in range(rounds)])
            session.call(Trigger, "/sim/pause", Trigger.Request(), timeout=10.0)
            paused = median_table([cpu_percent(pids, seconds) for _ in range(rounds)])
    finally:
        floor.stop()
        if "bringup" in locals():
            bringup.stop()
    print(f"  {robot:6s} start-up: {ready_s:.1f} s of wall time until every server answered; CPU until then: "
          f"{sum(at_ready.values()):.1f} s in all", flush=True)
    for name, cpu in at_ready.items():
        print(f"  {robot:6s} {name:18s} start-up CPU: {cpu:5.2f} s", flush=True)
    for name in running:
        print(f"  {robot:6s} {name:18s} running: {running[name]:5.1f} %   paused: {paused[name]:5.1f} %", flush=True)
    print_memory(robot, memory)


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
