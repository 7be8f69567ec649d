"""Run a scenario from start to end: bring up its nodes, carry it out, write what it leaves in its run folder.

A run folder holds ``report.json`` (expectations with measured values and verdicts, goals, wall and
sim time) and, when asked, ``recording.mcap``, ``video.mp4``, the plots and ``camera.png``
(:mod:`sim_client.scenario.outputs`).
"""

from __future__ import annotations

import datetime
import pathlib
import sys
import time
from collections.abc import Sequence
from typing import TextIO

from sim_client.scenario.model.schema import Scenario
from sim_client.scenario.outputs.recorder_process import RecordingError
from sim_client.scenario.running.bringups import Bringups
from sim_client.scenario.running.options import RunOptions
from sim_client.scenario.running.report import RunResult, write_json
from sim_client.scenario.running.scenario_run import ScenarioRun
from sim_client.scenario.running.sim_time import StepFailure
from sim_ros.session import RosSession, WaitTimeout

DEFAULT_OPTIONS = RunOptions()


def run_folder(base: pathlib.Path, name: str) -> pathlib.Path:
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    folder = base / f"{name}-{stamp}"
    n = 1
    while folder.exists():
        n += 1
        folder = base / f"{name}-{stamp}-{n}"
    folder.mkdir(parents=True)
    return folder


def run(scenario: Scenario, options: RunOptions = DEFAULT_OPTIONS, stream: TextIO = sys.stdout,
        bringups: Bringups | None = None) -> RunResult:
    """Bring up ``bringup --robot R`` (paused for lock-stepping), run the scenario, write artifacts.

    Args:
        scenario: what to run.
        options: how (``launch`` False: against nodes already running).
        stream: where the progress goes.
        bringups: the bring-up of the previous run, reused when it has the same robot and pace (this
            scenario's scene loaded, and reset, in between); None: a bring-up of its own, stopped at the end.
            Unused with ``launch`` False.
    """
    if not options.launch:
        bringups = None
    elif bringups is None:
        with Bringups(stream, quiet=True) as own:
            return run(scenario, options, stream, own)
    folder = run_folder(options.out, scenario.name)
    rtf = scenario.rtf if options.rtf is None else options.rtf
    if bringups is None:
        with RosSession("scenario_runner", use_sim_time=True, namespace=options.namespace) as session:
            run_ = ScenarioRun(scenario, session, options, folder, stream)
            result = run_.execute()
            _write_artifacts(run_, result, stream)
            return result
    wall0 = time.monotonic()
    bringup = bringups.acquire(scenario, rtf, options.namespace)
    session = bringup.session  # shared by the runs on this bring-up
    run_ = ScenarioRun(scenario, session, options, folder, stream, parameters=bringup.parameters, clients=bringup.clients)
    reset_wall = time.monotonic() - wall0  # resetting a reused bring-up is part of the run's start-up
    try:
        result = run_.execute()
    finally:
        run_.close()
    result.startup_time += reset_wall
    result.report["startup_wall_s"] = round(result.startup_time, 3)
    bringup.runs += 1
    bringup.trusted = not result.failures  # a run that ended in an error may leave what a reset does not mend
    if bringup.trusted:
        try:  # through the bring-up's session, which has found the nodes this run changed
            bringup.parameters.restore(session)
        except (StepFailure, WaitTimeout) as error:
            bringup.trusted = False
            stream.write(f"the parameters this run changed could not be set back ({error}): the next run "
                         "starts a bring-up of its own\n")
    log = bringup.copy_log(folder)
    if not bringup.process.alive():
        result.failures.append(f"bringup exited early with code {bringup.process.process.returncode}; see {log}")
        result.passed = False
        result.report["passed"] = False
        result.report["failures"] = result.failures
    _write_artifacts(run_, result, stream)
    return result


def run_order(scenarios: Sequence[Scenario], options: RunOptions = DEFAULT_OPTIONS) -> list[int]:
    """The order to run ``scenarios`` in (indices): those of one robot and pace together (one bring-up), within
    them those of one scene together (one world loaded), each in the order of its first scenario, each scene's
    in the order given. Every run starts from a reset, so the order changes no report; ``A B C`` with A and C
    on the open floor and B on the course brings the G1 up once and loads the course once. Against running
    nodes (``launch`` False) the order is the one given."""
    if not options.launch:
        return list(range(len(scenarios)))
    groups: dict[tuple[str, float], dict[str, list[int]]] = {}
    for index, scenario in enumerate(scenarios):
        rtf = scenario.rtf if options.rtf is None else options.rtf
        groups.setdefault((scenario.robot, rtf), {}).setdefault(scenario.scene, []).append(index)
    return [index for scenes in groups.values() for group in scenes.values() for index in group]


