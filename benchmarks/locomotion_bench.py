"""Locomotion benchmark of the G1 walking controller, core only (no ROS): prints figures, not a test.

Sections (``--only`` picks some; ``--quick`` runs a smaller version of each):

- ``sweep``: 0.3-1.0 m/s in 0.1 steps, ``--distance`` metres each (20): measured steady speed (from
  3 m on), lateral drift per metre, heading drift, falls;
- ``endurance``: 100 m at 0.8 m/s over ``--seeds`` seeds (5; each seed perturbs the initial base
  velocity and the joint angles a little);
- ``push``: walking at 0.5 m/s, a 0.1 s push on the pelvis (``xfrc_applied`` through
  ``Simulation.push``, force = impulse / 0.1 s) from 8 directions (heading frame, 0 = from behind,
  i.e. pushing forward, counter-clockwise) at 4 gait phases (start, middle and end of single support,
  double support), 10 N s; then the largest impulse absorbed at all 4 phases per direction, walking
  and standing. Absorbed: no fall, and the robot walks on at the commanded pace and stops standing;
- ``motions``: turn in place 180 deg, arc 0.5 m/s at 0.5 rad/s for 20 s, side step 1 m at 0.2 m/s,
  backward 2 m: the error against the commanded angle or distance;
- ``cost``: controller time per control tick next to raw ``mj_step`` over the same tick.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/locomotion_bench.py [--quick] [--only sweep push ...]``
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

import robot_models
from robot_models import g1_constants as names
from sim_bridge import Simulation, Slot
from sim_bridge.locomotion import GaitParameters, LocomotionMode, WalkingController

SECTIONS = ("sweep", "endurance", "push", "motions", "cost")
PUSH_DURATION = 0.1  # [s]
PUSH_PHASES = ("SS start", "SS mid", "SS end", "DS")
PUSH_DIRECTIONS = tuple(range(0, 360, 45))  # [deg] in the heading frame; 0 pushes forward, 90 to the left
SETTLE_TIME = 4.0  # walking before a push [s]
AFTER_PUSH = 4.0  # walking after a push before the stop [s]
STEADY_FROM = 3.0  # the steady speed is measured from this distance on [m]


class _Timed:
    """A controller wrapper that times its ``update`` calls."""

    def __init__(self, inner: WalkingController) -> None:
        self.inner = inner
        self.times: list[float] = []

    @property
    def active(self) -> bool:
        return self.inner.active

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.inner.reset(model, data)

    def release(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.inner.release(model, data)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        start = time.perf_counter()
        self.inner.update(model, data, control_dt)
        self.times.append(time.perf_counter() - start)


@dataclass
class Rig:
    """A G1 simulation with a (timed) walking controller in the locomotion slot."""

    sim: Simulation
    walker: WalkingController
    timed: _Timed

    @property
    def pelvis(self) -> int:
        return int(self.sim.model.body(names.ROOT_BODY).id)

    def pose(self) -> tuple[float, float, float]:
        """Pelvis x, y [m] and yaw [rad] in world."""
        data = self.sim.data
        xpos, xmat = data.xpos[self.pelvis], data.xmat[self.pelvis]
        return float(xpos[0]), float(xpos[1]), math.atan2(float(xmat[3]), float(xmat[0]))

    def fallen(self) -> bool:
        return self.walker.status().fallen

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Step ``seconds`` of sim time (or until ``until()``); False on a fall."""
        for _ in range(round(seconds / self.sim.control_timestep)):
            self.sim.step(1)
            if self.fallen():
                return False
            if until is not None and until():
                break
        return True

    def close(self) -> None:
        self.sim.reset()


def new_rig(robot: robot_models.RobotSpec, seed: int | None = None, params: GaitParameters | None = None) -> Rig:
    """A fresh simulation; with a seed, the initial base velocity and joint angles are perturbed a little."""
    sim = Simulation(robot)
    walker = WalkingController(sim.model, sim.robot.biped, params=params)
    timed = _Timed(walker)
    sim.set_controller(Slot.LOCOMOTION, timed)
    if seed is not None:
        rng = np.random.default_rng(seed)
        base = int(sim.model.jnt_dofadr[sim.model.body_jntadr[sim.model.body(names.ROOT_BODY).id]])
        sim.data.qvel[base : base + 3] += rng.normal(0.0, 0.02, 3)  # [m/s]
        sim.data.qvel[base + 3 : base + 6] += rng.normal(0.0, 0.05, 3)  # [rad/s]
        for joint in names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS + names.WAIST_JOINTS:
            sim.data.qpos[sim.model.joint(joint).qposadr[0]] += rng.normal(0.0, 0.01)  # [rad]
        mujoco.mj_forward(sim.model, sim.data)
    return Rig(sim, walker, timed)


