"""Benchmark of the G1's sensors and battery (issue 12): what they cost the sim, what a walk costs the battery.

Measured in one run on this machine (``--parts`` picks some; ``--baseline PATH`` also runs (a'), (d) and (e) with
the nodes of another checkout, e.g. ``git worktree add /tmp/base <commit>``, interleaved with this one's in (d), (e)):
 (a) the /sim node's as-fast-as-possible rate divided by raw ``mj_step`` on the same model (as in
     ``sim_bench.py``: the node is paused while raw ``mj_step`` runs for a second, then resumed and its
     1 Hz real-time-factor reports read), in interleaved rounds on one node: with nobody subscribed to
     the sensor streams (they are then not built) and with this process subscribed to /imu (100 Hz),
     both /<foot>/wrench and /sim/hand_sensors (50 Hz) and /sim/battery (30 Hz). Medians of the rounds.
 (a') the same node at real time (real_time_factor 1): its process's CPU [% of one core] over windows
     without and with the sensor streams subscribed (interleaved; medians): the publishing cost at the
     streams' nominal rates, without the as-fast-as-possible run's flood of messages.
 (b) the battery meter in the core, idle: ``Simulation.step_physics`` of the standing G1 with and
     without the meter in the legs' slot, in /sim's 10 ms stretches (its stops at 100 Hz); standing, the
     meter integrates |tau * qdot| once per stretch, which stays batched ``mj_step`` calls.
 (c) the battery a straight walk costs (core, walk at 0.3 m/s): level, energy, mean mechanical and
     electrical power.
 (d) what the streams cost /sim itself: its process's CPU time [ms] per second of sim time, lock-stepped
     through ``/sim/step`` in 20 ms chunks as scenarios run it (the same physics in every window), standing
     and walking (``/cmd_vel`` 0.3 m/s), without and with raw subscribers (as the MCAP recorder subscribes)
     to /imu, both foot wrenches, /sim/hand_sensors and /sim/battery; interleaved windows, medians of rounds.
 (e) the ``walk_2m`` scenario, lock-stepped, without and with ``--record`` (an MCAP of every topic, so every
     sensor stream is subscribed): its wall/sim from report.json, and the CPU time per sim second of all its
     processes (runner, /sim, servers) and of /sim alone while its steps ran (less sensitive than wall time
     to what else the machine runs); medians of rounds.

Usage: ``make bench-sensors`` or ``.venv/bin/python benchmarks/sensors_bench.py [--rounds 5] [--distance 20]
[--parts abcde] [--baseline /tmp/base]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import pathlib
import random
import statistics
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator

# A domain of this run's own, on this machine only: set before rclpy is imported.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + random.randrange(101)))
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

import mujoco
from geometry_msgs.msg import Twist, WrenchStamped
from rclpy.qos import QoSProfile
from sensor_msgs.msg import BatteryState, Imu
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

import robot_models
from sim_bridge import Simulation, Slot
from sim_bridge.battery import Battery, BatteryConfig, BatteryMeter, Metered
from sim_bridge.locomotion import WalkingController
from sim_bridge.skills import SkillHost, SkillStatus, WalkGoal, WalkSkill
from sim_interfaces.msg import HandSensors
from sim_interfaces.srv import Step
from sim_ros.processes import BIN, running
from sim_ros.session import RosSession, TopicRecorder

ROBOT = "g1"
SENSOR_TOPICS = ((Imu, "/imu"), (WrenchStamped, "/left_foot/wrench"), (WrenchStamped, "/right_foot/wrench"),
                 (HandSensors, "/sim/hand_sensors"), (BatteryState, "/sim/battery"))
CHUNK_S = 0.02  # sim time per /sim/step call, as the scenario runner steps
WINDOW_S = 3.0  # sim time of one measurement window of (d)


def raw_step_rate(spec: robot_models.RobotSpec, seconds: float) -> float:
    """Physics steps per wall second of plain ``mj_step`` from the default keyframe."""
    model = spec.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(spec.default_keyframe).id)
    mujoco.mj_step(model, data, nstep=500)
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        mujoco.mj_step(model, data, nstep=1000)
        steps += 1000
    return steps / (time.perf_counter() - start)


def subscribe_sensors(session: RosSession) -> list[TopicRecorder]:
    return [session.record(msg_type, topic, keep=1) for msg_type, topic in SENSOR_TOPICS]


def node_ratios(session: RosSession, spec: robot_models.RobotSpec, rounds: int) -> dict[str, list[float]]:
    """Per-round ratios (sim node rate / raw mj_step rate) without and with the sensor streams subscribed."""
    args = ["sim_node", "--ros-args", "-p", f"robot:={ROBOT}", "-p", "real_time_factor:=0.0", "-p", "joint_state_rate:=100.0"]
    ratios: dict[str, list[float]] = {"without": [], "with": []}
    with running(args):
        rtf = session.record(Float64, "/sim/real_time_factor", keep=1000)
        session.wait_for(lambda: rtf.count >= 2, 60.0, "the node's first reports")
        for _ in range(rounds):
            for mode in ("without", "with"):
                streams = subscribe_sensors(session) if mode == "with" else []
                if streams:
                    session.wait_for(lambda: all(s.count > 0 for s in streams), 30.0, "every sensor stream")  # noqa: B023
                assert session.call(Trigger, "/sim/pause", Trigger.Request()).success
                raw = raw_step_rate(spec, 1.0) * spec.physics_timestep
                assert session.call(Trigger, "/sim/resume", Trigger.Request()).success
                first = rtf.count + 1  # the first report after resuming covers part of a window: skip it
                session.wait_for(lambda: rtf.count >= first + 2, 30.0, "two real-time-factor reports")  # noqa: B023
                ratios[mode].append(statistics.median(m.data for m in rtf.messages()[first:first + 2]) / raw)
                for stream in streams:
                    stream.stop()
        rtf.stop()
    return ratios


def process_cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as handle:
        fields = handle.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def realtime_cpu(session: RosSession, rounds: int, seconds: float, path: str | None = None) -> dict[str, list[float]]:
    """CPU [% of one core] of the sim process at real time, without and with the sensor streams subscribed
    (the nodes of the checkout at ``path``; None: this one)."""
    args = ["sim_node", "--ros-args", "-p", f"robot:={ROBOT}", "-p", "real_time_factor:=1.0"]
    cpu: dict[str, list[float]] = {"without": [], "with": []}
    with checkout(path), running(args) as node:
        rtf = session.record(Float64, "/sim/real_time_factor", keep=10)
        session.wait_for(lambda: rtf.count >= 2, 60.0, "the node's first reports")
        rtf.stop()
        for _ in range(rounds):
            for mode in ("without", "with"):
                streams = subscribe_sensors(session) if mode == "with" else []
                if streams:
                    session.wait_for(lambda: all(s.count > 0 for s in streams), 30.0, "every sensor stream")  # noqa: B023
                cpu0, wall0 = process_cpu_seconds(node.process.pid), time.monotonic()
                time.sleep(seconds)  # a measurement window of wall time (nothing to wait for)
                cpu[mode].append(100.0 * (process_cpu_seconds(node.process.pid) - cpu0) / (time.monotonic() - wall0))
                for stream in streams:
                    stream.stop()
    return cpu


def meter_rates(spec: robot_models.RobotSpec, rounds: int) -> dict[str, list[float]]:
    """Physics steps per wall second of the standing G1 in the core, without and with the battery meter."""
    rates: dict[str, list[float]] = {"without": [], "with": []}
    for _ in range(rounds):
        for mode in ("without", "with"):
            sim = Simulation(spec)
            legs = SkillHost(WalkingController(sim.model, sim.robot.biped))
            sim.set_controller(Slot.LOCOMOTION, Metered(legs, BatteryMeter(Battery())) if mode == "with" else legs)
            sim.step_physics(500)
            start = time.perf_counter()
            for _ in range(1000):  # /sim's stretches between its 100 Hz stops: 5 physics steps of 2 ms
                sim.step_physics(5)
            rates[mode].append(5000 / (time.perf_counter() - start))
    return rates


def walk_drain(spec: robot_models.RobotSpec, distance: float) -> str:
    assert spec.walking is not None and spec.sensors.battery is not None
    sim = Simulation(spec)
    walker = WalkingController(sim.model, sim.robot.biped)
    legs = SkillHost(walker)
    battery = Battery(BatteryConfig.of(spec.sensors.battery))
    sim.set_controller(Slot.LOCOMOTION, Metered(legs, BatteryMeter(battery)))
    run = legs.start(1, WalkSkill(walker, spec.base_body, WalkGoal(distance, 0.3, 0.0, spec.walking), {}), sim.model, sim.data)
    while run.status is SkillStatus.RUNNING:
        sim.step(1)
    seconds = run.ended_at - run.started_at
    return (f"(c) a {distance:g} m walk at 0.3 m/s ({seconds:.1f} s of sim time, {run.outcome.code if run.outcome else '?'}): "
            f"battery 100 % -> {battery.level_percent:.2f} % ({battery.consumed_j / 3600:.2f} Wh of "
            f"{battery.config.capacity_wh:g} Wh); mean mechanical power {battery.mechanical_j / seconds:.0f} W, "
            f"electrical {battery.consumed_j / seconds:.0f} W (idle {battery.config.idle_power_w:g} W, drives at "
            f"{battery.config.drive_efficiency:g} efficiency)")


# ----- (d) and (e): this checkout against a baseline's ----------------------------------------------------
@contextlib.contextmanager
def checkout(path: str | None) -> Iterator[None]:
    """Child processes started inside import the project from ``path`` (None: this checkout)."""
    before = os.environ.get("PYTHONPATH")
    if path is not None:
        os.environ["PYTHONPATH"] = path + (os.pathsep + before if before else "")
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = before


def process_cpu_ns(pid: int) -> int:
    """CPU time [ns] of a process's threads (scheduler statistics: nanoseconds, not 10 ms ticks)."""
    total = 0
    for task in os.listdir(f"/proc/{pid}/task"):
        with contextlib.suppress(OSError), open(f"/proc/{pid}/task/{task}/schedstat") as handle:
            total += int(handle.read().split()[0])
    return total


