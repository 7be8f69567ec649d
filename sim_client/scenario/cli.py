"""``scenario list`` and ``scenario run NAME|FILE [--rtf X] [--record] [--video] [--plots] [--out DIR]``."""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

from sim_client.scenario import schema


def _list() -> int:
    for path in schema.all_files():
        try:
            scenario = schema.load(path)
        except schema.ScenarioError as error:
            print(f"{path.stem:<28} INVALID  {error}")
            continue
        needs = ", ".join(scenario.actions) or "sim only"
        tags = f" [{', '.join(scenario.tags)}]" if scenario.tags else ""
        print(f"{scenario.name:<28} {scenario.robot:<6} needs: {needs:<26}{tags}  {scenario.description}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="scenario", description="Run headless scenario files and judge them.")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the scenarios in scenarios/")
    check = sub.add_parser("check", help="validate scenario files")
    check.add_argument("files", nargs="*")
    run = sub.add_parser("run", help="run a scenario by name or file")
    run.add_argument("scenario", help="name in scenarios/ or a .yaml path")
    run.add_argument("--rtf", type=float, default=None,
                     help="real-time factor; 0 = lock-stepped as fast as possible (default: the file's)")
    run.add_argument("--record", action="store_true", help="write an MCAP of every topic")
    run.add_argument("--video", action="store_true", help="render an MP4 from the track camera")
    run.add_argument("--plots", action="store_true", help="plot what the expectations check")
    run.add_argument("--all", action="store_true", help="--record --video --plots")
    run.add_argument("--out", type=pathlib.Path, default=pathlib.Path("scenario_runs"), help="folder for the run folders")
    run.add_argument("--attach", action="store_true", help="use nodes already running (e.g. `sim up`) instead of starting them")
    options = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("MUJOCO_GL", "egl")
    if options.command == "list":
        return _list()
    if options.command == "check":
        files = [pathlib.Path(f) for f in options.files] or schema.all_files()
        bad = 0
        for path in files:
            try:
                schema.load(path)
                print(f"ok       {path}")
            except schema.ScenarioError as error:
                bad += 1
                print(f"invalid  {error}")
        return 1 if bad else 0
    try:
        scenario = schema.load(schema.find(options.scenario))
    except schema.ScenarioError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    from sim_client.scenario.runner import RunOptions, run as run_scenario

    run_options = RunOptions(rtf=options.rtf, record=options.record or options.all, video=options.video or options.all,
                             plots=options.plots or options.all, out=options.out, launch=not options.attach)
    try:
        result = run_scenario(scenario, run_options)
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return 130
    return 0 if result.passed else 1


if __name__ == "__main__":
    sys.exit(main())