# ----- straight walks ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Straight:
    """One straight walk: commanded speed after clamping [m/s], fall, distance [m], steady speed [m/s],
    lateral drift [m/m], heading drift [deg/m]."""

    speed: float
    fell: bool
    fall_time: float
    distance: float
    steady_speed: float
    lateral_per_m: float
    heading_per_m: float
    sim_time: float


def straight(robot: robot_models.RobotSpec, speed: float, distance: float, seed: int | None = None,
             params: GaitParameters | None = None) -> Straight:
    """Walk forward at ``speed`` until ``distance`` metres are covered (or a fall, or a deadline)."""
    rig = new_rig(robot, seed, params)
    x0, y0, _ = rig.pose()
    rig.walker.set_velocity_command(speed, 0.0, 0.0)
    commanded = rig.walker.status().commanded.vx  # after clamping to the gait's limits
    t0 = rig.sim.time
    deadline = t0 + distance / max(speed, 0.05) * 1.5 + 8.0
    mark: tuple[float, float] | None = None
    ok = True
    while rig.pose()[0] - x0 < distance and rig.sim.time < deadline:
        ok = rig.run(rig.sim.control_timestep)
        if not ok:
            break
        if mark is None and rig.pose()[0] - x0 >= STEADY_FROM:
            mark = (rig.pose()[0], rig.sim.time)
    x, y, yaw = rig.pose()
    covered = max(x - x0, 1e-6)
    steady = (x - mark[0]) / max(rig.sim.time - mark[1], 1e-6) if mark else 0.0
    result = Straight(commanded, not ok, rig.sim.time - t0, covered, steady, abs(y - y0) / covered,
                      abs(math.degrees(yaw)) / covered, rig.sim.time - t0)
    rig.close()
    return result


def sweep(robot: robot_models.RobotSpec, speeds: list[float], distance: float, params: GaitParameters | None) -> None:
    print(f"speed sweep, {distance:g} m each (steady speed from {STEADY_FROM:g} m on):")
    print(f"{'cmd m/s':>8} {'fell':>5} {'dist m':>7} {'speed m/s':>9} {'err %':>6} {'lat cm/m':>9} {'yaw deg/m':>9} {'sim s':>6}")
    for speed in speeds:
        r = straight(robot, speed, distance, params=params)
        fell = f"{r.fall_time:.1f}s" if r.fell else "no"
        clamped = f"  (commanded {speed:g}, clamped to the gait's {r.speed:g} m/s)" if r.speed < speed - 1e-9 else ""
        print(f"{r.speed:8.2f} {fell:>5} {r.distance:7.2f} {r.steady_speed:9.3f} {100 * (r.steady_speed / r.speed - 1):6.1f} "
              f"{100 * r.lateral_per_m:9.2f} {r.heading_per_m:9.3f} {r.sim_time:6.1f}{clamped}", flush=True)


def endurance(robot: robot_models.RobotSpec, speed: float, distance: float, seeds: int,
              params: GaitParameters | None) -> None:
    print(f"{distance:g} m at {speed:g} m/s, {seeds} seeds (perturbed initial state):")
    for seed in range(seeds):
        r = straight(robot, speed, distance, seed=seed, params=params)
        fell = f"FELL at {r.fall_time:.1f} s" if r.fell else "no fall"
        print(f"  seed {seed}: {fell}, {r.distance:.1f} m, steady {r.steady_speed:.3f} m/s "
              f"({100 * (r.steady_speed / speed - 1):+.1f}%), lateral {100 * r.lateral_per_m:.2f} cm/m, "
              f"heading {r.heading_per_m:.3f} deg/m", flush=True)


