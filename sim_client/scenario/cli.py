"""``scenario list``, ``scenario kinds``, ``scenario check [FILE...]`` and
``scenario run NAME|FILE... [--rtf X] [--record] [--video] [--plots] [--out DIR]`` and
``scenario sweep NAME|FILE --grid KEY=VALUES ... [--seeds 0,1] [--workers N] [--address RAY]``."""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

from sim_client.scenario.model import schema


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


def _kinds() -> int:
    """What a scenario file may use, from the kinds that parse, run and describe it."""
    import robot_models
    from sim_client.scenario.model.actions import ACTIONS
    from sim_client.scenario.model.conditions import COMPARISONS
    from sim_client.scenario.model.measures import MEASURES
    from sim_client.scenario.model.robots import robot_facts
    from sim_client.scenario.model.steps import STEPS

    print("steps (each may carry mark: NAME):")
    for step in STEPS.values():
        print(f"  {step.name:<18} {step.about}")
    print("measures (in expectations and conditions; marks: start, end, step marks, <goal>.sent, <goal>.done):")
    for measure in MEASURES.values():
        keys = ", ".join(key.name + ("" if key.required else "?") for key in measure.keys)
        unit = f" [{measure.unit}]" if isinstance(measure.unit, str) and measure.unit else ""
        walking = " (walking robots)" if measure.walking else ""
        print(f"  {measure.name:<18} {keys:<28} {measure.about}{unit}{walking}")
    print(f"comparisons: {', '.join(COMPARISONS)} (near with tol or rel_tol)")
    print("actions (send_goal):")
    for action in ACTIONS.values():
        robots_with = [name for name in robot_models.ROBOT_NAMES if action.available(robot_facts(name))]
        print(f"  {action.name:<18} goal: {action.fields}")
        print(f"  {'':<18} robots: {', '.join(robots_with)}; error codes: {', '.join(action.error_names)}")
    return 0


def _sweep(options: argparse.Namespace) -> int:
    from sim_client.scenario.running.sweep import SweepError, parse_grid, run_sweep

    try:
        path = schema.find(options.scenario)
        grid = parse_grid(options.grid)
        seeds = [int(seed) for seed in str(options.seeds).split(",") if seed.strip()]
        if options.workers is not None and options.workers < 1:
            raise SweepError(f"--workers must be >= 1, got {options.workers}")
        result = run_sweep(path, grid, seeds or [0], options.out, options.address, options.workers, options.rtf)
    except (SweepError, schema.ScenarioError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except ValueError as error:
        print(f"error: --seeds takes comma-separated integers: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return 130
    return 0 if result.passed == len(result.rows) else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="scenario", description="Run headless scenario files and judge them.")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the scenarios in scenarios/")
    sub.add_parser("kinds", help="list the steps, measures and actions a scenario file may use")
    check = sub.add_parser("check", help="validate scenario files")
    check.add_argument("files", nargs="*")
    run = sub.add_parser("run", help="run scenarios by name or file (consecutive ones of one robot and scene share a bring-up)")
    run.add_argument("scenarios", nargs="+", metavar="scenario", help="name in scenarios/ or a .yaml path")
    run.add_argument("--rtf", type=float, default=None,
                     help="real-time factor; 0 = lock-stepped as fast as possible (default: the file's)")
    run.add_argument("--record", action="store_true", help="write an MCAP of every topic")
    run.add_argument("--video", action="store_true", help="render an MP4 from the track camera")
    run.add_argument("--plots", action="store_true", help="plot what the expectations check")
    run.add_argument("--camera", action="store_true",
                     help="watch the robot's camera: its images in the MCAP and camera.png (each frame costs a rendering)")
    run.add_argument("--all", action="store_true", help="--record --video --plots")
    run.add_argument("--out", type=pathlib.Path, default=pathlib.Path("scenario_runs"), help="folder for the run folders")
    run.add_argument("--attach", action="store_true", help="use nodes already running (e.g. `sim up`) instead of starting them")
    run.add_argument("--namespace", default="",
                     help="run under this namespace (its bring-up started there; with --attach, found there)")
    sweep = sub.add_parser("sweep", help="run a scenario over a grid of values and seeds, in parallel on Ray",
                           description="Run one scenario over every combination of --grid values, once per seed, "
                           "each run on its own ROS domain, as Ray tasks (a local Ray instance, or the cluster at "
                           "--address). Writes sweep.csv, sweep.json and sweep.png.")
    sweep.add_argument("scenario", help="name in scenarios/ or a .yaml path")
    sweep.add_argument("--grid", action="append", default=[], metavar="KEY=VALUES",
                       help="a dotted path into the file and its values: a YAML list or start:stop:step, e.g. "
                       "steps.0.send_goal.goal.speed=0.3:0.6:0.1 (repeat for more keys)")
    sweep.add_argument("--seeds", default="0", help="comma-separated seeds, written into each run's seed (default 0)")
    sweep.add_argument("--workers", type=int, default=None, help="runs at once on a local Ray instance (default: CPUs)")
    sweep.add_argument("--address", default=None, help="address of a Ray cluster (e.g. ray://head:10001 or auto)")
    sweep.add_argument("--rtf", type=float, default=None, help="real-time factor of each run (default: the file's)")
    sweep.add_argument("--out", type=pathlib.Path, default=pathlib.Path("scenario_runs"), help="folder for the sweep folder")
    options = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("MUJOCO_GL", "egl")
    if options.command == "list":
        return _list()
    if options.command == "kinds":
        return _kinds()
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
    if options.command == "sweep":
        return _sweep(options)
    try:
        scenarios = [schema.load(schema.find(name)) for name in options.scenarios]
    except schema.ScenarioError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    from sim_client.scenario.running.options import RunOptions
    from sim_client.scenario.running.runner import run_all

    run_options = RunOptions(rtf=options.rtf, record=options.record or options.all, video=options.video or options.all,
                             plots=options.plots or options.all, camera=options.camera, out=options.out,
                             launch=not options.attach, namespace=options.namespace.strip("/"))
    try:
        results, bringups = run_all(scenarios, run_options)
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return 130
    if len(results) > 1:
        passed = sum(result.passed for result in results)
        print(f"\n{passed}/{len(results)} scenarios passed, on {bringups} bring-up{'s' if bringups != 1 else ''}")
        for result in results:
            print(f"  {'PASSED' if result.passed else 'FAILED':<8} {result.scenario:<28} start-up {result.startup_time:5.1f} s, "
                  f"run {result.wall_time:5.1f} s  ->  {result.folder}")
    return 0 if all(result.passed for result in results) else 1

if __name__ == "__main__":
    sys.exit(main())
