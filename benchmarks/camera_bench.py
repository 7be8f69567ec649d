"""Camera benchmark: what the G1's head camera costs, in the core and through ROS. Prints figures, not a test.

Measured on the standing G1 (its stand keyframe, no controller: the servos' own PD holds it), in
interleaved rounds (each round measures every row once, so a busy machine slows all rows alike);
medians of the rounds:

- frames per wall second of ``CameraRenderer.render`` at 320x240, 640x480 and 1280x720 (the scene
  as built, exposure gain 1) and at 640x480 with an exposure gain of 2 (the lookup table's cost);
- physics steps per wall second of ``Simulation.step_physics`` alone, and with a frame rendered
  every 1/30 s of sim time at 320x240 and 640x480: the ratio is what a subscribed 30 Hz camera
  costs the simulation's rate (a sim that renders nothing pays nothing).

Through ROS (``--ros``, on by default): one ``sim_node`` with the G1, in interleaved windows, medians:

- at real time (real_time_factor 1): the sim process's CPU [% of one core] with nobody subscribed to
  the camera, and with this process subscribed to ``/head_camera/image_raw`` at 10 Hz 320x240 (the
  default) and at 30 Hz 640x480; frames received per second of sim time;
- as fast as possible (real_time_factor 0): the node's real-time factor (its ``~/real_time_factor``
  reports) without and with the camera subscribed: what a watched camera costs the sim's rate, and
  that an unwatched one costs nothing.

Usage: ``make bench-camera`` or ``.venv/bin/python benchmarks/camera_bench.py [--rounds 5] [--seconds 2] [--no-ros]``.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

import robot_models
from robot_models.cameras import CameraLayout
from sim_bridge import Simulation
from sim_bridge.camera import CameraRenderer

SIZES = ((320, 240), (640, 480), (1280, 720))
CAMERA_RATE_HZ = 30.0  # of sim time


def frames_per_second(sim: Simulation, renderer: CameraRenderer, seconds: float, gain: float = 1.0) -> float:
    """Frames per wall second of ``renderer.render`` over about ``seconds``."""
    renderer.render(sim.data, gain)
    frames, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        renderer.render(sim.data, gain)
        frames += 1
    return frames / (time.perf_counter() - start)


def steps_per_second(sim: Simulation, renderer: CameraRenderer | None, sim_seconds: float) -> float:
    """Physics steps per wall second over ``sim_seconds`` of sim time, rendering at CAMERA_RATE_HZ if a renderer is given."""
    dt = sim.physics_timestep
    frames = round(sim_seconds * CAMERA_RATE_HZ)
    start_time, steps_done = sim.time, 0
    start = time.perf_counter()
    for k in range(1, frames + 1):
        due = round(k / CAMERA_RATE_HZ / dt)  # physics steps from the start to the k-th frame
        sim.step_physics(due - steps_done)
        steps_done = due
        if renderer is not None:
            renderer.render(sim.data)
    elapsed = time.perf_counter() - start
    assert abs(sim.time - start_time - steps_done * dt) < 1e-9
    return steps_done / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (medians are printed)")
    parser.add_argument("--seconds", type=float, default=2.0, help="wall seconds per frame-rate measurement")
    parser.add_argument("--sim-seconds", type=float, default=4.0, help="sim seconds per stepping measurement")
    parser.add_argument("--no-ros", dest="ros", action="store_false", help="skip the part through ROS (sim_node)")
    args = parser.parse_args()

    robot = robot_models.load("g1")
    camera: CameraLayout = robot.cameras[0]
    sim = Simulation(robot)
    sim.step(round(0.5 / sim.control_timestep))
    renderers = {size: CameraRenderer(sim.model, camera, *size) for size in SIZES}
    rows: dict[str, Callable[[], float]] = {}
    for size, renderer in renderers.items():
        rows[f"render {size[0]}x{size[1]} [frames/s]"] = functools.partial(frames_per_second, sim, renderer, args.seconds)
    rows["render 640x480, exposure 2 [frames/s]"] = lambda: frames_per_second(sim, renderers[(640, 480)], args.seconds, 2.0)
    rows["physics only [steps/s]"] = lambda: steps_per_second(sim, None, args.sim_seconds)
    for size in ((320, 240), (640, 480)):
        rows[f"physics + {size[0]}x{size[1]} at 30 Hz sim [steps/s]"] = functools.partial(
            steps_per_second, sim, renderers[size], args.sim_seconds)
    results: dict[str, list[float]] = {name: [] for name in rows}
    started = time.perf_counter()
    try:
        for round_index in range(args.rounds):
            for name, measure in rows.items():
                results[name].append(measure())
            print(f"round {round_index + 1}/{args.rounds} done", flush=True)
    finally:
        for renderer in renderers.values():
            renderer.close()
    median = {name: statistics.median(values) for name, values in results.items()}
    physics = median["physics only [steps/s]"]
    print(f"\nG1 head camera ({camera.name}, fovy {camera.fovy_deg:g} deg), standing; medians of {args.rounds} rounds "
          f"(min-max in brackets); physics step {sim.physics_timestep * 1e3:g} ms")
    print(f"{'':46} {'median':>10} {'range':>20} {'x real time':>12}")
    for name, values in results.items():
        real_time = f"{median[name] * sim.physics_timestep:12.2f}" if "steps/s" in name else ""
        print(f"{name:46} {median[name]:10.1f} [{min(values):8.1f}, {max(values):8.1f}] {real_time}")
    for size in ((320, 240), (640, 480)):
        with_camera = median[f"physics + {size[0]}x{size[1]} at 30 Hz sim [steps/s]"]
        print(f"physics-only / with {size[0]}x{size[1]} at 30 Hz: {physics / with_camera:.2f} "
              f"(the sim runs {with_camera / physics:.0%} as fast while the camera is subscribed)")
    if args.ros:
        ros_costs(args.rounds, args.seconds * 2)
    print(f"(benchmark wall time {time.perf_counter() - started:.0f} s; load average now {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores)")


ROS_SETTINGS = {"unwatched": None, "320x240 at 10 Hz": (320, 240, 10.0), "640x480 at 30 Hz": (640, 480, 30.0)}


def process_cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as handle:
        fields = handle.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _width(images: Any) -> int:
    return -1 if images.latest is None else int(images.latest.width)


def _stamp_s(images: Any) -> float:
    stamp = images.latest.header.stamp
    return float(stamp.sec + stamp.nanosec * 1e-9)


def ros_costs(rounds: int, seconds: float) -> None:
    """The sim node's CPU at real time and its rate as fast as possible, with the camera unwatched and watched."""
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import Image
    from std_msgs.msg import Float64

    from sim_interfaces.msg import CameraSettings
    from sim_ros.processes import running
    from sim_ros.session import RosSession

    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    cpu: dict[str, list[float]] = {name: [] for name in ROS_SETTINGS}
    frames: dict[str, list[float]] = {name: [] for name in ROS_SETTINGS}
    rtf: dict[str, list[float]] = {name: [] for name in ROS_SETTINGS}
    with RosSession("camera_bench", use_sim_time=False) as session:
        settings = session.node.create_publisher(CameraSettings, "/sim/head_camera/settings", latched)
        for factor in (1.0, 0.0):
            args = ["sim_node", "--ros-args", "-p", "robot:=g1", "-p", f"real_time_factor:={factor}"]
            with running(args) as node:
                reports = session.record(Float64, "/sim/real_time_factor", keep=1000)
                session.wait_for(lambda: reports.count >= 2, 60.0, "the node's first reports")  # noqa: B023
                for _ in range(rounds):
                    for name, setting in ROS_SETTINGS.items():
                        images = None
                        if setting is not None:
                            width, height, rate = setting
                            settings.publish(CameraSettings(camera="head_camera", exposure_ms=10.0, rate_hz=rate,
                                                            width=width, height=height))
                            recorder = session.record(Image, "/head_camera/image_raw", keep=2)
                            session.wait_for(lambda: recorder.count >= 3 and _width(recorder) == width,  # noqa: B023
                                             60.0, f"frames at {name}")
                            images = recorder
                        first = images.count if images is not None else 0
                        stamp0 = _stamp_s(images) if images is not None else 0.0
                        seen = reports.count
                        cpu0, wall0 = process_cpu_seconds(node.process.pid), time.monotonic()
                        session.wait_for(lambda: reports.count >= seen + max(2, round(seconds)), 60.0,  # noqa: B023
                                         "the node's reports")
                        wall = time.monotonic() - wall0
                        if factor == 1.0:
                            cpu[name].append(100.0 * (process_cpu_seconds(node.process.pid) - cpu0) / wall)
                        else:
                            rtf[name].append(statistics.median(m.data for m in reports.messages()[seen + 1:]))
                        if images is not None and factor == 1.0:
                            span = _stamp_s(images) - stamp0
                            frames[name].append((images.count - first) / span if span > 0 else 0.0)
                        if images is not None:
                            images.stop()
                reports.stop()
    print(f"\nThrough ROS: sim_node with the G1 standing, {rounds} interleaved rounds, medians")
    print(f"{'camera':20} {'sim CPU at rtf 1 [%]':>22} {'frames per sim s':>18} {'rtf as fast as possible':>25}")
    for name in ROS_SETTINGS:
        received = f"{statistics.median(frames[name]):18.1f}" if frames[name] else f"{'-':>18}"
        print(f"{name:20} {statistics.median(cpu[name]):22.1f} {received} {statistics.median(rtf[name]):25.2f}")
    unwatched = statistics.median(rtf["unwatched"])
    for name in list(ROS_SETTINGS)[1:]:
        print(f"rtf unwatched / watched at {name}: {unwatched / statistics.median(rtf[name]):.2f}")


if __name__ == "__main__":
    main()