# ----- pushes ------------------------------------------------------------------------------------
def _wait_for_phase(rig: Rig, phase: str) -> bool:
    """Step until the gait is at ``phase`` (one of :data:`PUSH_PHASES`); False on a fall or a timeout."""
    walker = rig.walker
    single = walker.params.step_duration
    start = {"SS start": 0.0, "SS mid": 0.5 * single - 0.5 * PUSH_DURATION, "SS end": single - PUSH_DURATION}

    def ready() -> bool:
        kind, elapsed, _ = walker.gait_phase()
        if phase == "DS":
            return kind == "double"
        return kind == "single" and elapsed >= start[phase] - 1e-9

    # First leave the current phase, so the push meets the start of a fresh one.
    if not rig.run(1.0, until=lambda: walker.gait_phase()[0] == "double"):
        return False
    return rig.run(1.0, until=ready)


def push_trial(robot: robot_models.RobotSpec, direction_deg: float, phase: str | None, impulse: float,
               speed: float = 0.5) -> bool:
    """One push; True when absorbed. ``phase`` None pushes a standing robot."""
    rig = new_rig(robot)
    try:
        walker = rig.walker
        walker.set_velocity_command(speed if phase is not None else 0.0, 0.0, 0.0)
        if not rig.run(SETTLE_TIME if phase is not None else 1.0):
            return False
        if phase is not None and not _wait_for_phase(rig, phase):
            return False
        _, _, yaw = rig.pose()
        angle = yaw + math.radians(direction_deg)
        force = impulse / PUSH_DURATION
        rig.sim.push(names.ROOT_BODY, [force * math.cos(angle), force * math.sin(angle), 0.0], [0.0, 0.0, 0.0],
                     PUSH_DURATION)
        if phase is None:
            if not rig.run(4.0):
                return False
            return walker.status().mode is LocomotionMode.STANDING
        x0 = rig.pose()[0]
        if not rig.run(AFTER_PUSH):
            return False
        # Walks on at about the commanded pace (measured over the last 2 s) and stops standing.
        x1, t1 = rig.pose()[0], rig.sim.time
        if not rig.run(2.0):
            return False
        pace = (rig.pose()[0] - x1) / (rig.sim.time - t1)
        walker.set_velocity_command(0.0, 0.0, 0.0)
        if not rig.run(6.0, until=lambda: not walker.active):
            return False
        del x0
        return abs(pace - speed) < 0.15 and walker.status().mode is LocomotionMode.STANDING
    finally:
        rig.close()


def push_table(robot: robot_models.RobotSpec, impulse: float, directions: tuple[int, ...]) -> None:
    print(f"pushes while walking at 0.5 m/s: {impulse:g} N s over {PUSH_DURATION:g} s at the pelvis "
          "(direction: heading frame, 0 = pushed forward, 90 = pushed to the left)")
    print(f"{'dir deg':>8} " + " ".join(f"{p:>9}" for p in PUSH_PHASES))
    total = passed = 0
    for direction in directions:
        row = []
        for phase in PUSH_PHASES:
            ok = push_trial(robot, direction, phase, impulse)
            total += 1
            passed += ok
            row.append("ok" if ok else "FALL")
        print(f"{direction:8d} " + " ".join(f"{c:>9}" for c in row), flush=True)
    print(f"absorbed {passed}/{total}")


def largest_absorbed(robot: robot_models.RobotSpec, direction: float, walking: bool, high: float = 40.0,
                     resolution: float = 2.5) -> float:
    """Largest impulse [N s] (to ``resolution``) absorbed at every push phase (walking) or standing."""
    phases: tuple[str | None, ...] = PUSH_PHASES if walking else (None,)

    def absorbed(impulse: float) -> bool:
        return all(push_trial(robot, direction, phase, impulse) for phase in phases)

    low = 0.0
    probe = 10.0
    # Bracket from 10 N s, then bisect.
    if absorbed(probe):
        low = probe
        while low < high and absorbed(min(low * 1.5, high)):
            low = min(low * 1.5, high)
        top = min(low * 1.5, high) if low < high else high
    else:
        top = probe
    while top - low > resolution:
        mid = 0.5 * (low + top)
        if absorbed(mid):
            low = mid
        else:
            top = mid
    return low


