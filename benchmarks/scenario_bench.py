"""The ROS path against the core (figures for the closing note; not a test).

In one run, alternating so that the machine's drifting speed touches both alike:
- ``walk_2m`` through ROS: ``bringup`` (sim node and servers in their own processes), lock-stepped
  as fast as possible by the scenario runner, MCAP recording on, video off. Its run's wall time over
  sim time (start-up, i.e. process start and discovery, is printed apart: a fixed cost);
- the same gait in the core (``Simulation`` + ``WalkingController``, no ROS): a 0.3 m/s walk for
  the same sim time, wall/sim;
- the ROS run again with ``SIM_SCHEDULING=fair``: every thread under the normal policy, as before
  ``sim_ros.scheduling`` (what the physics thread gains from the others' ``SCHED_BATCH``).

Prints each round and the medians, and the ratio of the two medians.

Usage: ``make bench-scenario`` or ``.venv/bin/python benchmarks/scenario_bench.py [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import random
import statistics
import sys
import tempfile

# A domain of this run's own, on this machine only: set before rclpy is imported.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + random.randrange(101)))  # 1..101: safe for Fast DDS ports
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

# Imported once the ROS environment and the path above are fixed.
import robot_models
from sim_client.scenario.model import schema
from sim_client.scenario.running.options import RunOptions
from sim_client.scenario.running.runner import run
from sim_ros.scheduling import SCHEDULING_VARIABLE

from walk_bench import core_walk


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="walk_2m")
    parser.add_argument("--rounds", type=int, default=3)
    options = parser.parse_args()
    scenario = schema.load(schema.find(options.scenario))
    robot = robot_models.load(scenario.robot, scenario.scene)
    ros_ratios, core_ratios, fair_ratios = [], [], []
    print(f"{options.scenario} through ROS (lock-step, MCAP on, video off) against the core walk, wall/sim")
    with tempfile.TemporaryDirectory(prefix="scenario_bench-") as out, open(os.devnull, "w") as quiet:
        for round_ in range(options.rounds):
            fair = None
            for policy in (("fair", "") if round_ % 2 else ("", "fair")):  # alternated: neither always runs first
                os.environ[SCHEDULING_VARIABLE] = policy
                result = run(scenario, RunOptions(record=True, out=pathlib.Path(out), quiet=True), stream=quiet)
                if policy == "fair":
                    fair = result.wall_time / result.sim_time if result.passed else None
                else:
                    ours = result
            os.environ.pop(SCHEDULING_VARIABLE, None)
            result = ours
            if not result.passed:
                print(f"  round {round_ + 1}: the scenario FAILED: {result.failures}")
                continue
            if fair is not None:
                fair_ratios.append(fair)
            ros = result.wall_time / result.sim_time
            core = core_walk(robot, speed=0.3, duration=result.sim_time, physics=False)
            ros_ratios.append(ros)
            core_ratios.append(core.wall_time / core.sim_time)
            print(f"  round {round_ + 1}: ROS {ros:.3f} (start-up {result.startup_time:.1f} s, run {result.wall_time:.1f} s "
                  f"for {result.sim_time:.1f} s of sim time)   core {core_ratios[-1]:.3f}   "
                  f"ROS with SIM_SCHEDULING=fair {'-' if fair is None else f'{fair:.3f}'}", flush=True)
    if ros_ratios:
        ros_median, core_median = statistics.median(ros_ratios), statistics.median(core_ratios)
        print(f"median: ROS {ros_median:.3f} ({1 / ros_median:.1f}x real time; issue 24 asks <= 0.15)   core {core_median:.3f}   "
              f"ROS / core {ros_median / core_median:.1f}x")
    if fair_ratios:
        print(f"median with SIM_SCHEDULING=fair (every thread under the normal policy): ROS {statistics.median(fair_ratios):.3f}")


if __name__ == "__main__":
    main()
