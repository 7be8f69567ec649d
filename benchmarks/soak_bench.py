"""Soak: many clients for minutes against ``bringup --robot g1``; memory, CPU, goals and /joint_states.

``python benchmarks/soak_bench.py [--minutes 10] [--clients 10]``. Each client (a process of its own)
loops: a Walk goal (a short step back or forth) or a MoveArm goal on a G1 arm,
a ``walking_speed`` change through the parameter services, a parameter read of /sim. Meanwhile
/joint_states is subscribed at the sim's highest rate (500 Hz), by a process of its own. Printed at the
end: per process RSS growth (from the first minute to the end, so start-up allocation is not counted) and CPU share; goals sent /
succeeded / failed / lost (no result within 120 s); /joint_states received against published (its
stamps) and the jitter of its arrivals.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import pathlib
import random
import statistics
import subprocess
import sys
import threading
import time
from typing import Any

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

JOINT_RATE_HZ = 500.0  # the sim's highest joint_state_rate
RESULT_WALL_S = 120.0


def process_stats(pid: int) -> tuple[float, float]:
    """(RSS [MiB], CPU time [s]) of a process and its threads, from /proc."""
    status = pathlib.Path(f"/proc/{pid}/status").read_text()
    rss_kib = next(int(line.split()[1]) for line in status.splitlines() if line.startswith("VmRSS:"))
    fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return rss_kib / 1024.0, (int(fields[11]) + int(fields[12])) / ticks


class Counts:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.sent = self.succeeded = self.failed = self.rejected = 0
        self.lost_request = self.lost_result = 0  # no goal response within 30 s / no result within RESULT_WALL_S
        self.params = self.param_failures = self.queries = 0
        self.failures: dict[str, int] = {}

    def add(self, **values: int) -> None:
        with self.lock:
            for key, value in values.items():
                setattr(self, key, getattr(self, key) + value)


def client_loop(index: int, stop: threading.Event, counts: Counts) -> None:
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import GetParameters, SetParameters

    from sim_client import RosSession
    from sim_client.session import WaitTimeout
    from sim_interfaces.action import MoveArm, Walk
    from tests.ros.actions import ready_client, result, send

    rng = random.Random(index)
    with RosSession(f"soak_{index}", use_sim_time=False) as session:
        walk = ready_client(session, Walk, "/walk", timeout=120.0)
        arm = ready_client(session, MoveArm, "/move_arm", timeout=120.0)
        while not stop.is_set():
            if rng.random() < 0.5:
                goal: Any = Walk.Goal(distance=rng.choice((-0.3, 0.3)), speed=0.3)
                action, action_type = walk, Walk
            else:
                goal = MoveArm.Goal(end_effector=rng.choice(("left_arm", "right_arm")), position_tolerance=0.005)
                goal.target.header.frame_id = "pelvis"
                side = 1.0 if goal.end_effector == "left_arm" else -1.0
                goal.target.pose.position.x, goal.target.pose.position.y = 0.25, side * rng.uniform(0.15, 0.3)
                goal.target.pose.position.z = rng.uniform(0.05, 0.25)
                goal.target.pose.orientation.w = 1.0
                action, action_type = arm, MoveArm
            try:
                sent = send(session, action, goal, timeout=30.0)
            except WaitTimeout:
                counts.add(sent=1, lost_request=1)
                continue
            counts.add(sent=1)
            if not sent.handle.accepted:
                counts.add(rejected=1)
                continue
            try:
                outcome = result(session, sent, timeout=RESULT_WALL_S)
            except WaitTimeout:
                counts.add(lost_result=1)
                continue
            code = outcome.result.error_code
            if code == action_type.Result.SUCCESS:
                counts.add(succeeded=1)
            else:
                counts.add(failed=1)
                key = f"{action_type.__name__} {code}: {outcome.result.error_msg[:60]}"
                with counts.lock:
                    counts.failures[key] = counts.failures.get(key, 0) + 1
            speed = round(rng.uniform(0.2, 0.6), 2)
            request = SetParameters.Request(parameters=[Parameter(name="walking_speed", value=ParameterValue(
                type=ParameterType.PARAMETER_DOUBLE, double_value=speed))])
            try:
                answer = session.call(SetParameters, "/locomotion/set_parameters", request, timeout=30.0)
                counts.add(params=1, param_failures=0 if answer.results[0].successful else 1)
                session.call(GetParameters, "/sim/get_parameters", GetParameters.Request(names=["real_time_factor"]),
                             timeout=30.0)
                counts.add(queries=1)
            except WaitTimeout:
                counts.add(param_failures=1)


def run_client(index: int, seconds: float) -> None:
    """One client process: the loop for ``seconds``, then its counts as one JSON line."""
    stop = threading.Event()
    counts = Counts()
    worker = threading.Thread(target=client_loop, args=(index, stop, counts), daemon=True)
    worker.start()
    worker.join(seconds)
    stop.set()
    worker.join(RESULT_WALL_S + 30.0)
    print(json.dumps({key: value for key, value in vars(counts).items() if key != "lock"}), flush=True)


def run_listener(seconds: float) -> None:
    """The /joint_states listener process: stamps and arrival times over ``seconds``, then a JSON line."""
    from sensor_msgs.msg import JointState

    from sim_client import RosSession

    arrivals: list[float] = []
    stamps: list[float] = []

    def on_joints(msg: JointState) -> None:
        arrivals.append(time.monotonic())
        stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)

    with RosSession("soak_joint_states", use_sim_time=False) as listener:
        listener.node.create_subscription(JointState, "/joint_states", on_joints, 1000)
        listener.wait_for(lambda: len(stamps) > 100, 120.0, "/joint_states")
        begin = len(stamps)
        time.sleep(seconds)  # the listening window
        end = len(stamps)
    window_arrivals, window_stamps = arrivals[begin:end], stamps[begin:end]
    gaps = [b - a for a, b in itertools.pairwise(window_arrivals)]
    published = round((window_stamps[-1] - window_stamps[0]) * JOINT_RATE_HZ) + 1
    print(json.dumps({"received": len(window_stamps), "published": published, "gap_median_ms": 1e3 * statistics.median(gaps),
                      "gap_p99_ms": 1e3 * sorted(gaps)[int(0.99 * (len(gaps) - 1))], "gap_max_ms": 1e3 * max(gaps)}),
          flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--clients", type=int, default=10)
    parser.add_argument("--client", type=int, default=None, help=argparse.SUPPRESS)  # internal: one client process
    parser.add_argument("--listener", action="store_true", help=argparse.SUPPRESS)  # internal: the /joint_states listener
    options = parser.parse_args()
    seconds = options.minutes * 60.0
    if options.client is not None:
        run_client(options.client, seconds)
        return 0
    if options.listener:
        run_listener(seconds)
        return 0
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    from nodes.processes import ChildProcess, child_processes

    bringup = ChildProcess(["bringup", "--robot", "g1", "--rtf", "1", "--no-respawn", "--ros-args", "-p",
                            f"joint_state_rate:={JOINT_RATE_HZ}"])
    me = [sys.executable, str(pathlib.Path(__file__).resolve())]
    try:
        listener = subprocess.Popen([*me, "--listener", "--minutes", str(options.minutes)], stdout=subprocess.PIPE, text=True)
        clients = [subprocess.Popen([*me, "--client", str(i), "--minutes", str(options.minutes)], stdout=subprocess.PIPE,
                                    text=True) for i in range(options.clients)]
        nodes: dict[str, int] = {}
        while len(nodes) < 5 and bringup.alive():
            time.sleep(0.5)  # until bringup has started its nodes
            nodes = child_processes(bringup.process.pid)
        warm = min(60.0, seconds / 5)
        time.sleep(warm)  # the first sample after start-up allocation
        first = {name: process_stats(pid) for name, pid in nodes.items()}
        first_wall = time.monotonic()
        deadline = first_wall + seconds - warm
        while time.monotonic() < deadline and bringup.alive():
            time.sleep(1.0)  # the soak's duration
        last = {name: process_stats(pid) for name, pid in nodes.items()}
        wall = time.monotonic() - first_wall
        outputs = [json.loads((c.communicate(timeout=RESULT_WALL_S + 120.0)[0] or "{}").strip().splitlines()[-1])
                   for c in clients]
        joints = json.loads(listener.communicate(timeout=300.0)[0].strip().splitlines()[-1])
        alive = bringup.alive()
    finally:
        bringup.stop(timeout=30.0)
    total = {key: sum(o.get(key, 0) for o in outputs) for key in outputs[0] if key != "failures"}
    failures: dict[str, int] = {}
    for output in outputs:
        for key, count in output.get("failures", {}).items():
            failures[key] = failures.get(key, 0) + count
    print(f"soak: {options.clients} client processes, {options.minutes:g} min, /joint_states at {JOINT_RATE_HZ:g} Hz "
          f"subscribed; bringup {'alive' if alive else 'DIED'} to the end")
    print(f"{'process':<20} {'RSS first [MiB]':>16} {'RSS end [MiB]':>14} {'growth':>8} {'CPU [% of a core]':>18}")
    for name in sorted(last):
        rss0, cpu0 = first[name]
        rss1, cpu1 = last[name]
        print(f"{name:<20} {rss0:>16.1f} {rss1:>14.1f} {100 * (rss1 / rss0 - 1):>7.1f}% {100 * (cpu1 - cpu0) / wall:>17.1f}%")
    print(f"goals: sent {total['sent']}, succeeded {total['succeeded']}, failed {total['failed']}, rejected "
          f"{total['rejected']}, lost {total['lost_request']} requests / {total['lost_result']} results; parameter sets "
          f"{total['params']} ({total['param_failures']} failed), queries {total['queries']}")
    for key, count in sorted(failures.items(), key=lambda item: -item[1])[:6]:
        print(f"  {count:>5} x {key}")
    lost = 100 * (1 - joints["received"] / max(joints["published"], 1))
    print(f"/joint_states: received {joints['received']} of {joints['published']} published ({lost:.2f}% lost); arrival gap "
          f"median {joints['gap_median_ms']:.2f} ms, p99 {joints['gap_p99_ms']:.2f} ms, max {joints['gap_max_ms']:.1f} ms")
    return 0

if __name__ == "__main__":
    sys.exit(main())
