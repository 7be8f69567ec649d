"""Arm benchmark: MoveArm accuracy, pick-and-place success, IK cost per control step, speed.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/arm_bench.py [--poses 20] [--picks 50] [--seed 0]``.
Headless, single-threaded, seeded.
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco
import numpy as np

import robot_models
from robot_models import panda_constants as names
from sim_bridge import Pose, Simulation, Slot
from sim_bridge.arm import ArmController, PickPlace, PickPlaceGoal, solve_ik

IK_BUDGET_MS = 0.5  # p95 of the IK per control step (tracker issue 9)
SETTLE_TIMEOUT_S = 6.0
PICK_TIMEOUT_S = 40.0
CLEARANCE_M = 0.12  # from the other boxes, for picks and places


def _down_tilted(rng: np.random.Generator) -> np.ndarray:
    """Tool pointing down with a random yaw and a tilt of up to 0.3 rad."""
    yaw = rng.uniform(-math.pi / 2, math.pi / 2)
    axis = rng.normal(size=3)
    axis[2] = 0.0
    axis /= np.linalg.norm(axis)
    tilt = np.empty(4)
    mujoco.mju_axisAngle2Quat(tilt, axis, rng.uniform(0.0, 0.3))
    base = np.array([0.0, math.cos(0.5 * yaw), math.sin(0.5 * yaw), 0.0])
    quat = np.empty(4)
    mujoco.mju_mulQuat(quat, tilt, base)
    return quat


def bench_reach(count: int, rng: np.random.Generator) -> np.ndarray:
    robot = robot_models.load("panda")
    sim = Simulation(robot)
    arm = ArmController(robot)
    sim.set_controller(Slot.ARM, arm)
    position_errors, orientation_errors, settle_times, failures = [], [], [], 0
    wall_start, sim_start = time.perf_counter(), sim.time
    done = 0
    while done < count:
        target = Pose(np.array([rng.uniform(0.3, 0.65), rng.uniform(-0.35, 0.35), rng.uniform(0.1, 0.5)]), _down_tilted(rng))
        if not solve_ik(arm.kinematics, sim.data, "arm", target, False).success:
            continue
        arm.set_target("arm", target, False, 0.5, 1.5)
        started = sim.time
        status = arm.status("arm")
        while sim.time - started < SETTLE_TIMEOUT_S:
            sim.step(1)
            status = arm.status("arm")
            if status.settled or status.unreachable:
                break
        done += 1
        if not status.settled:
            failures += 1
        position_errors.append(status.position_error)
        orientation_errors.append(status.orientation_error)
        settle_times.append(sim.time - started)
    ik = np.array(arm.take_ik_timings()) * 1000.0
    wall, simulated = time.perf_counter() - wall_start, sim.time - sim_start
    print(f"MoveArm over {count} random reachable poses (0.5 m/s, 1.5 rad/s limits):")
    print(f"  settled {count - failures}/{count}; position error mean {np.mean(position_errors) * 1000:.3f} mm, "
          f"max {np.max(position_errors) * 1000:.3f} mm; orientation error mean {np.mean(orientation_errors):.5f} rad, "
          f"max {np.max(orientation_errors):.5f} rad")
    print(f"  sim time to settle: mean {np.mean(settle_times):.2f} s, max {np.max(settle_times):.2f} s")
    print(f"  IK per control step: p50 {np.percentile(ik, 50):.3f} ms, p95 {np.percentile(ik, 95):.3f} ms")
    print(f"  wall/sim time: {wall:.2f} s / {simulated:.2f} s = {wall / simulated:.3f}")
    return ik


def bench_g1_reach(count: int, rng: np.random.Generator) -> np.ndarray:
    robot = robot_models.load("g1")
    sim = Simulation(robot)
    arm = ArmController(robot)
    sim.set_controller(Slot.ARM, arm)
    sim.step(125)
    home = arm.status("right_arm").tool_pose
    settled, errors, tilts = 0, [], []
    wall_start, sim_start = time.perf_counter(), sim.time
    done = 0
    while done < count:
        target = Pose(home.position + rng.uniform([0.0, -0.1, 0.0], [0.15, 0.1, 0.2]), home.orientation_wxyz)
        if not solve_ik(arm.kinematics, sim.data, "right_arm", target, False).success:
            continue
        arm.set_target("right_arm", target, False, 0.15, 0.5)
        started = sim.time
        while sim.time - started < SETTLE_TIMEOUT_S and not arm.status("right_arm").settled:
            sim.step(1)
        status = arm.status("right_arm")
        settled += int(status.settled)
        errors.append(status.position_error)
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, sim.base_state().pose.orientation_wxyz)
        tilts.append(math.degrees(math.acos(min(1.0, rot[8]))))
        done += 1
    ik = np.array(arm.take_ik_timings()) * 1000.0
    wall, simulated = time.perf_counter() - wall_start, sim.time - sim_start
    print(f"G1 right arm over {count} random reachable poses (0.15 m/s), legs on their PD servos:")
    print(f"  settled {settled}/{count}; position error mean {np.mean(errors) * 1000:.3f} mm, "
          f"max {np.max(errors) * 1000:.3f} mm; "
          f"pelvis tilt at settle max {np.max(tilts):.2f} deg; pelvis height {sim.base_state().pose.position[2]:.3f} m")
    print(f"  IK per control step: p50 {np.percentile(ik, 50):.3f} ms, p95 {np.percentile(ik, 95):.3f} ms; "
          f"wall/sim {wall:.2f} s / {simulated:.2f} s = {wall / simulated:.3f}")
    return ik


def _free_spot(rng: np.random.Generator, avoid: list[np.ndarray]) -> np.ndarray:
    while True:
        xy = np.array([rng.uniform(0.35, 0.65), rng.uniform(-0.35, 0.35)])
        if all(np.linalg.norm(xy - a[:2]) >= CLEARANCE_M for a in avoid):
            return xy


def bench_pick_place(count: int, rng: np.random.Generator) -> np.ndarray:
    robot = robot_models.load("panda")
    sim = Simulation(robot)
    arm = ArmController(robot)
    skill = PickPlace(arm)
    sim.set_controller(Slot.ARM, skill)
    others = [np.array(names.BOX_HOME_POSITIONS[0]), np.array(names.BOX_HOME_POSITIONS[2])]
    box_adr = int(robot.model.joint("box_1").qposadr[0])
    successes, errors, lifts = 0, [], []
    failures: dict[str, int] = {}
    wall_start, sim_total = time.perf_counter(), 0.0
    for _ in range(count):
        sim.reset()
        pick_xy = _free_spot(rng, others)
        yaw = rng.uniform(-math.pi / 4, math.pi / 4)
        sim.data.qpos[box_adr : box_adr + 7] = [*pick_xy, names.BOX_HALF_SIZE, math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
        mujoco.mj_forward(sim.model, sim.data)
        place_xy = _free_spot(rng, [*others, np.array([*pick_xy, 0.0])])
        started = sim.time
        skill.start(PickPlaceGoal("box_1", (float(place_xy[0]), float(place_xy[1]), 0.0)))
        while sim.time - started < PICK_TIMEOUT_S:
            sim.step(1)
            progress = skill.progress()
            if progress.done:
                break
        sim_total += sim.time - started
        if progress.success:
            successes += 1
            errors.append(progress.placement_error)
            lifts.append(progress.object_lift)
        else:
            key = f"{progress.failure.name} at {progress.stage.name}"
            failures[key] = failures.get(key, 0) + 1
            print(f"  failed: pick {np.round(pick_xy, 3)} yaw {yaw:.2f} -> place {np.round(place_xy, 3)}: {progress.reason}")
    ik = np.array(arm.take_ik_timings()) * 1000.0
    wall = time.perf_counter() - wall_start
    print(f"Pick-and-place of box_1 over {count} random pick/place positions (random yaw +-45 deg):")
    print(f"  success {successes}/{count} = {100.0 * successes / count:.1f} %; failures: {failures or 'none'}")
    if errors:
        print(f"  placement error: mean {np.mean(errors) * 1000:.2f} mm, p95 {np.percentile(errors, 95) * 1000:.2f} mm, "
              f"max {np.max(errors) * 1000:.2f} mm; object lift mean {np.mean(lifts):.3f} m")
    print(f"  sim time per pick-place: {sim_total / count:.2f} s")
    print(f"  IK per control step: p50 {np.percentile(ik, 50):.3f} ms, p95 {np.percentile(ik, 95):.3f} ms")
    print(f"  wall/sim time: {wall:.2f} s / {sim_total:.2f} s = {wall / sim_total:.3f}")
    return ik


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--poses", type=int, default=20)
    parser.add_argument("--picks", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    ik = np.concatenate([bench_reach(args.poses, rng), bench_g1_reach(10, rng), bench_pick_place(args.picks, rng)])
    p95 = np.percentile(ik, 95)
    print(f"IK per control step, every tick of the three runs ({ik.size} ticks): p50 {np.percentile(ik, 50):.3f} ms, "
          f"p95 {p95:.3f} ms, max {np.max(ik):.3f} ms; "
          f"budget p95 <= {IK_BUDGET_MS} ms: {'met' if p95 <= IK_BUDGET_MS else 'MISSED'}")


if __name__ == "__main__":
    main()