class RawSubscribers:
    """Raw (undeserialized) subscriptions to every sensor stream, as the MCAP recorder makes them."""

    def __init__(self, session: RosSession) -> None:
        self.counts = dict.fromkeys((topic for _, topic in SENSOR_TOPICS), 0)
        self._session = session
        self._subscriptions = [session.node.create_subscription(msg_type, topic, self._counter(topic), QoSProfile(depth=1000),
                                                                raw=True)
                               for msg_type, topic in SENSOR_TOPICS]

    def _counter(self, topic: str) -> Callable[[bytes], None]:
        def count(data: bytes) -> None:
            self.counts[topic] += 1

        return count

    def close(self) -> None:
        for subscription in self._subscriptions:
            self._session.node.destroy_subscription(subscription)


def step_sim(session: RosSession, seconds: float, chunk_steps: int, chunk_s: float) -> float:
    """Advance the paused sim by about ``seconds`` of sim time in chunks of ``chunk_steps`` control steps; the sim time after."""
    sim_time = math.nan
    for _ in range(max(1, round(seconds / chunk_s))):
        response = session.call(Step, "/sim/step", Step.Request(steps=chunk_steps), timeout=60.0)
        assert response.success, response.message
        sim_time = float(response.sim_time)
    return sim_time


def lockstep_costs(session: RosSession, versions: dict[str, str | None], rounds: int) -> dict[tuple[str, str, str], list[float]]:
    """CPU [ms] of /sim per sim second, per (version, standing|walking, without|with), one value per round."""
    costs: dict[tuple[str, str, str], list[float]] = {}
    walk = Twist()
    walk.linear.x = 0.3
    cmd_vel = session.node.create_publisher(Twist, "/cmd_vel", 10)
    for round_index in range(rounds):
        for version, path in versions.items():
            args = ["sim_node", "--ros-args", "-p", f"robot:={ROBOT}", "-p", "start_paused:=true",
                    "-p", "cmd_vel_timeout:=10.0"]
            with checkout(path), running(args) as node:
                t0 = step_sim(session, 0.0, 1, 1.0)
                control_dt = step_sim(session, 0.0, 1, 1.0) - t0
                chunk_steps = max(1, round(CHUNK_S / control_dt))
                chunk_s = chunk_steps * control_dt
                for gait in ("standing", "walking"):
                    if gait == "walking":
                        cmd_vel.publish(walk)
                    step_sim(session, 1.5, chunk_steps, chunk_s)  # settle; walking: into the gait
                    modes = ("without", "with") if round_index % 2 == 0 else ("with", "without")
                    for mode in modes:
                        subscribers = RawSubscribers(session) if mode == "with" else None
                        if subscribers is not None:
                            while not all(subscribers.counts.values()):  # matched and flowing (stepping makes them)
                                step_sim(session, chunk_s, chunk_steps, chunk_s)
                        if gait == "walking":
                            cmd_vel.publish(walk)
                        sim0 = step_sim(session, 0.1, chunk_steps, chunk_s)
                        cpu0 = process_cpu_ns(node.process.pid)
                        sim1 = step_sim(session, WINDOW_S, chunk_steps, chunk_s)
                        cpu_ms = (process_cpu_ns(node.process.pid) - cpu0) / 1e6
                        costs.setdefault((version, gait, mode), []).append(cpu_ms / (sim1 - sim0))
                        if subscribers is not None:
                            subscribers.close()
    session.node.destroy_publisher(cmd_vel)
    return costs


