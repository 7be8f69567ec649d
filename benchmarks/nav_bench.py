"""Navigation benchmark on the G1 course (prints figures; not a test).

For --goals random goal positions in free space of the course (seeded), the robot starts at the
origin, the planner (A* on the inflated obstacle grid) plans a path and the path follower commands
the physics walking controller at 20 Hz, exactly what ``/navigate_to_pose`` does, without the ROS
transport in between. A goal succeeds when the robot stands within 0.15 m / 0.15 rad of it without
falling before a timeout. Prints the success rate, the position errors and wall time / sim time.

Run: ``.venv/bin/python benchmarks/nav_bench.py [--goals 20] [--seed 0] [--speed 0.3]``
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

import robot_models
from sim_bridge import Simulation, Slot
from sim_bridge.locomotion import LocomotionMode, WalkingController
from sim_bridge.navigation import NoPathError, OccupancyGrid, PathFollower, grid_from_obstacles, plan_path
from sim_bridge.navigation.planner import path_length

COMMAND_PERIOD_S = 0.05
INFLATION_M = 0.45  # robot radius 0.30 + obstacle_detection_threshold 0.15 (the server's defaults)


def pose_of(sim: Simulation) -> tuple[float, float, float]:
    base = sim.base_state().pose
    w, x, y, z = base.orientation_wxyz
    return float(base.position[0]), float(base.position[1]), math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def navigate(
    sim: Simulation, walker: WalkingController, grid: OccupancyGrid, goal: tuple[float, float, float], speed: float
) -> dict:
    sim.reset()
    path = plan_path(grid, (0.0, 0.0), goal[:2])
    follower = PathFollower(path, goal[2])
    steps_per_command = round(COMMAND_PERIOD_S / sim.control_timestep)
    deadline = sim.time + path_length(path) / speed * 3.0 + 30.0
    start_sim, start_wall = sim.time, time.perf_counter()
    outcome = "timeout"
    while sim.time < deadline:
        x, y, yaw = pose_of(sim)
        if sim.base_state().pose.position[2] < 0.45 or walker.status().fallen:
            outcome = "fell"
            break
        command = follower.command(x, y, yaw, speed, 0.6)
        if command.phase == "arrived":
            walker.set_velocity_command(0.0, 0.0, 0.0)
            settle = sim.time + 4.0
            while sim.time < settle and walker.status().mode != LocomotionMode.STANDING:
                sim.step(steps_per_command)
            outcome = "arrived"
            break
        walker.set_velocity_command(command.vx, 0.0, command.wz)
        sim.step(steps_per_command)
    x, y, yaw = pose_of(sim)
    error = math.dist((x, y), goal[:2])
    yaw_error = abs(math.remainder(yaw - goal[2], 2 * math.pi))
    success = outcome == "arrived" and error <= 0.2 and yaw_error <= 0.2 and not walker.status().fallen
    return {"success": success, "outcome": outcome, "error": error, "yaw_error": yaw_error,
            "sim": sim.time - start_sim, "wall": time.perf_counter() - start_wall, "path": path_length(path)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--goals", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--speed", type=float, default=0.3)
    options = parser.parse_args()
    robot = robot_models.load("g1", "course")
    sim = Simulation(robot)
    walker = WalkingController(sim.model, sim.robot.biped)
    sim.set_controller(Slot.LOCOMOTION, walker)
    grid = grid_from_obstacles(robot.obstacles).inflated(INFLATION_M)
    rng = np.random.default_rng(options.seed)
    results: list[dict] = []
    while len(results) < options.goals:
        goal = (float(rng.uniform(-1.5, 4.5)), float(rng.uniform(-2.5, 2.5)), float(rng.uniform(-math.pi, math.pi)))
        if not grid.is_free(*goal[:2]) or math.dist(goal[:2], (0.0, 0.0)) < 1.0:
            continue
        try:
            result = navigate(sim, walker, grid, goal, options.speed)
        except NoPathError as error:
            print(f"goal {goal}: no path ({error})")
            continue
        results.append(result)
        print(f"goal ({goal[0]:+.2f}, {goal[1]:+.2f}, {math.degrees(goal[2]):+4.0f} deg): {result['outcome']:<8} "
              f"error {result['error']:.3f} m {math.degrees(result['yaw_error']):.1f} deg, path {result['path']:.2f} m, "
              f"sim {result['sim']:.1f} s, wall {result['wall']:.1f} s", flush=True)
    successes = sum(r["success"] for r in results)
    print(f"\nNavigateToPose on the course: {successes}/{len(results)} succeeded ({100 * successes / len(results):.0f}%), "
          f"median position error {statistics.median(r['error'] for r in results):.3f} m, "
          f"median wall/sim {statistics.median(r['wall'] / r['sim'] for r in results):.3f}")


if __name__ == "__main__":
    main()
