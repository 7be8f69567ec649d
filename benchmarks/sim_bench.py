"""Benchmark of the /sim node (figures for the closing note; not a test).

For each robot, measured in one run on this machine:
 (a) the sim node's as-fast-as-possible sim-time rate (standing still, /joint_states at 100 Hz of
     sim time, other topics at their defaults), divided by raw ``mj_step`` on the same compiled
     model. Raw rates are measured before and after the node runs; the node's rate is the median
     of its own 1 Hz real-time-factor reports.
 (b) the sim process's CPU use at real_time_factor 1 with /joint_states at 500 Hz, and the
     /joint_states arrival period jitter seen by a subscriber in another process (p50/p99).

Usage: ``make bench`` or ``.venv/bin/python benchmarks/sim_bench.py [--robots g1 panda] [--seconds 8]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import mujoco
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

import robot_models
from sim_client.processes import running
from sim_client.session import RosSession

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def raw_step_rate(robot: str, seconds: float = 2.0) -> float:
    """Physics steps per wall second of plain ``mj_step`` from the default keyframe."""
    spec = robot_models.load(robot)
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


def unpaced_ratio(session: RosSession, robot: str, seconds: float) -> dict[str, float]:
    raw_before = raw_step_rate(robot)
    args = ["sim_node", "--ros-args", "-p", f"robot:={robot}", "-p", "real_time_factor:=0.0", "-p", "joint_state_rate:=100.0"]
    with running(args):
        rtf = session.record(Float64, "/sim/real_time_factor", keep=100)
        session.wait_for(lambda: rtf.count >= 2, 60.0, "the first real-time-factor reports")
        start = rtf.count
        session.wait_for(lambda: rtf.count - start >= seconds, seconds + 30.0, "real-time-factor reports")
        factors = [m.data for m in rtf.messages()[-int(seconds):]]
    raw_after = raw_step_rate(robot)
    timestep = robot_models.load(robot).physics_timestep
    raw_factor = statistics.median([raw_before, raw_after]) * timestep
    node_factor = statistics.median(factors)
    return {"raw_steps_per_s": statistics.median([raw_before, raw_after]), "raw_rtf": raw_factor,
            "node_rtf": node_factor, "ratio": node_factor / raw_factor}


def paced_cpu_and_jitter(session: RosSession, robot: str, seconds: float) -> dict[str, float]:
    args = ["sim_node", "--ros-args", "-p", f"robot:={robot}", "-p", "real_time_factor:=1.0", "-p", "joint_state_rate:=500.0"]
    with running(args) as node:
        arrivals: list[float] = []
        session.node.create_subscription(JointState, "/joint_states", lambda _m: arrivals.append(time.monotonic()), 100)
        session.wait_for(lambda: len(arrivals) > 100, 60.0, "/joint_states at 500 Hz")
        arrivals.clear()
        cpu0, wall0 = process_cpu_seconds(node.process.pid), time.monotonic()
        session.wait_for(lambda: time.monotonic() - wall0 >= seconds, seconds + 10.0, "the CPU window")
        cpu = (process_cpu_seconds(node.process.pid) - cpu0) / (time.monotonic() - wall0)
        periods = np.diff(np.array(arrivals)) * 1e3
    jitter = np.abs(periods - 2.0)
    return {"cpu_percent_of_one_core": 100.0 * cpu, "received_hz": len(periods) / seconds,
            "period_p50_ms": float(np.percentile(periods, 50)), "jitter_p50_ms": float(np.percentile(jitter, 50)),
            "jitter_p99_ms": float(np.percentile(jitter, 99))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(robot_models.ROBOT_NAMES))
    parser.add_argument("--seconds", type=float, default=8.0)
    options = parser.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    with RosSession("sim_bench", use_sim_time=False) as session:
        for robot in options.robots:
            a = unpaced_ratio(session, robot, options.seconds)
            print(f"[{robot}] (a) raw mj_step {a['raw_steps_per_s']:.0f} steps/s = {a['raw_rtf']:.1f}x real time; "
                  f"sim node (JS 100 Hz) median {a['node_rtf']:.1f}x; ratio {a['ratio']:.2f}", flush=True)
            b = paced_cpu_and_jitter(session, robot, options.seconds)
            print(f"[{robot}] (b) rtf 1, JS 500 Hz: sim process CPU {b['cpu_percent_of_one_core']:.1f}% of one core; "
                  f"received {b['received_hz']:.0f} Hz, period p50 {b['period_p50_ms']:.2f} ms, "
                  f"jitter p50 {b['jitter_p50_ms']:.3f} ms p99 {b['jitter_p99_ms']:.3f} ms", flush=True)


if __name__ == "__main__":
    main()
