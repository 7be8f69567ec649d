"""Walking benchmark for the G1 physics walking controller (prints figures; not a test).

Figures:
- the core walk (issue 9): 0.5 m/s for 10 s of sim time, stepped as one ``sim.step`` call: wall/sim,
  controller time per control tick p50 / p95 [us], and raw ``mj_step`` time per control tick measured in
  the same run on the walk's own states (physics alone, as wall/sim); goal wall/sim <= 0.08 at 250 Hz;
- with --profile, where the controller's time goes (planner, QP build, solver, MuJoCo calls) [us/tick];
- highest commanded speed among --speeds that walks --distance metres without a fall;
- per speed: measured average speed, lateral drift [cm/m] and heading drift [deg/m];
- wall time / sim time of a 2 m walk at 0.3 m/s;
- controller time per control tick, p50 / p95 [ms].

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/walk_bench.py [--distance 20] [--speeds 0.3 0.4 0.5 0.6] [--profile]``
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Self

import mujoco
import numpy as np

import robot_models
from robot_models import g1_constants as names
from sim_bridge import Simulation, Slot
from sim_bridge.locomotion import WalkingController
from sim_bridge.locomotion.wbc import WholeBodyQP


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
    """Wraps a controller to time its ``update`` calls (and, if asked, keep the state after each one)."""

    def __init__(self, inner: WalkingController, record_states: bool = False) -> None:
        self.inner = inner
        self.times: list[float] = []
        self.record_states = record_states
        self.states = np.empty((0, 0))  # (ticks, state size), preallocated by ``reserve``
        self.recorded = 0

    def reserve(self, model: mujoco.MjModel, ticks: int) -> None:
        """Preallocate room for ``ticks`` recorded states (recording then costs one ``mj_getState``)."""
        self.states = np.empty((ticks, mujoco.mj_stateSize(model, _PHYSICS_STATE)))
        self.recorded = 0

    @property
    def active(self) -> bool:
        return self.inner.active

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.inner.reset(model, data)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        start = time.perf_counter()
        self.inner.update(model, data, control_dt)
        self.times.append(time.perf_counter() - start)
        if self.record_states and self.recorded < len(self.states):
            mujoco.mj_getState(model, data, self.states[self.recorded], _PHYSICS_STATE)
            self.recorded += 1


_PHYSICS_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass(frozen=True)
class CoreWalk:
    """The core walk's figures: sim, wall and process CPU time [s], controller and raw physics time per tick [s]."""

    sim_time: float
    wall_time: float
    cpu_time: float
    controller_times: np.ndarray
    physics_times: np.ndarray
    fell: bool


def _start_walk(robot: robot_models.RobotSpec, speed: float, record: bool) -> tuple[Simulation, _TimedController]:
    sim = Simulation(robot)
    controller = WalkingController(sim.model, sim.robot.biped)
    timed = _TimedController(controller, record_states=record)
    sim.set_controller(Slot.LOCOMOTION, timed)
    controller.set_velocity_command(speed, 0.0, 0.0)
    return sim, timed


def core_walk(robot: robot_models.RobotSpec, speed: float = 0.5, duration: float = 10.0, physics: bool = True) -> CoreWalk:
    """Walk at ``speed`` for ``duration`` seconds of sim time in one ``sim.step`` call, then time raw physics.

    The raw physics figure: the same (deterministic) walk is run again recording the state after every
    control tick's controller, and each tick is replayed from it on a second MjData, ``mj_step`` over
    one control period and nothing else. The timed walk itself records nothing.
    """
    sim, timed = _start_walk(robot, speed, record=False)
    ticks = round(duration / sim.control_timestep)
    wall_start, cpu_start = time.perf_counter(), time.process_time()
    sim.step(ticks)
    wall, cpu = time.perf_counter() - wall_start, time.process_time() - cpu_start
    fell = timed.inner.status().fallen
    sim.reset()
    physics_times = np.zeros(0)
    if physics:
        sim, recorder = _start_walk(robot, speed, record=True)
        recorder.reserve(sim.model, ticks)
        sim.step(ticks)
        replay = mujoco.MjData(sim.model)  # the model still has the legs in torque mode, as during the walk
        physics_times = np.zeros(recorder.recorded)
        for k, state in enumerate(recorder.states[: recorder.recorded]):
            mujoco.mj_setState(sim.model, replay, state, _PHYSICS_STATE)
            start = time.perf_counter()
            mujoco.mj_step(sim.model, replay, nstep=sim.decimation)
            physics_times[k] = time.perf_counter() - start
        sim.reset()
    return CoreWalk(duration, wall, cpu, np.array(timed.times), physics_times, fell)


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
    controller = WalkingController(sim.model, sim.robot.biped)
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


