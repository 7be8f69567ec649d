"""Walking benchmark for the G1 physics walking controller (prints figures; not a test).

Figures:
- highest commanded speed among --speeds that walks --distance metres without a fall;
- per speed: measured average speed, lateral drift [cm/m] and heading drift [deg/m];
- wall time / sim time of a 2 m walk at 0.3 m/s;
- controller time per control tick, p50 / p95 [ms].

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/walk_bench.py [--distance 20] [--speeds 0.3 0.4 0.5 0.6]``
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import mujoco
import numpy as np

import robot_models
from robot_models import g1_constants as names
from sim_bridge import Simulation, Slot
from sim_bridge.locomotion import WalkingController


@dataclass(frozen=True)
class WalkResult:
    """One straight walk: whether it fell, distance [m], sim and wall time [s], drifts, tick times [s]."""

    speed: float
    fell: bool
    distance: float
    sim_time: float
    wall_time: float
    lateral_drift_per_m: float
    heading_drift_per_m: float
    average_speed: float
    tick_times: np.ndarray


class _TimedController:
    """Wraps a controller to time its ``update`` calls."""

    def __init__(self, inner: WalkingController) -> None:
        self.inner = inner
        self.times: list[float] = []

    @property
    def active(self) -> bool:
        return self.inner.active

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.inner.reset(model, data)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        start = time.perf_counter()
        self.inner.update(model, data, control_dt)
        self.times.append(time.perf_counter() - start)


def walk(
    robot: robot_models.RobotSpec, speed: float, distance: float, disturbance: float = 0.0, seed: int = 0
) -> WalkResult:
    """Walk straight at ``speed`` until ``distance`` metres are covered (or a fall, or a deadline).

    Args:
        disturbance: standard deviation of a random horizontal force on the pelvis, redrawn every 0.1 s [N].
        seed: seed of that force.
    """
    rng = np.random.default_rng(seed)
    sim = Simulation(robot)
    controller = WalkingController(sim.model)
    timed = _TimedController(controller)
    sim.set_controller(Slot.LOCOMOTION, timed)
    pelvis = sim.data.body(names.ROOT_BODY)
    start = pelvis.xpos[:2].copy()
    controller.set_velocity_command(speed, 0.0, 0.0)
    deadline = sim.time + distance / speed + 8.0
    wall_start = time.perf_counter()
    sim_start = sim.time
    fell = False
    cruise_start: tuple[float, float] | None = None
    pelvis_id = sim.model.body(names.ROOT_BODY).id
    redraw = max(1, round(0.1 / sim.control_timestep))
    ticks = 0
    while pelvis.xpos[0] - start[0] < distance and sim.time < deadline:
        if disturbance > 0.0 and ticks % redraw == 0:
            sim.data.xfrc_applied[pelvis_id, :2] = rng.normal(0.0, disturbance, 2)
        sim.step(1)
        ticks += 1
        if controller.status().fallen:
            fell = True
            break
        if cruise_start is None and pelvis.xpos[0] - start[0] >= 1.0:
            cruise_start = (float(pelvis.xpos[0]), sim.time)
    wall = time.perf_counter() - wall_start
    travelled = pelvis.xpos[:2] - start
    yaw = math.degrees(math.atan2(pelvis.xmat[3], pelvis.xmat[0]))
    covered = max(float(travelled[0]), 1e-6)
    average = (pelvis.xpos[0] - cruise_start[0]) / max(sim.time - cruise_start[1], 1e-6) if cruise_start else 0.0
    result = WalkResult(
        speed=speed, fell=fell, distance=float(travelled[0]), sim_time=sim.time - sim_start, wall_time=wall,
        lateral_drift_per_m=abs(float(travelled[1])) / covered, heading_drift_per_m=abs(yaw) / covered,
        average_speed=float(average), tick_times=np.array(timed.times),
    )
    sim.reset()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distance", type=float, default=20.0, help="distance of each speed trial [m]")
    parser.add_argument("--disturbance", type=float, default=0.0,
                        help="std of a random horizontal pelvis force, redrawn every 0.1 s [N]; 0 = none")
    parser.add_argument("--seeds", type=int, default=1, help="runs per speed (seeds of the disturbance)")
    parser.add_argument("--speeds", type=float, nargs="+", default=[0.3, 0.4, 0.5, 0.6], help="commanded speeds [m/s]")
    args = parser.parse_args()
    robot = robot_models.load("g1")

    print(f"{'cmd m/s':>8} {'seed':>4} {'fell':>5} {'dist m':>7} {'speed m/s':>9} {'lat cm/m':>9} {'yaw deg/m':>9} {'sim s':>6} {'wall s':>7}")
    best = None
    ticks = []
    for speed in args.speeds:
        passed = True
        for seed in range(args.seeds):
            r = walk(robot, speed, args.distance, args.disturbance, seed)
            ticks.append(r.tick_times)
            passed = passed and not r.fell and r.distance >= args.distance
            print(f"{speed:8.2f} {seed:4d} {str(r.fell):>5} {r.distance:7.2f} {r.average_speed:9.3f} {100 * r.lateral_drift_per_m:9.2f} "
                  f"{r.heading_drift_per_m:9.3f} {r.sim_time:6.1f} {r.wall_time:7.1f}")
        if passed:
            best = speed if best is None else max(best, speed)
    print(f"highest speed walking {args.distance:g} m without a fall: {best if best is not None else 'none'} m/s")

    short = walk(robot, 0.3, 2.0)
    ticks.append(short.tick_times)
    print(f"2 m walk at 0.3 m/s: sim {short.sim_time:.2f} s, wall {short.wall_time:.2f} s, "
          f"wall/sim {short.wall_time / short.sim_time:.3f}")
    all_ticks = np.concatenate(ticks) * 1e3
    print(f"controller time per tick: p50 {np.percentile(all_ticks, 50):.3f} ms, p95 {np.percentile(all_ticks, 95):.3f} ms "
          f"({len(all_ticks)} ticks)")


if __name__ == "__main__":
    main()