# ----- turns, arcs, side steps, backward ----------------------------------------------------------
def turn_in_place(robot: robot_models.RobotSpec, angle_deg: float = 180.0, rate: float = 0.5) -> float:
    """Turn by ``angle_deg`` with a stop heading; returns the turned angle [deg] (nan on a fall)."""
    rig = new_rig(robot)
    try:
        _, _, yaw0 = rig.pose()
        target = yaw0 + math.radians(angle_deg)
        rig.walker.set_stop_heading(target)
        rig.walker.set_velocity_command(0.0, 0.0, math.copysign(rate, angle_deg))
        if not rig.run(abs(math.radians(angle_deg)) / rate + 10.0, until=lambda: abs(rig.walker.stop_heading_remaining()) < 1e-6):
            return math.nan
        rig.walker.set_velocity_command(0.0, 0.0, 0.0)
        if not rig.run(6.0, until=lambda: not rig.walker.active):
            return math.nan
        _, _, yaw = rig.pose()
        turned = yaw - yaw0  # within 2 pi; the turn is the equivalent angle nearest to the command
        turned += 2.0 * math.pi * round((math.radians(angle_deg) - turned) / (2.0 * math.pi))
        return math.degrees(turned)
    finally:
        rig.close()


def arc(robot: robot_models.RobotSpec, speed: float = 0.5, rate: float = 0.5, seconds: float = 20.0
        ) -> tuple[bool, float, float, float, float]:
    """Walk an arc for ``seconds``; returns (fell, turned angle [deg] over the whole command, the commanded
    angle [deg], the steady yaw rate [rad/s] and the steady speed along the path [m/s], both from 5 s on)."""
    rig = new_rig(robot)
    try:
        rig.walker.set_velocity_command(speed, 0.0, rate)
        poses = [rig.pose()]
        ok = True
        for _ in range(round(seconds / 0.1)):
            ok = rig.run(0.1)
            poses.append(rig.pose())
            if not ok:
                break
        track = np.array(poses)
        yaw = np.unwrap(track[:, 2])
        steady = track[50:] if len(track) > 60 else track
        steady_yaw = yaw[50:] if len(track) > 60 else yaw
        duration = 0.1 * (len(steady) - 1)
        steady_rate = float(steady_yaw[-1] - steady_yaw[0]) / max(duration, 1e-9)
        # Speed along the arc: the radius of a least-squares circle through the pelvis track times the yaw rate
        # (the pelvis also sways sideways each step, so its own path is longer than the arc).
        x, y = steady[:, 0], steady[:, 1]
        (a, b, c), *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), x * x + y * y, rcond=None)
        radius = math.sqrt(max(c + 0.25 * (a * a + b * b), 0.0))
        return (not ok, math.degrees(float(yaw[-1] - yaw[0])), math.degrees(rate * seconds), steady_rate,
                radius * abs(steady_rate))
    finally:
        rig.close()


def translate(robot: robot_models.RobotSpec, vx: float, vy: float, distance: float) -> float:
    """Walk ``distance`` metres along (vx, vy) with a stop point; returns the distance covered along it (nan on a fall)."""
    rig = new_rig(robot)
    try:
        x0, y0, yaw0 = rig.pose()
        speed = math.hypot(vx, vy)
        ux, uy = vx / speed, vy / speed
        wx, wy = math.cos(yaw0) * ux - math.sin(yaw0) * uy, math.sin(yaw0) * ux + math.cos(yaw0) * uy
        mx, my = rig.walker.feet_midpoint(rig.sim.data)
        rig.walker.set_stop_point((mx + distance * wx, my + distance * wy))
        rig.walker.set_velocity_command(vx, vy, 0.0)
        if not rig.run(distance / speed * 2.0 + 10.0, until=lambda: rig.walker.stop_point_reached()):
            return math.nan
        rig.walker.set_velocity_command(0.0, 0.0, 0.0)
        if not rig.run(6.0, until=lambda: not rig.walker.active):
            return math.nan
        x, y, _ = rig.pose()
        return (x - x0) * wx + (y - y0) * wy
    finally:
        rig.close()


def motions(robot: robot_models.RobotSpec) -> None:
    print("turns, arcs, side steps, backward (error against the command):")
    turned = turn_in_place(robot, 180.0)
    print(f"  turn in place 180 deg at 0.5 rad/s: turned {turned:.1f} deg (error {turned - 180.0:+.1f} deg, "
          f"{100 * (turned / 180.0 - 1):+.1f}%)", flush=True)
    fell, got, expected, rate, speed = arc(robot)
    print(f"  arc 0.5 m/s, 0.5 rad/s, 20 s: {'FELL' if fell else 'no fall'}, turned {got:.0f} deg of {expected:.0f} "
          f"({100 * (got / expected - 1):+.1f}%, the start included); from 5 s on: {rate:.3f} rad/s "
          f"({100 * (rate / 0.5 - 1):+.1f}%), {speed:.3f} m/s along the arc ({100 * (speed / 0.5 - 1):+.1f}%)",
          flush=True)
    side = translate(robot, 0.0, 0.2, 1.0)
    print(f"  side step 1 m left at 0.2 m/s: {side:.3f} m ({100 * (side - 1.0):+.1f}%)", flush=True)
    back = translate(robot, -0.3, 0.0, 2.0)
    print(f"  backward 2 m at 0.3 m/s: {back:.3f} m ({100 * (back / 2.0 - 1):+.1f}%)", flush=True)