class PartTimer:
    """Times named methods of the controller's classes while installed (``with PartTimer(): ...``).

    The wrappers cost ~0.3 us per call, a few calls per tick, so the parts add up to the measured tick.
    """

    PARTS = (
        ("update", WalkingController, "update"),
        ("qp", WholeBodyQP, "solve"),
        ("kinematics", WholeBodyQP, "_kinematics"),
        ("solver", WholeBodyQP, "_solve_qp"),
        ("com", WalkingController, "_com_jacobian"),
    )

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {name: 0.0 for name, _, _ in self.PARTS}
        self._originals: list[tuple[type, str, object]] = []

    def __enter__(self) -> Self:
        for name, owner, attribute in self.PARTS:
            original = getattr(owner, attribute)
            self._originals.append((owner, attribute, original))
            setattr(owner, attribute, self._timed(name, original))
        return self

    def __exit__(self, *exc: object) -> None:
        for owner, attribute, original in self._originals:
            setattr(owner, attribute, original)
        self._originals.clear()

    def _timed(self, name: str, function: Callable[..., Any]) -> Callable[..., Any]:
        seconds = self.seconds
        clock = time.perf_counter

        def timed(*args: Any, **kwargs: Any) -> Any:
            start = clock()
            result = function(*args, **kwargs)
            seconds[name] += clock() - start
            return result

        return timed

    def print(self, ticks: int, wall: float) -> None:
        """The per-part table, us per control tick."""
        t = {name: 1e6 * value / ticks for name, value in self.seconds.items()}
        rows = [
            ("planner + gait state machine (Python)", t["update"] - t["qp"] - t["com"]),
            ("QP build (numpy, LAPACK elimination)", t["qp"] - t["solver"] - t["kinematics"]),
            ("QP solver (DAQP update + solve)", t["solver"]),
            ("MuJoCo calls (M, Jacobians)", t["kinematics"] + t["com"]),
            ("controller total", t["update"]),
            ("physics and simulation loop", 1e6 * wall / ticks - t["update"]),
        ]
        print("controller parts (us per control tick, timers around the parts):")
        for label, value in rows:
            print(f"  {label:40s} {value:8.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distance", type=float, default=20.0, help="distance of each speed trial [m]")
    parser.add_argument("--disturbance", type=float, default=0.0,
                        help="std of a random horizontal pelvis force, redrawn every 0.1 s [N]; 0 = none")
    parser.add_argument("--seeds", type=int, default=1, help="runs per speed (seeds of the disturbance)")
    parser.add_argument("--speeds", type=float, nargs="+", default=[0.3, 0.4, 0.5, 0.6], help="commanded speeds [m/s]")
    parser.add_argument("--profile", action="store_true", help="also profile the core walk per part (cProfile)")
    parser.add_argument("--core-only", action="store_true", help="only the core walk figures")
    args = parser.parse_args()
    robot = robot_models.load("g1")

    core = core_walk(robot)
    us = 1e6
    ctl, phys = core.controller_times * us, core.physics_times * us
    print(f"core walk 0.5 m/s for {core.sim_time:g} s{' (FELL)' if core.fell else ''}: "
          f"wall/sim {core.wall_time / core.sim_time:.3f} ({core.sim_time / core.wall_time:.1f}x real time; goal <= 0.08)")
    print(f"  controller per tick: p50 {np.percentile(ctl, 50):.0f} us, p95 {np.percentile(ctl, 95):.0f} us "
          f"({len(ctl)} ticks at {len(ctl) / core.sim_time:.0f} Hz)")
    print(f"  raw mj_step per tick (same run, the walk's states): p50 {np.percentile(phys, 50):.0f} us, "
          f"p95 {np.percentile(phys, 95):.0f} us; physics alone wall/sim {phys.sum() / us / core.sim_time:.3f}")
    rest = core.wall_time * us / len(ctl) - np.mean(ctl) - np.mean(phys)
    print(f"  rest (simulation loop, mj_step1/2 split): {rest:.0f} us per tick")
    print(f"  process CPU / wall during the walk {core.cpu_time / core.wall_time:.2f} "
          f"(below ~0.95: other processes took the core; CPU/sim {core.cpu_time / core.sim_time:.3f})")
    if args.profile:
        with PartTimer() as parts:
            profiled = core_walk(robot, physics=False)
        parts.print(len(profiled.controller_times), profiled.wall_time)
    if args.core_only:
        return

    print(f"{'cmd m/s':>8} {'seed':>4} {'fell':>5} {'dist m':>7} {'speed m/s':>9} {'lat cm/m':>9} {'yaw deg/m':>9} "
          f"{'sim s':>6} {'wall s':>7}")
    best = None
    ticks = []
    for speed in args.speeds:
        passed = True
        for seed in range(args.seeds):
            r = walk(robot, speed, args.distance, args.disturbance, seed)
            ticks.append(r.tick_times)
            passed = passed and not r.fell and r.distance >= args.distance
            print(f"{speed:8.2f} {seed:4d} {r.fell!s:>5} {r.distance:7.2f} {r.average_speed:9.3f} "
                  f"{100 * r.lateral_drift_per_m:9.2f} "
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
