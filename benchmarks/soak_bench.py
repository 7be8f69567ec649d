"""Soak: many clients for minutes against ``bringup --robot g1``; memory, CPU, goals, parameters, /joint_states.

``python benchmarks/soak_bench.py [--minutes 10] [--clients 10] [--rtf 2]``. Each client (a process of
its own) loops: a Walk goal (a short step back or forth) or a MoveArm goal on a G1 arm, then a
``walking_speed`` change through /locomotion's parameter services and a parameter read of /sim.
Meanwhile /joint_states is counted by a listener process of its own.

/joint_states at 1 kHz: the G1's physics steps every 2 ms of sim time (robot_models/g1.py), so /sim
publishes at most 500 distinct joint states per second of *sim* time (joint_state_rate 500). 1 kHz of
*wall* time is that stream at real_time_factor 2, the default here; the achieved factor and rate are
measured and printed, never assumed. The listener subscribes raw (serialized bytes) and reads only the
header stamp from the CDR, as a counting listener should: deserializing a 29-joint JointState in
Python 1000 times a second costs a loaded 2-core machine more than it has. Its reader queue (reliable,
keep-last) holds :data:`LISTENER_QUEUE_S` seconds of the stream, so a listener whose Python lags loses
nothing. A message counts as lost when its stamp (every physics step's) never arrives; each hole is
printed with the listener's longest stall before it: /sim's writer keeps ``STREAM_HISTORY_DEPTH``
states (10 s of sim time at 500 Hz), and a listener process stalled longer than that (its DDS threads
too) loses what it had not acknowledged. Measured with the listener stopped (SIGSTOP) every 8 s, the sim
otherwise idle, when the writer kept 1000: 1.5 s stops at 500 Hz lost nothing, 2.5 s stops lost 250
states each (1250 - 1000). On a machine loaded far beyond its 2 cores, holes come after shorter stalls
too (the repairs a reliable writer sends need CPU on both ends). The soak fills both cores, so the
listener asks for a higher priority (:data:`LISTENER_NICE`), as a recorder on a core of its own would
have: otherwise it measures its own starvation (6% of a core in one run), not /sim's delivery.

The clients' service readers keep ``sim_ros.session.RESPONSE_QOS``'s 1000 responses: a server's responses go to every
client and each client throws the others' away only as it reads them, so with rclpy's default
(keep-last 10) a client stalled while the other nine were answered lost its own response.

Every request is waited for up to :data:`LOST_S` wall seconds: answered within its deadline it is on
time, answered later it is *late* (counted and printed apart), never answered it is *lost*. Goals a
newer goal on the same resource preempts (10 clients share the G1's legs and two arms) end PREEMPTED,
by design; they are counted apart from failures. A client whose Walk ends FELL resets /sim (the fall
is counted), so one fall does not fail every later goal. A MoveArm target is given in the pelvis frame and
fixed in the world when the goal starts, so an arm goal running while another client's Walk moves the
robot can end UNREACHABLE: a failure with its reason, not a loss.

Printed at the end: per process RSS growth (first sample after a warm-up, so start-up allocation is
not counted, to the end) and CPU share; goals sent / succeeded / preempted / failed / late / lost with
the latencies of goal responses and results; parameter calls (sets and reads) with failures, late and
lost; /joint_states received against published (every stamp checked), the achieved rate, and jitter.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import pathlib
import random
import re
import struct
import subprocess
import sys
import threading
import time
from array import array
from typing import Any

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

JOINT_RATE_HZ = 500.0  # [Hz of sim time] one joint state per physics step of the G1 (2 ms): the most there is
DEFAULT_RTF = 2.0  # 500 Hz of sim time at real_time_factor 2 = 1 kHz of wall time
LISTENER_QUEUE_S = 5.0  # [s of wall time] of /joint_states the listener's reader queue holds (5000: Fast DDS's max_samples)
GOAL_ANSWER_S = 5.0  # [s] deadline of a goal response: answered later is late
PARAM_ANSWER_S = 5.0  # [s] deadline of a parameter call's response
RESULT_S = 30.0  # [s] deadline of a goal's result (a 0.3 m step or an arm reach takes a few seconds of sim time)
LOST_S = 120.0  # [s] a request not answered within this long is lost
LISTENER_NICE = -10  # the listener is the instrument: it asks for this priority (needs the right to; else it runs at 0)
STALL_WINDOW_S = 5.0  # [s] before a hole in /joint_states, where the listener's longest stall is looked for
CLOSE_S = 20.0  # [s] a client's ROS session gets this long to close after it reported


def process_stats(pid: int) -> tuple[float, float]:
    """(RSS [MiB], CPU time [s]) of a process and its threads, from /proc."""
    status = pathlib.Path(f"/proc/{pid}/status").read_text()
    rss_kib = next(int(line.split()[1]) for line in status.splitlines() if line.startswith("VmRSS:"))
    fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return rss_kib / 1024.0, (int(fields[11]) + int(fields[12])) / ticks


def wait_timed(future: Any, limit_s: float) -> tuple[Any, float]:
    """(the future's result or None if not done within ``limit_s``, wall seconds waited)."""
    done = threading.Event()
    started = time.monotonic()
    future.add_done_callback(lambda _future: done.set())
    if not done.wait(limit_s) and not future.done():
        return None, time.monotonic() - started
    return future.result(), time.monotonic() - started


class Counts:
    """A client's tallies; every waited request's latency [s] is kept for the percentiles."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.final = threading.Event()
        self.sent = self.succeeded = self.preempted = self.failed = self.rejected = 0
        self.request_late = self.request_lost = self.result_late = self.result_lost = 0
        self.param_calls = self.param_failures = self.param_late = self.param_lost = 0
        self.falls = self.resets = 0
        self.failures: dict[str, int] = {}
        self.param_problems: dict[str, int] = {}
        self.goal_response_s: list[float] = []
        self.result_s: list[float] = []
        self.param_s: list[float] = []

    def add(self, **values: int) -> None:
        with self.lock:
            for key, value in values.items():
                setattr(self, key, getattr(self, key) + value)

    def note(self, table: str, key: str) -> None:
        with self.lock:
            entries = getattr(self, table)
            entries[key] = entries.get(key, 0) + 1

    def as_json(self) -> str:
        with self.lock:
            return json.dumps({key: value for key, value in vars(self).items() if key not in ("lock", "final")})


def arm_goal(rng: random.Random) -> Any:
    from sim_interfaces.action import MoveArm

    goal = MoveArm.Goal(end_effector=rng.choice(("left_arm", "right_arm")), position_tolerance=0.005)
    goal.target.header.frame_id = "pelvis"
    side = 1.0 if goal.end_effector == "left_arm" else -1.0
    goal.target.pose.position.x, goal.target.pose.position.y = 0.25, side * rng.uniform(0.15, 0.3)
    goal.target.pose.position.z = rng.uniform(0.05, 0.25)
    goal.target.pose.orientation.w = 1.0
    return goal


def client_loop(index: int, stop: threading.Event, counts: Counts, started: float) -> None:
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.action import ActionClient

    from sim_client import RosSession
    from sim_interfaces.action import MoveArm, Walk
    from sim_interfaces.srv import Reset
    from sim_ros.session import RESPONSE_QOS

    rng = random.Random(index)
    # A server's responses go to every client's response reader, and only there are the others' thrown
    # away: with rclpy's default (keep-last 10) a client whose process is starved for a moment while the
    # other nine are answered finds its own response overwritten. Keep 1000, as rclpy's parameter services do.
    deep = RESPONSE_QOS
    with RosSession(f"soak_{index}", use_sim_time=False) as session:
        walk, arm = (ActionClient(session.node, action_type, name, goal_service_qos_profile=deep,
                                  result_service_qos_profile=deep, cancel_service_qos_profile=deep)
                     for action_type, name in ((Walk, "/walk"), (MoveArm, "/move_arm")))
        set_client = session.node.create_client(SetParameters, "/locomotion/set_parameters", qos_profile=deep)
        get_client = session.node.create_client(GetParameters, "/sim/get_parameters", qos_profile=deep)
        reset_client = session.node.create_client(Reset, "/sim/reset", qos_profile=deep)
        for ready, name in ((walk.server_is_ready, "/walk"), (arm.server_is_ready, "/move_arm"),
                            (set_client.service_is_ready, "/locomotion/set_parameters"),
                            (get_client.service_is_ready, "/sim/get_parameters"),
                            (reset_client.service_is_ready, "/sim/reset")):
            session.wait_for(ready, LOST_S, name)

        def param_call(client: Any, request: Any, what: str) -> Any:
            answer, waited = wait_timed(client.call_async(request), LOST_S)
            counts.add(param_calls=1)
            if answer is None:
                counts.add(param_lost=1, param_failures=1)
                counts.note("param_problems", f"{what}: lost (call {counts.param_calls}, {time.monotonic() - started:.0f} s)")
                return None
            with counts.lock:
                counts.param_s.append(waited)
            if waited > PARAM_ANSWER_S:
                counts.add(param_late=1)
                counts.note("param_problems", f"{what}: late {waited:.1f} s")
            return answer

        while not stop.is_set():
            if rng.random() < 0.5:
                goal: Any = Walk.Goal(distance=rng.choice((-0.3, 0.3)), speed=0.3)
                action, action_type = walk, Walk
            else:
                goal, action, action_type = arm_goal(rng), arm, MoveArm
            # Sent from the executor's thread: see RosSession.in_executor for the rclpy race this avoids.
            request = session.in_executor(functools.partial(action.send_goal_async, goal), LOST_S,
                                          "the goal request")
            handle, waited = wait_timed(request, LOST_S)
            counts.add(sent=1)
            if handle is None:
                counts.add(request_lost=1)
                continue
            with counts.lock:
                counts.goal_response_s.append(waited)
            if waited > GOAL_ANSWER_S:
                counts.add(request_late=1)
            if not handle.accepted:
                counts.add(rejected=1)
                continue
            outcome, waited = wait_timed(session.in_executor(handle.get_result_async, LOST_S, "the result request"),
                                         LOST_S)
            if outcome is None:
                counts.add(result_lost=1)
                counts.note("failures", f"{action_type.__name__}: no result within {LOST_S:g} s")
                continue
            with counts.lock:
                counts.result_s.append(waited)
            if waited > RESULT_S:
                counts.add(result_late=1)
            code = outcome.result.error_code
            if action_type is Walk and code == Walk.Result.FELL:
                # Stood up again, or every later Walk ends FELL and the rest of the run measures nothing.
                counts.add(falls=1)
                answer, _ = wait_timed(reset_client.call_async(Reset.Request()), LOST_S)
                counts.add(resets=1 if answer is not None and answer.success else 0)
            if code == action_type.Result.SUCCESS:
                counts.add(succeeded=1)
            elif code == action_type.Result.PREEMPTED:
                counts.add(preempted=1)
            else:
                counts.add(failed=1)
                # Grouped by code and wording (numbers blanked): "MoveArm 2: unreachable: IK converged # mm ..."
                wording = re.sub(r"-?\d+(\.\d+)?", "#", outcome.result.error_msg)[:70]
                counts.note("failures", f"{action_type.__name__} {code}: {wording}")
            speed = round(rng.uniform(0.2, 0.6), 2)
            answer = param_call(set_client, SetParameters.Request(parameters=[Parameter(
                name="walking_speed", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=speed))]),
                "set /locomotion walking_speed")
            if answer is not None and not answer.results[0].successful:
                counts.add(param_failures=1)
                counts.note("param_problems", f"set refused: {answer.results[0].reason[:60]}")
            answer = param_call(get_client, GetParameters.Request(names=["real_time_factor"]), "get /sim real_time_factor")
            if answer is not None and len(answer.values) != 1:
                counts.add(param_failures=1)
                counts.note("param_problems", "get: no value")
        # Reported before the session closes: rclpy's shutdown hung once in 10 clients (Context._logging_fini,
        # with the interpreter lock held), and the parent then takes this line and ends the process.
        print(counts.as_json(), flush=True)
        counts.final.set()


def run_client(index: int) -> None:
    """One client process: the loop until a line (or the end) on stdin, then its counts as one JSON line."""
    stop = threading.Event()
    counts = Counts()
    worker = threading.Thread(target=client_loop, args=(index, stop, counts, time.monotonic()), daemon=True)
    worker.start()
    sys.stdin.readline()  # the soak's end
    stop.set()
    if not counts.final.wait(3 * LOST_S):  # the goal in flight ends, or is counted lost
        print(counts.as_json(), flush=True)  # the loop itself is stuck or failed: what was counted so far
    worker.join(CLOSE_S)


def stamp_of(data: bytes) -> int:
    """The header stamp [ns] of a serialized std_msgs/Header-first message (CDR: 4 bytes of encapsulation first)."""
    little = data[1] & 1  # encapsulation kind CDR_LE = 0x0001, CDR_BE = 0x0000
    sec, nanosec = struct.unpack_from("<iI" if little else ">iI", data, 4)
    return sec * 1_000_000_000 + nanosec


def run_listener(wall_rate_hz: float) -> None:
    """The /joint_states listener process: stamps and arrival times until a line on stdin, then its figures."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    from sim_client import RosSession
    from sim_ros.session import quiet_events

    # The soak fills both cores of a 2-core machine; a listener at the same priority as /sim and the ten
    # clients gets a few % of a core and measures its own starvation, not /sim's delivery. As a recorder
    # on a core of its own would, it asks for a higher priority (and says what it got).
    try:
        niceness = os.nice(LISTENER_NICE)
    except OSError:
        niceness = os.nice(0)
    arrivals = array("d")  # [s, monotonic]
    stamps = array("q")  # [ns of sim time]

    def on_joints(data: bytes) -> None:
        arrivals.append(time.monotonic())
        stamps.append(stamp_of(data))

    # As /sim's publisher (reliable, keep-last), deep enough for LISTENER_QUEUE_S of the stream.
    qos = QoSProfile(depth=int(LISTENER_QUEUE_S * wall_rate_hz), reliability=ReliabilityPolicy.RELIABLE)
    with RosSession("soak_joint_states", use_sim_time=False) as listener:
        listener.node.create_subscription(JointState, "/joint_states", on_joints, qos, raw=True,
                                          event_callbacks=quiet_events())
        listener.wait_for(lambda: len(stamps) > 100, LOST_S, "/joint_states")
        begin, cpu, wall = len(stamps), time.process_time(), time.monotonic()
        sys.stdin.readline()  # the listening window: to the soak's end
        end, cpu, wall = len(stamps), time.process_time() - cpu, time.monotonic() - wall
        figures = joint_figures(arrivals[begin:end].tolist(), stamps[begin:end].tolist(), JOINT_RATE_HZ)
        # printed before the close (see client_loop)
        print(json.dumps({**figures, "cpu_share": cpu / wall, "niceness": niceness}), flush=True)


def report_of(child: subprocess.Popen[str], deadline: float) -> dict[str, Any]:
    """The JSON report on the last line a child printed; a child still running at ``deadline`` [s, monotonic] is killed."""
    try:
        out, _ = child.communicate(timeout=max(1.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:  # it reported, then hung closing its ROS session (or never reported)
        child.kill()
        out, _ = child.communicate()
    lines = (out or "").strip().splitlines()
    return dict(json.loads(lines[-1])) if lines else {}


def joint_figures(arrivals: list[float], stamps_ns: list[int], rate_hz: float) -> dict[str, Any]:
    """Lost, duplicated and reordered stamps; achieved rate and real-time factor; arrival jitter."""
    import numpy as np

    period_ns = round(1e9 / rate_hz)
    stamp = np.asarray(stamps_ns, dtype=np.int64)
    arrival = np.asarray(arrivals)
    steps = np.rint((stamp - stamp[0]) / period_ns).astype(np.int64)  # each message's index in the stream
    distinct = np.unique(steps)
    published = int(steps.max() - steps.min()) + 1  # every physics step's state between the first and the last
    gaps = np.diff(arrival)
    # Jitter: each arrival against a steady clock fitted over its second of wall time (the pacer re-anchors
    # when the sim falls behind, so one clock for the whole run would measure the lag, not the jitter).
    residual = np.zeros_like(arrival)
    second = np.floor(arrival - arrival[0]).astype(np.int64)
    for index in np.unique(second):
        part = second == index
        if np.count_nonzero(part) >= 10:
            x = steps[part].astype(float)
            residual[part] = arrival[part] - np.polyval(np.polyfit(x, arrival[part], 1), x)
    wall = float(arrival[-1] - arrival[0])
    # Where the stream has holes: (wall second of the hole, states missing, the listener's longest stall in the
    # STALL_WINDOW_S before it [ms]). A reliable keep-last writer drops what a stalled reader has not
    # acknowledged once its history is full: /sim's keeps STREAM_HISTORY_DEPTH states.
    order = np.argsort(steps, kind="stable")
    jumps = np.diff(steps[order])
    holes = []
    for i in np.flatnonzero(jumps > 1):
        at = float(arrival[order[i + 1]])
        before = gaps[(arrival[1:] <= at) & (arrival[1:] > at - STALL_WINDOW_S)]
        holes.append((round(at - float(arrival[0]), 1), int(jumps[i] - 1), round(1e3 * float(before.max(initial=0.0)))))
    return {
        "holes": holes[:10], "hole_count": len(holes),
        "received": len(stamp), "distinct": len(distinct), "published": published,
        "lost": published - len(distinct), "duplicates": len(stamp) - len(distinct),
        "reordered": int(np.count_nonzero(np.diff(steps) < 0)),
        "off_grid": int(np.count_nonzero(np.abs(stamp - stamp[0] - steps * period_ns) > period_ns // 10)),
        "wall_s": wall, "wall_rate_hz": (len(stamp) - 1) / wall if wall > 0 else 0.0,
        "rtf": (float(stamp[-1] - stamp[0]) * 1e-9) / wall if wall > 0 else 0.0,
        "gap_median_ms": 1e3 * float(np.median(gaps)), "gap_p99_ms": 1e3 * float(np.percentile(gaps, 99)),
        "gap_max_ms": 1e3 * float(gaps.max()),
        "jitter_p50_ms": 1e3 * float(np.percentile(np.abs(residual), 50)),
        "jitter_p99_ms": 1e3 * float(np.percentile(np.abs(residual), 99)),
        "jitter_max_ms": 1e3 * float(np.abs(residual).max()),
    }


def percentiles(values: list[float]) -> str:
    if not values:
        return "none"
    ordered = sorted(values)

    def at(q: float) -> float:
        return 1e3 * ordered[min(len(ordered) - 1, int(q * (len(ordered) - 1) + 0.5))]

    return f"median {at(0.5):.0f} ms, p99 {at(0.99):.0f} ms, max {1e3 * ordered[-1]:.0f} ms"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--clients", type=int, default=10)
    parser.add_argument("--rtf", type=float, default=DEFAULT_RTF,
                        help=f"/sim's real_time_factor (default {DEFAULT_RTF:g}: /joint_states at "
                             f"{JOINT_RATE_HZ * DEFAULT_RTF:g} Hz of wall time)")
    parser.add_argument("--client", type=int, default=None, help=argparse.SUPPRESS)  # internal: one client process
    parser.add_argument("--listener", action="store_true", help=argparse.SUPPRESS)  # internal: the /joint_states listener
    options = parser.parse_args()
    if not options.rtf > 0:
        parser.error("--rtf must be > 0 (a paced sim: the /joint_states rate is measured against it)")
    seconds = options.minutes * 60.0
    if options.client is not None:
        run_client(options.client)
        return 0
    if options.listener:
        run_listener(JOINT_RATE_HZ * options.rtf)
        return 0
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    from sim_ros.processes import ChildProcess, child_processes

    bringup = ChildProcess(["bringup", "--robot", "g1", "--rtf", f"{options.rtf:g}", "--no-respawn", "--ros-args", "-p",
                            f"joint_state_rate:={JOINT_RATE_HZ}"])
    me = [sys.executable, str(pathlib.Path(__file__).resolve())]
    pipes: dict[str, Any] = {"stdin": subprocess.PIPE, "stdout": subprocess.PIPE, "text": True}
    try:
        listener = subprocess.Popen([*me, "--listener", "--rtf", str(options.rtf)], **pipes)
        clients = [subprocess.Popen([*me, "--client", str(i)], **pipes) for i in range(options.clients)]
        nodes: dict[str, int] = {}
        while len(nodes) < 5 and bringup.alive():
            time.sleep(0.5)  # until bringup has started its nodes
            nodes = child_processes(bringup.process.pid)
        watched = {**nodes, "bringup": bringup.process.pid, "listener": listener.pid}
        watched.update({f"client {i}": client.pid for i, client in enumerate(clients)})
        warm = min(60.0, max(30.0, seconds / 5))  # the nodes started and allocated (each re-executes itself once)
        time.sleep(warm)  # the first sample after start-up allocation
        first = {name: process_stats(pid) for name, pid in watched.items()}
        first_wall = time.monotonic()
        deadline = first_wall + seconds - warm
        while time.monotonic() < deadline and bringup.alive():
            time.sleep(1.0)  # the soak's duration
        last = {name: process_stats(pid) for name, pid in watched.items()}
        wall = time.monotonic() - first_wall
        for child in (listener, *clients):
            assert child.stdin is not None  # opened as a pipe
            child.stdin.write("stop\n")  # the end: the clients finish their goal in flight and report
            child.stdin.flush()
        ending = time.monotonic() + 3 * LOST_S + CLOSE_S + 30.0
        joints = report_of(listener, ending)
        outputs = [report_of(client, ending) for client in clients]
        alive = bringup.alive()
    finally:
        bringup.stop(timeout=30.0)
    reported = sum(1 for output in outputs if output)
    total: dict[str, Any] = json.loads(Counts().as_json())
    for output in outputs:
        for key, value in output.items():
            if isinstance(value, dict):
                table = total.setdefault(key, {})
                for entry, count in value.items():
                    table[entry] = table.get(entry, 0) + count
            else:
                total[key] = total[key] + value
    print(f"soak: {options.clients} client processes, {options.minutes:g} min; /sim at real_time_factor {options.rtf:g}, "
          f"joint_state_rate {JOINT_RATE_HZ:g} Hz of sim time (one per 2 ms physics step: no more exist) = "
          f"{JOINT_RATE_HZ * options.rtf:g} Hz of wall time asked; bringup {'alive' if alive else 'DIED'} to the end; "
          f"{reported} of {options.clients} clients reported")
    print(f"{'process':<20} {'RSS first [MiB]':>16} {'RSS end [MiB]':>14} {'growth':>8} {'CPU [% of a core]':>18}")
    rows = sorted(name for name in last if not name.startswith("client "))  # the listener grows: it keeps every arrival
    for name in rows:
        rss0, cpu0 = first[name]
        rss1, cpu1 = last[name]
        print(f"{name:<20} {rss0:>16.1f} {rss1:>14.1f} {100 * (rss1 / rss0 - 1):>7.1f}% {100 * (cpu1 - cpu0) / wall:>17.1f}%")
    client_names = [name for name in last if name.startswith("client ")]
    if client_names:
        growths = [100 * (last[n][0] / first[n][0] - 1) for n in client_names]
        cpu = sum(last[n][1] - first[n][1] for n in client_names)
        print(f"{f'{len(client_names)} clients':<20} {sum(first[n][0] for n in client_names):>16.1f} "
              f"{sum(last[n][0] for n in client_names):>14.1f} {max(growths):>7.1f}% {100 * cpu / wall:>17.1f}%  "
              "(RSS summed, growth the largest, CPU summed)")
    print(f"goals: sent {total['sent']}, succeeded {total['succeeded']}, preempted {total['preempted']} (by another "
          f"client's goal), failed {total['failed']}, rejected {total['rejected']}; late {total['request_late']} "
          f"responses (> {GOAL_ANSWER_S:g} s) / {total['result_late']} results (> {RESULT_S:g} s); lost "
          f"{total['request_lost']} requests / {total['result_lost']} results (nothing in {LOST_S:g} s)")
    print(f"  goal response {percentiles(total['goal_response_s'])}; result {percentiles(total['result_s'])}; "
          f"the G1 fell {total['falls']} times (a client saw FELL and reset /sim: {total['resets']} resets)")
    for key, count in sorted(total["failures"].items(), key=lambda item: -item[1])[:8]:
        print(f"  {count:>5} x {key}")
    print(f"parameter calls: {total['param_calls']} (walking_speed sets on /locomotion, reads on /sim), "
          f"{total['param_failures']} failed, late {total['param_late']} (> {PARAM_ANSWER_S:g} s), lost "
          f"{total['param_lost']}; response {percentiles(total['param_s'])}")
    for key, count in sorted(total["param_problems"].items(), key=lambda item: -item[1])[:8]:
        print(f"  {count:>5} x {key}")
    if not joints:
        print("/joint_states: the listener did not report")
        joints = {"lost": -1, "wall_rate_hz": 0.0}
    else:
        print(f"/joint_states: received {joints['distinct']} of {joints['published']} published (stamps checked: "
              f"{joints['lost']} lost, {joints['duplicates']} duplicated, {joints['reordered']} reordered, "
              f"{joints['off_grid']} off the 2 ms grid) over {joints['wall_s']:.0f} s; {joints['wall_rate_hz']:.0f} Hz of "
              f"wall time at real_time_factor {joints['rtf']:.3f}; listener CPU {100 * joints['cpu_share']:.0f}% "
              f"of a core at niceness {joints.get('niceness', 0)}")
        if joints["hole_count"]:
            from sim_ros.names import STREAM_HISTORY_DEPTH as SIM_JOINT_HISTORY

            history_s = SIM_JOINT_HISTORY * joints["wall_s"] / max(joints["published"], 1)  # at the rate published
            print(f"  {joints['hole_count']} holes (at wall second, states missing, the listener's longest stall in the "
                  f"{STALL_WINDOW_S:g} s before [ms]): {', '.join(str(tuple(hole)) for hole in joints['holes'])}; /sim's "
                  f"writer keeps {SIM_JOINT_HISTORY} states = {history_s:.1f} s of what it published: a reader stalled "
                  "longer loses what it had not acknowledged")
        print(f"  arrival gap median {joints['gap_median_ms']:.2f} ms, p99 {joints['gap_p99_ms']:.2f} ms, max "
              f"{joints['gap_max_ms']:.1f} ms; jitter against a steady clock (fitted per second) p50 "
              f"{joints['jitter_p50_ms']:.2f} ms, p99 "
              f"{joints['jitter_p99_ms']:.2f} ms, max {joints['jitter_max_ms']:.1f} ms")
    growth = max(100 * (last[name][0] / first[name][0] - 1) for name in rows if name != "listener")
    lost = total["request_lost"] + total["result_lost"] + total["param_lost"]
    print(f"verdict: RSS growth at most {growth:.1f}% per node of bringup (limit 5%); lost {lost} requests and results, "
          f"{joints['lost']} /joint_states; late {total['request_late'] + total['result_late'] + total['param_late']}; "
          f"/joint_states at {joints['wall_rate_hz']:.0f} Hz of wall time ({JOINT_RATE_HZ * options.rtf:g} asked)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
