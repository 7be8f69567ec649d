"""The main job (``make demo``): run the headline scenarios headless and show verdicts and artifacts.

The G1 walks 2 m with feedback, walking_speed is changed mid-walk, a shove knocks it over and it
walks again after a reset, it navigates around an obstacle (the course scene); the Panda moves its
arm through poses and picks and places a box; the G1 fetches a box from one table to another with
both palms, then the cube with one hand (the tables scene). Consecutive scenarios of one robot and
scene share their nodes (``bringup``, started once and reset between runs: four bring-ups for the
default list); each runs lock-stepped on sim time as fast as the machine allows, and leaves a folder
with report.json, an MCAP recording, an MP4 video and plots.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

# Ordered by bring-up (G1 open floor, G1 course, Panda table): consecutive ones share their nodes.
# The G1's first (one bring-up: the open floor, the course, the tables loaded in turn), then the Panda's.
HEADLINE = ("walk_2m", "walking_speed_change", "walking_speed_0_5_to_0_8", "shove_fall_and_recover",
            "navigate_around_obstacle", "fetch_box", "fetch_cube", "move_arm_sequence", "pick_place_box")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="sim-demo", description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", default=list(HEADLINE), help="scenario names (default: the headline ones)")
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("demo_runs"))
    parser.add_argument("--no-video", action="store_true", help="skip the MP4 rendering (the slowest artifact)")
    options = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("MUJOCO_GL", "egl")

    from sim_client.scenario.model import schema
    from sim_client.scenario.running.bringups import Bringups
    from sim_client.scenario.running.options import RunOptions
    from sim_client.scenario.running.runner import run

    rows: list[tuple[str, str, str]] = []
    scenarios = [schema.load(schema.find(name)) for name in options.scenarios]
    with Bringups() as bringups:
        results = []
        for scenario in scenarios:
            print(f"\n{'=' * 78}\n{scenario.name}: {scenario.description}\n{'=' * 78}", flush=True)
            run_options = RunOptions(record=True, video=not options.no_video, plots=True, out=options.out)
            results.append(run(scenario, run_options, bringups=bringups))
        started = bringups.started
    for name, result in zip(options.scenarios, results, strict=True):
        ratio = (f"start-up {result.startup_time:.0f} s, wall {result.wall_time:.1f} s / sim {result.sim_time:.1f} s"
                 f" = {result.wall_time / max(result.sim_time, 1e-9):.2f}")
        rows.append((name, "PASSED" if result.passed else "FAILED", f"{ratio}  ->  {result.folder}"))
    print(f"\n{'=' * 78}\ndemo summary: {len(results)} scenarios on {started} bring-up{'s' if started != 1 else ''}")
    for name, verdict, detail in rows:
        print(f"  {verdict:<8} {name:<26} {detail}")
    print("Open recording.mcap in Foxglove; video.mp4 and *.png are next to report.json.")
    return 0 if all(v == "PASSED" for _, v, _ in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
