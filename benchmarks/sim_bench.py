"""Benchmark of the /sim node (figures for the closing note; not a test).

For each robot, measured in one run on this machine:
 (a) the sim node's as-fast-as-possible sim-time rate (standing still, /joint_states at 100 Hz of
     sim time, other topics at their defaults), divided by raw ``mj_step`` on the same compiled
     model. This machine is shared and its speed drifts by 2x within seconds, so the two are
     interleaved: the node is paused (``/sim/pause``) while raw ``mj_step`` runs for a second, then
     resumed and its own 1 Hz real-time-factor reports are read; the figure is the median of the
     per-round ratios. Measured twice: with no subscriber (as specified: no stream but /clock is
     then built or published), and with this process subscribed
     to /clock, /joint_states, /odom, /tf and /objects (every stream built and delivered; the
     subscriber's own work then competes for the machine's two cores).
 (b) the sim process's CPU use at real_time_factor 1 with /joint_states at 500 Hz, and the
     /joint_states arrival period jitter seen by a subscriber in another process (p50/p99).
     Two floors at the same 2 ms cadence put it in context: a bare ``mj_step`` loop with no ROS,
     and a child process doing only that loop plus one rclpy JointState publish per period.

Usage: ``make bench`` or ``.venv/bin/python benchmarks/sim_bench.py [--robots g1 panda] [--seconds 8]``.
"""

from __future__ import annotations

import argparse
import functools
import os
import re
import statistics
import time

import mujoco
import numpy as np
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage

import robot_models
from sim_bridge import Simulation
from sim_interfaces.msg import ObjectStates
from sim_ros.processes import running
from sim_ros.session import RosSession

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


@functools.cache
def _spec(robot: str) -> robot_models.RobotSpec:
    return robot_models.load(robot)


def raw_step_rate(robot: str, seconds: float = 2.0) -> float:
    """Physics steps per wall second of plain ``mj_step`` from the default keyframe."""
    spec = _spec(robot)
    model = spec.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(spec.default_keyframe).id)
    mujoco.mj_step(model, data, nstep=500)  # warm-up
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        mujoco.mj_step(model, data, nstep=1000)
        steps += 1000
    return steps / (time.perf_counter() - start)


def process_cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as handle:
        fields = handle.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def unpaced_ratio(session: RosSession, robot: str, rounds: int, all_topics: bool) -> dict[str, float]:
    timestep = _spec(robot).physics_timestep
    args = ["sim_node", "--ros-args", "-p", f"robot:={robot}", "-p", "real_time_factor:=0.0", "-p", "joint_state_rate:=100.0"]
    with running(args):
        rtf = session.record(Float64, "/sim/real_time_factor", keep=1000)
        topics = [(Clock, "/clock"), (JointState, "/joint_states"), (Odometry, "/odom"), (TFMessage, "/tf")]
        topics += [(ObjectStates, "/objects")] if _spec(robot).objects else []
        streams = [session.record(msg_type, topic, keep=1) for msg_type, topic in topics] if all_topics else []
        session.wait_for(lambda: rtf.count >= 2, 60.0, "the node's first reports")
        raw_rates, node_rates, ratios = [], [], []
        for _ in range(rounds):
            assert session.call(Trigger, "/sim/pause", Trigger.Request()).success
            raw = raw_step_rate(robot, seconds=1.0) * timestep
            assert session.call(Trigger, "/sim/resume", Trigger.Request()).success
            first = rtf.count + 1  # the first report after resuming covers part of a window: skip it
            session.wait_for(lambda: rtf.count >= first + 2, 30.0, "two real-time-factor reports")  # noqa: B023 - called in this iteration
            node = statistics.median(m.data for m in rtf.messages()[first:first + 2])
            raw_rates.append(raw)
            node_rates.append(node)
            ratios.append(node / raw)
        received = [stream.count > 0 for stream in streams]
        for recorder in (rtf, *streams):
            recorder.stop()  # a subscription left behind would load the next measurement
    assert all(received), "every subscribed stream was received"
    return {"raw_rtf": statistics.median(raw_rates), "node_rtf": statistics.median(node_rates),
            "ratio": statistics.median(ratios), "ratio_min": min(ratios), "ratio_max": max(ratios)}


def physics_floor_cpu(robot: str, period_s: float, seconds: float) -> float:
    """CPU [% of one core] of a bare loop (no ROS) stepping the physics of one period each period.

    On a shared virtual machine a thread that sleeps between short bursts finds its caches cold:
    here one G1 ``mj_step`` right after a 2 ms sleep costs ~2.5x a back-to-back one. This is the
    floor under (b) that no node design removes; the node's own cost is what lies above it.
    """
    spec = _spec(robot)
    model = spec.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(spec.default_keyframe).id)
    steps = max(1, round(period_s / model.opt.timestep))
    start, cpu0 = time.monotonic(), time.thread_time()
    due = start
    while time.monotonic() - start < seconds:
        mujoco.mj_step(model, data, nstep=steps)
        due += period_s
        time.sleep(max(0.0, due - time.monotonic()))
    return 100.0 * (time.thread_time() - cpu0) / (time.monotonic() - start)


