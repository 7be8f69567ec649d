"""Benchmark of the G1's sensors and battery (issue 12): what they cost the sim, what a walk costs the battery.

Measured in one run on this machine:
 (a) the /sim node's as-fast-as-possible rate divided by raw ``mj_step`` on the same model (as in
     ``sim_bench.py``: the node is paused while raw ``mj_step`` runs for a second, then resumed and its
     1 Hz real-time-factor reports read), in interleaved rounds on one node: with nobody subscribed to
     the sensor streams (they are then not built) and with this process subscribed to /imu (100 Hz),
     both /<foot>/wrench and /sim/hand_sensors (50 Hz) and /sim/battery (30 Hz). Medians of the rounds.
 (a') the same node at real time (real_time_factor 1): its process's CPU [% of one core] over windows
     without and with the sensor streams subscribed (interleaved; medians): the publishing cost at the
     streams' nominal rates, without the as-fast-as-possible run's flood of messages.
 (b) the battery meter in the core, idle: ``Simulation.step_physics`` of the standing G1 with and
     without the meter in the legs' slot (the meter integrates |tau * qdot| every control step, so the
     idle robot is stepped control step by control step instead of in batched ``mj_step`` calls).
 (c) the battery a straight walk costs (core, walk at 0.3 m/s): level, energy, mean mechanical and
     electrical power.

Usage: ``make bench-sensors`` or ``.venv/bin/python benchmarks/sensors_bench.py [--rounds 5] [--distance 20]``.
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import time

# A domain of this run's own, on this machine only: set before rclpy is imported.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + random.randrange(101)))
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

import mujoco
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import BatteryState, Imu
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

import robot_models
from nodes.processes import running
from sim_bridge import Simulation, Slot
from sim_bridge.battery import Battery, BatteryConfig, BatteryMeter, Metered
from sim_bridge.locomotion import WalkingController
from sim_bridge.skills import SkillHost, SkillStatus, WalkGoal, WalkSkill
from sim_client.session import RosSession, TopicRecorder
from sim_interfaces.msg import HandSensors

ROBOT = "g1"


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
    topics = [(Imu, "/imu"), (WrenchStamped, "/left_foot/wrench"), (WrenchStamped, "/right_foot/wrench"),
              (HandSensors, "/sim/hand_sensors"), (BatteryState, "/sim/battery")]
    return [session.record(msg_type, topic, keep=1) for msg_type, topic in topics]


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


def realtime_cpu(session: RosSession, rounds: int, seconds: float) -> dict[str, list[float]]:
    """CPU [% of one core] of the sim process at real time, without and with the sensor streams subscribed."""
    args = ["sim_node", "--ros-args", "-p", f"robot:={ROBOT}", "-p", "real_time_factor:=1.0"]
    cpu: dict[str, list[float]] = {"without": [], "with": []}
    with running(args) as node:
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
            legs = SkillHost(WalkingController(sim.model))
            sim.set_controller(Slot.LOCOMOTION, Metered(legs, BatteryMeter(Battery())) if mode == "with" else legs)
            sim.step_physics(500)
            start = time.perf_counter()
            sim.step_physics(5000)
            rates[mode].append(5000 / (time.perf_counter() - start))
    return rates


def walk_drain(spec: robot_models.RobotSpec, distance: float) -> str:
    assert spec.walking is not None and spec.sensors.battery is not None
    sim = Simulation(spec)
    walker = WalkingController(sim.model)
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds of (a) and (b)")
    parser.add_argument("--distance", type=float, default=20.0, help="walk of (c) [m]")
    options = parser.parse_args()
    spec = robot_models.load(ROBOT)
    with RosSession("sensors_bench", use_sim_time=False) as session:
        ratios = node_ratios(session, spec, options.rounds)
        cpu = realtime_cpu(session, 3, 4.0)
    without, with_ = statistics.median(ratios["without"]), statistics.median(ratios["with"])
    print(f"[g1] (a) sim node / raw mj_step, medians of {options.rounds} interleaved rounds: without sensor subscribers "
          f"{without:.3f}, with /imu, foot and wrist wrenches and the battery subscribed {with_:.3f} "
          f"(cost {100.0 * (1.0 - with_ / without):.1f} % of the node's rate)", flush=True)
    print(f"[g1] (a') sim node at real time, CPU of its process (% of one core, medians of 3 interleaved 4 s windows): "
          f"without sensor subscribers {statistics.median(cpu['without']):.1f}, with them "
          f"{statistics.median(cpu['with']):.1f}", flush=True)
    rates = meter_rates(spec, options.rounds)
    plain, metered = statistics.median(rates["without"]), statistics.median(rates["with"])
    print(f"[g1] (b) core, standing: {plain:.0f} physics steps/s without the battery meter, {metered:.0f} with it "
          f"(cost {100.0 * (1.0 - metered / plain):.1f} %)", flush=True)
    print(f"[g1] {walk_drain(spec, options.distance)}", flush=True)


if __name__ == "__main__":
    main()