# ----- cost --------------------------------------------------------------------------------------
def cost(robot: robot_models.RobotSpec, speed: float, seconds: float) -> None:
    """Controller time per tick, and raw mj_step over one control period on the same walk's states."""
    rig = new_rig(robot)
    rig.walker.set_velocity_command(speed, 0.0, 0.0)
    model, data = rig.sim.model, rig.sim.data
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    ticks = round(seconds / rig.sim.control_timestep)
    states = np.empty((ticks, mujoco.mj_stateSize(model, spec)))
    for k in range(ticks):
        mujoco.mj_getState(model, data, states[k], spec)
        rig.sim.step(1)
    replay = mujoco.MjData(model)  # legs still in torque mode, as during the walk
    physics = np.zeros(ticks)
    for k in range(ticks):
        mujoco.mj_setState(model, replay, states[k], spec)
        start = time.perf_counter()
        mujoco.mj_step(model, replay, nstep=rig.sim.decimation)
        physics[k] = time.perf_counter() - start
    control = np.array(rig.timed.times) * 1e6
    physics *= 1e6
    fell = rig.fallen()
    rig.close()
    print(f"cost, {seconds:g} s at {speed:g} m/s{' (FELL)' if fell else ''}, {ticks} control ticks of "
          f"{rig.sim.decimation} physics steps:")
    print(f"  controller per tick: mean {control.mean():.0f} us, p50 {np.percentile(control, 50):.0f} us, "
          f"p95 {np.percentile(control, 95):.0f} us")
    print(f"  raw mj_step per tick: mean {physics.mean():.0f} us, p50 {np.percentile(physics, 50):.0f} us, "
          f"p95 {np.percentile(physics, 95):.0f} us; controller / physics {control.mean() / physics.mean():.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a smaller version of every section")
    parser.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS), help="sections to run")
    parser.add_argument("--speeds", type=float, nargs="+", help="sweep speeds [m/s] (default 0.3 .. 1.0)")
    parser.add_argument("--distance", type=float, default=20.0, help="sweep distance [m]")
    parser.add_argument("--seeds", type=int, default=5, help="endurance seeds")
    parser.add_argument("--endurance-distance", type=float, default=100.0, help="[m]")
    parser.add_argument("--endurance-speed", type=float, default=0.8, help="[m/s]")
    parser.add_argument("--directions", type=int, nargs="+", default=list(PUSH_DIRECTIONS), help="push directions [deg]")
    parser.add_argument("--impulse", type=float, default=10.0, help="push table impulse [N s]")
    parser.add_argument("--no-largest", action="store_true", help="skip the largest-impulse search")
    args = parser.parse_args()
    robot = robot_models.load("g1")
    speeds = args.speeds or [round(0.3 + 0.1 * k, 1) for k in range(8)]
    if args.quick:
        speeds = args.speeds or [0.5, 0.8, 1.0]
    started = time.perf_counter()
    if "sweep" in args.only:
        sweep(robot, speeds, args.distance, None)
    if "endurance" in args.only:
        endurance(robot, args.endurance_speed, 20.0 if args.quick else args.endurance_distance,
                  1 if args.quick else args.seeds, None)
    if "push" in args.only:
        directions = tuple(args.directions[::2] if args.quick else args.directions)
        push_table(robot, args.impulse, directions)
        if not (args.quick or args.no_largest):
            print("largest impulse absorbed per direction [N s] (at all 4 phases walking; standing):")
            for direction in directions:
                walking = largest_absorbed(robot, direction, walking=True)
                standing = largest_absorbed(robot, direction, walking=False)
                print(f"  {direction:4d} deg: walking {walking:5.1f}, standing {standing:5.1f}", flush=True)
    if "motions" in args.only:
        motions(robot)
    if "cost" in args.only:
        cost(robot, 0.8 if not args.quick else 0.5, 10.0 if not args.quick else 4.0)
    print(f"(benchmark wall time {time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