def tree_cpu_s(root: int) -> dict[str, float]:
    """CPU [s] so far of a process and its descendants, summed per program name (``sim_node``, ``scenario``, ...)."""
    parents: dict[int, int] = {}
    cpu: dict[int, tuple[str, float]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        with contextlib.suppress(OSError):
            with open(f"/proc/{entry}/stat") as handle:
                fields = handle.read().rsplit(")", 1)[1].split()
            with open(f"/proc/{entry}/cmdline") as handle:
                argv = handle.read().split("\0")
            name = pathlib.Path(argv[1] if len(argv) > 1 and "python" in argv[0] else argv[0]).name
            parents[int(entry)] = int(fields[1])
            cpu[int(entry)] = (name, (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK"))
    totals: dict[str, float] = {}
    for pid, (name, seconds) in cpu.items():
        ancestor = pid
        while ancestor not in (root, 0, 1) and ancestor in parents:
            ancestor = parents[ancestor]
        if ancestor == root:
            totals[name] = totals.get(name, 0.0) + seconds
    return totals


def run_walk_2m(record: bool) -> tuple[float, float, float]:
    """One lock-stepped walk_2m: (wall/sim from its report, CPU [s] per sim second of all its processes while the
    steps ran, the same of /sim alone)."""
    with tempfile.TemporaryDirectory(prefix="sensors_bench_") as out:
        process = subprocess.Popen([str(BIN / "scenario"), "run", "walk_2m", *(["--record"] if record else []), "--out", out],
                                   cwd=out, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=dict(os.environ))
        stdout = process.stdout
        assert stdout is not None
        start: dict[str, float] = {}
        end: dict[str, float] = {}
        line = ""
        for char in iter(lambda: stdout.read(1), ""):  # progress lines end in \r, others in \n
            if char not in "\r\n":
                line += char
                continue
            if not start and "[1/" in line:  # the first step starts (nodes up, reset done)
                start = tree_cpu_s(process.pid)
            if not end and "wall/sim" in line:  # the verdict line, right after the run
                end = tree_cpu_s(process.pid)
            line = ""
        assert process.wait() == 0 and start and end, "walk_2m failed"
        report = json.loads(next(pathlib.Path(out).glob("walk_2m-*/report.json")).read_text())
    sim_s = float(report["sim_time_s"])
    used = {name: end[name] - start.get(name, 0.0) for name in end}
    return float(report["wall_per_sim"]), sum(used.values()) / sim_s, used.get("sim_node", math.nan) / sim_s


def scenario_costs(versions: dict[str, str | None], rounds: int) -> dict[tuple[str, str], list[tuple[float, float, float]]]:
    """walk_2m per (version, plain|recorded): one (wall/sim, CPU/sim of all, CPU/sim of /sim) per round."""
    costs: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
    for round_index in range(rounds):
        for version, path in versions.items():
            for mode in (("plain", "recorded") if round_index % 2 == 0 else ("recorded", "plain")):
                with checkout(path):
                    costs.setdefault((version, mode), []).append(run_walk_2m(mode == "recorded"))
    return costs


def print_lockstep(costs: dict[tuple[str, str, str], list[float]], versions: dict[str, str | None], rounds: int) -> None:
    for gait in ("standing", "walking"):
        for version in versions:
            without, with_ = costs[(version, gait, "without")], costs[(version, gait, "with")]
            extra = [b - a for a, b in zip(without, with_, strict=True)]  # per round: the windows ran back to back
            print(f"[g1] (d) /sim lock-stepped, {gait}, {version}: {statistics.median(without):.0f} ms CPU per sim second "
                  f"without sensor subscribers, {statistics.median(with_):.0f} with them "
                  f"(x{statistics.median(b / a for a, b in zip(without, with_, strict=True)):.2f}): the streams cost "
                  f"{statistics.median(extra):.0f} ms per sim second (median of {rounds} interleaved rounds: "
                  f"{', '.join(f'{e:.0f}' for e in extra)})", flush=True)


def print_scenario(costs: dict[tuple[str, str], list[tuple[float, float, float]]], versions: dict[str, str | None],
                   rounds: int) -> None:
    for version in versions:
        plain, recorded = costs[(version, "plain")], costs[(version, "recorded")]

        def median(runs: list[tuple[float, float, float]], i: int) -> float:
            return statistics.median(run[i] for run in runs)

        print(f"[g1] (e) walk_2m lock-stepped, {version} (medians of {rounds} interleaved rounds): wall/sim "
              f"{median(plain, 0):.2f} without recording, {median(recorded, 0):.2f} with --record (each: "
              f"{', '.join(f'{run[0]:.2f}' for run in recorded)}); CPU per sim second of all its processes while the "
              f"steps ran {median(plain, 1):.2f} s -> {median(recorded, 1):.2f} s with --record, of /sim alone "
              f"{median(plain, 2):.2f} s -> {median(recorded, 2):.2f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds of (a) and (b)")
    parser.add_argument("--distance", type=float, default=20.0, help="walk of (c) [m]")
    parser.add_argument("--parts", default="abcde", help="which measurements to run (letters of the list above)")
    parser.add_argument("--baseline", help="a checkout of this project whose nodes (d) and (e) measure too")
    parser.add_argument("--scenario-rounds", type=int, default=3, help="rounds of (e)")
    options = parser.parse_args()
    spec = robot_models.load(ROBOT)
    versions: dict[str, str | None] = {"this checkout": None}
    if options.baseline:
        versions = {f"baseline {options.baseline}": os.path.abspath(options.baseline), **versions}
    with RosSession("sensors_bench", use_sim_time=False) as session:
        if "a" in options.parts:
            ratios = node_ratios(session, spec, options.rounds)
            without, with_ = statistics.median(ratios["without"]), statistics.median(ratios["with"])
            print(f"[g1] (a) sim node / raw mj_step, medians of {options.rounds} interleaved rounds: without sensor "
                  f"subscribers {without:.3f}, with /imu, foot and wrist wrenches and the battery subscribed {with_:.3f} "
                  f"(cost {100.0 * (1.0 - with_ / without):.1f} % of the node's rate)", flush=True)
            for version, path in versions.items():
                cpu = realtime_cpu(session, 3, 4.0, path)
                print(f"[g1] (a') sim node at real time, {version}: CPU of its process (% of one core, medians of 3 "
                      f"interleaved 4 s windows): without sensor subscribers {statistics.median(cpu['without']):.1f}, "
                      f"with them {statistics.median(cpu['with']):.1f}", flush=True)
        if "d" in options.parts:
            print_lockstep(lockstep_costs(session, versions, options.rounds), versions, options.rounds)
    if "b" in options.parts:
        rates = meter_rates(spec, options.rounds)
        plain, metered = statistics.median(rates["without"]), statistics.median(rates["with"])
        print(f"[g1] (b) core, standing: {plain:.0f} physics steps/s without the battery meter, {metered:.0f} with it "
              f"(cost {100.0 * (1.0 - metered / plain):.1f} %)", flush=True)
    if "c" in options.parts:
        print(f"[g1] {walk_drain(spec, options.distance)}", flush=True)
    if "e" in options.parts:
        print_scenario(scenario_costs(versions, options.scenario_rounds), versions, options.scenario_rounds)


if __name__ == "__main__":
    main()