def ros_floor_child(robot: str, period_s: float, seconds: float) -> None:
    """Child process of :func:`ros_floor_cpu`: the bare loop plus one rclpy /joint_states publish per period."""
    import rclpy
    from rclpy.qos import QoSProfile

    from nodes.sim.serialized import JointStateTemplate

    sim = Simulation(_spec(robot))  # the model and joint indexing; stepped with bare mj_step below
    model, data = sim.model, sim.data
    steps = max(1, round(period_s / model.opt.timestep))
    rclpy.init()
    node = rclpy.create_node("sim_bench_floor")
    publisher = node.create_publisher(JointState, "/joint_states", QoSProfile(depth=10))
    template = JointStateTemplate(list(sim.robot.actuated_joints))
    while publisher.get_subscription_count() == 0:  # the parent's subscriber; it bounds this wait
        time.sleep(0.01)
    pid = os.getpid()
    start, cpu0, process0 = time.monotonic(), time.thread_time(), process_cpu_seconds(pid)
    due = start
    while time.monotonic() - start < seconds:
        mujoco.mj_step(model, data, nstep=steps)
        publisher.publish(template.serialize(data.time, *sim.joint_arrays()))
        due += period_s
        time.sleep(max(0.0, due - time.monotonic()))
    wall = time.monotonic() - start
    thread = 100.0 * (time.thread_time() - cpu0) / wall
    process = 100.0 * (process_cpu_seconds(pid) - process0) / wall
    print(f"FLOOR thread {thread:.2f} process {process:.2f}", flush=True)
    node.destroy_node()
    rclpy.shutdown()


def ros_floor_cpu(session: RosSession, robot: str, period_s: float, seconds: float) -> float:
    """CPU [% of one core] of a child process doing only a bare physics loop plus one rclpy publish.

    The same 2 ms cadence as (b), each period one ``mj_step`` stretch and one pre-serialized
    JointState published to a subscriber in this process; no node logic at all. What the sim
    node costs above this is its own.
    """
    arrivals: list[float] = []
    subscription = session.node.create_subscription(
        JointState, "/joint_states", lambda _m: arrivals.append(time.monotonic()), 100)
    with running(["python", __file__, "--ros-floor-child", robot, str(period_s), str(seconds)]) as child:
        session.wait_for(lambda: not child.alive(), seconds + 60.0, "the floor measurement")
        match = re.search(r"FLOOR thread \S+ process (\S+)", child.output())
    session.node.destroy_subscription(subscription)
    assert match is not None and arrivals, f"the floor child failed: {child.output()[-2000:]}"
    return float(match.group(1))


def paced_cpu_and_jitter(session: RosSession, robot: str, seconds: float) -> dict[str, float]:
    args = ["sim_node", "--ros-args", "-p", f"robot:={robot}", "-p", "real_time_factor:=1.0", "-p", "joint_state_rate:=500.0"]
    with running(args) as node:
        arrivals: list[float] = []
        subscription = session.node.create_subscription(
            JointState, "/joint_states", lambda _m: arrivals.append(time.monotonic()), 100)
        session.wait_for(lambda: len(arrivals) > 100, 60.0, "/joint_states at 500 Hz")
        arrivals.clear()
        cpu0, wall0 = process_cpu_seconds(node.process.pid), time.monotonic()
        session.wait_for(lambda: time.monotonic() - wall0 >= seconds, seconds + 10.0, "the CPU window")
        cpu = (process_cpu_seconds(node.process.pid) - cpu0) / (time.monotonic() - wall0)
        periods = np.diff(np.array(arrivals)) * 1e3
        session.node.destroy_subscription(subscription)
    jitter = np.abs(periods - 2.0)
    return {"cpu_percent_of_one_core": 100.0 * cpu, "received_hz": len(periods) / seconds,
            "period_p50_ms": float(np.percentile(periods, 50)), "jitter_p50_ms": float(np.percentile(jitter, 50)),
            "jitter_p99_ms": float(np.percentile(jitter, 99))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(robot_models.ROBOT_NAMES))
    parser.add_argument("--seconds", type=float, default=8.0, help="length of the CPU/jitter window (b)")
    parser.add_argument("--rounds", type=int, default=6, help="pause/raw/resume/node rounds of (a)")
    parser.add_argument("--ros-floor-child", nargs=3, metavar=("ROBOT", "PERIOD_S", "SECONDS"), help=argparse.SUPPRESS)
    options = parser.parse_args()
    if options.ros_floor_child:
        robot, period, seconds = options.ros_floor_child
        ros_floor_child(robot, float(period), float(seconds))
        return
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    with RosSession("sim_bench", use_sim_time=False) as session:
        for robot in options.robots:
            for all_topics, label in ((False, "no subscribers"), (True, "all topics subscribed")):
                a = unpaced_ratio(session, robot, options.rounds, all_topics)
                print(f"[{robot}] (a) {label}: raw mj_step median {a['raw_rtf']:.1f}x real time, sim node (JS 100 Hz) "
                      f"median {a['node_rtf']:.1f}x; ratio median {a['ratio']:.2f} (rounds {a['ratio_min']:.2f}-"
                      f"{a['ratio_max']:.2f})", flush=True)
            b = paced_cpu_and_jitter(session, robot, options.seconds)
            floor = physics_floor_cpu(robot, 0.002, options.seconds)
            ros_floor = ros_floor_cpu(session, robot, 0.002, options.seconds)
            print(f"[{robot}] (b) rtf 1, JS 500 Hz: sim process CPU {b['cpu_percent_of_one_core']:.1f}% of one core "
                  f"(floors at the same 2 ms cadence: bare mj_step loop, no ROS, {floor:.1f}%; the same loop plus "
                  f"one rclpy JointState publish per period, whole process, {ros_floor:.1f}%); "
                  f"received {b['received_hz']:.0f} Hz, period p50 {b['period_p50_ms']:.2f} ms, "
                  f"jitter p50 {b['jitter_p50_ms']:.3f} ms p99 {b['jitter_p99_ms']:.3f} ms", flush=True)


if __name__ == "__main__":
    main()