def run_all(scenarios: Sequence[Scenario], options: RunOptions = DEFAULT_OPTIONS,
            stream: TextIO = sys.stdout) -> tuple[list[RunResult], int]:
    """Run scenarios, those of the same robot and pace one after another on one bring-up (:func:`run_order`).

    Returns:
        each run's result, in the order of ``scenarios``, and how many bring-ups were started.
    """
    order = run_order(scenarios, options)
    if order != sorted(order) and not options.quiet:
        stream.write(f"running {len(scenarios)} scenarios grouped by robot and scene, one bring-up per robot: "
                     f"{' '.join(scenarios[i].name for i in order)}\n")
    results: dict[int, RunResult] = {}
    with Bringups(stream, quiet=options.quiet) as bringups:
        for index in order:
            results[index] = run(scenarios[index], options, stream, bringups)
        return [results[index] for index in range(len(scenarios))], bringups.started


def _write_artifacts(run_: ScenarioRun, result: RunResult, stream: TextIO) -> None:
    folder = result.folder
    paths: dict[str, str | list[str]] = {}  # artifact kind -> path; "plots" -> a list of paths
    if run_.mcap is not None:
        try:
            recorded = run_.mcap.close()
            paths["mcap"] = str(run_.mcap.path)
            result.report["mcap_topics"] = dict(sorted(recorded.counts.items()))
        except RecordingError as error:
            result.report.setdefault("artifact_errors", []).append(f"mcap: {error}")
    start, end = run_.marks.get("start", 0.0), run_.marks.get("end", 0.0)
    if run_.options.plots:
        from sim_client.scenario.outputs import plots

        try:
            plot_paths = [str(plot) for plot in plots.make_plots(run_, folder)]
            if plot_paths:
                paths["plots"] = plot_paths
        except Exception as error:  # noqa: BLE001 - an artifact failing must not hide the verdicts
            result.report.setdefault("artifact_errors", []).append(f"plots: {type(error).__name__}: {error}")
    if run_.camera_images is not None and end > start:
        try:
            from sim_client.scenario.outputs import camera_sheet

            sheet = camera_sheet.make_sheet(run_.camera_images.messages(), start, end, folder / "camera.png",
                                            f"{run_.scenario.name}: /{run_.camera_name}/image_raw")
            if sheet is not None:
                paths["camera"] = str(sheet)
        except Exception as error:  # noqa: BLE001 - an artifact failing must not hide the verdicts
            result.report.setdefault("artifact_errors", []).append(f"camera: {type(error).__name__}: {error}")
    if run_.options.video and end > start:
        try:
            from sim_client.scenario.outputs import render

            render.render_video(render.recorded_run(run_), folder / "video.mp4")
            paths["video"] = str(folder / "video.mp4")
        except Exception as error:  # noqa: BLE001 - an artifact failing must not hide the verdicts
            (folder / "video.mp4").unlink(missing_ok=True)  # never leave a broken file that looks like a video
            result.report.setdefault("artifact_errors", []).append(f"video: {type(error).__name__}: {error}")
    paths["report"] = str(folder / "report.json")
    result.report["artifacts"] = paths
    problems = result.report.get("artifact_errors", [])
    if problems:  # an artifact that was asked for and not made fails the run, saying which and why
        result.failures.extend(f"asked-for artifact not made: {problem}" for problem in problems)
        result.passed = False
        result.report.update(passed=False, failures=result.failures)
    write_json(folder / "report.json", result.report)
    if not run_.options.quiet:
        verdict = "PASSED" if result.passed else "FAILED"
        ratio = f"{result.wall_time / result.sim_time:.2f}" if result.sim_time > 0 else "n/a"
        stream.write(f"\n{result.scenario}: {verdict}  ({sum(v.passed for v in result.verdicts)}/{len(result.verdicts)} "
                     f"expectations; start-up {result.startup_time:.1f} s, then wall {result.wall_time:.1f} s for sim "
                     f"{result.sim_time:.1f} s: wall/sim {ratio})\n")
        for kind, written in paths.items():
            stream.write(f"  {kind}: {written}\n")
        for problem in result.report.get("artifact_errors", []):
            stream.write(f"  artifact error: {problem}\n")
        stream.flush()
