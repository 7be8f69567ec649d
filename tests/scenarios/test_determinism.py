"""Same scenario, same numbers: lock-stepped runs with the action servers in the loop are repeatable.

Each scenario runs twice, each time with its own freshly started nodes, as fast as possible (and a third
run of walk_2m paced at real-time factor 2 gives the numbers of the first, as fast as possible: the same numbers
at any pace); a short one runs twice on one bring-up after a run that changed parameters and left a goal
running, as on fresh nodes; and the course, run after the open scene on one bring-up, as on fresh nodes (its first
fresh run). A run on fresh nodes is made once for the module (:func:`fresh_runs`) and compared wherever needed.
Every number of the two reports (the goals' results, the sim times at which they were sent, the measured values of the
expectations) must agree to 1e-6, and so must every feedback message both runs received for the same
instant of the goal (its ``elapsed``). Not compared: the sim time at which the runner *saw* a goal end,
which is quantized by its stepping (the goal's own end, in its result, is compared); and how many
feedback messages arrived. That count is delivery, not physics: feedback and the result travel on
different DDS readers, and rclpy drops feedback that arrives after the result (a free-running sim sent
two fresh clones' runs 85 and 86 messages of identical content); so at least 90% of either run's
feedback must be matched in the other.
"""

from __future__ import annotations

import io
import math
import pathlib
import textwrap
from collections.abc import Callable
from typing import Any

import pytest

from sim_client.scenario.model import schema
from sim_client.scenario.running.bringups import Bringups
from sim_client.scenario.running.options import RunOptions
from sim_client.scenario.running.report import msg_to_dict
from sim_client.scenario.running.runner import run

TOLERANCE = 1e-6


def _numbers(value: Any, path: str = "") -> dict[str, float]:
    """Every number in a nested report, keyed by its path."""
    found: dict[str, float] = {}
    if isinstance(value, bool):
        return found
    if isinstance(value, (int, float)):
        found[path] = float(value)
    elif isinstance(value, dict):
        for key, item in value.items():
            found.update(_numbers(item, f"{path}.{key}"))
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            found.update(_numbers(item, f"{path}[{index}]"))
    return found


def _outcome_numbers(report: dict[str, Any]) -> dict[str, float]:
    goals = {goal_id: {k: v for k, v in goal.items() if k in ("result", "sent_at", "error_code")}
             for goal_id, goal in report["goals"].items()}
    measured = {e["name"]: e["measured"] for e in report["expectations"]}
    return _numbers({"goals": goals, "measured": measured})


def _feedback_by_instant(samples: list[Any]) -> dict[tuple[int, int, int], dict[str, float]]:
    """A goal's feedback keyed by the goal's own time in it (``elapsed``, or Nav2's ``navigation_time``) [s, ns]."""
    keyed: dict[tuple[int, int, int], dict[str, float]] = {}
    for sample in samples:
        content = msg_to_dict(sample.feedback)
        instant = content.get("elapsed", content.get("navigation_time"))
        assert instant is not None, content
        repeat = 0
        while (instant["sec"], instant["nanosec"], repeat) in keyed:  # two messages of one instant (a milestone)
            repeat += 1
        keyed[(instant["sec"], instant["nanosec"], repeat)] = _numbers(content)
    return keyed


def _feedback_differences(first: dict[str, list[Any]], second: dict[str, list[Any]]) -> list[str]:
    assert first.keys() == second.keys()
    problems = []
    for goal_id in first:
        one, other = _feedback_by_instant(first[goal_id]), _feedback_by_instant(second[goal_id])
        common = one.keys() & other.keys()
        if len(common) < 0.9 * max(len(one), len(other)):
            problems.append(f"{goal_id}: only {len(common)} feedback instants in common of {len(one)} and {len(other)}")
        for instant in sorted(common):
            differ = {key: (value, other[instant].get(key)) for key, value in one[instant].items()
                      if not (math.isnan(value) and math.isnan(other[instant].get(key, math.nan)))
                      and abs(value - other[instant].get(key, math.inf)) > TOLERANCE}
            if differ:
                problems.append(f"{goal_id} feedback at {instant}: {differ}")
    return problems


FreshRun = Callable[[str, float, int], Any]


@pytest.fixture(scope="module")
def fresh_runs(tmp_path_factory: pytest.TempPathFactory) -> FreshRun:
    """``fresh_runs(name, rtf, attempt)``: the result of a passing run of a shipped scenario on freshly started nodes,
    made the first time a test of this module asks for that (scenario, pace, attempt)."""
    made: dict[tuple[str, float, int], Any] = {}

    def fresh(name: str, rtf: float, attempt: int) -> Any:
        key = (name, rtf, attempt)
        if key not in made:
            options = RunOptions(out=tmp_path_factory.mktemp(f"{name}-{rtf:g}-{attempt}"), quiet=True, rtf=rtf)
            result: Any = run(schema.load(schema.find(name)), options, stream=io.StringIO())
            assert result.passed, result.report
            made[key] = result
        return made[key]

    return fresh


@pytest.mark.slow
@pytest.mark.parametrize(("name", "second_rtf"), [("walk_2m", 0.0), ("navigate_around_obstacle", 0.0),
                                                 ("pick_place_box", 0.0), ("walk_2m", 2.0)])
def test_a_scenario_run_twice_gives_the_same_numbers(fresh_runs: FreshRun, name: str, second_rtf: float) -> None:
    """The first run as fast as possible, the second on new nodes as fast as possible or paced (a third run)."""
    results = [fresh_runs(name, 0.0, 0), fresh_runs(name, second_rtf, 1)]
    reports, feedback = [result.report for result in results], [result.feedback for result in results]
    # The scenario starts at the same sim time, however long the recordings took to be matched (on a
    # loaded machine that once shifted the start, and the publication grid under the run, by 30 ms).
    assert reports[0]["started_at_sim_s"] == reports[1]["started_at_sim_s"]
    first, second = (_outcome_numbers(report) for report in reports)
    assert first.keys() == second.keys()
    assert len(first) >= 5, first  # the comparison has something to compare
    differ = {key: (first[key], second[key]) for key in first
              if not (math.isnan(first[key]) and math.isnan(second[key])) and abs(first[key] - second[key]) > TOLERANCE}
    assert not differ, f"{name} differs between two runs: {differ}"
    assert sum(len(samples) for samples in feedback[0].values()) >= 5, feedback[0]  # the goals gave feedback
    problems = _feedback_differences(*feedback)
    assert not problems, f"{name}'s feedback differs between two runs: {problems}"


# A short walk at the default pace (walking_speed), judged on /odom (its publication grid) and the parameter.
WALK_AT_DEFAULT_PACE = """\
name: walk_at_default_pace
robot: g1
steps:
  - send_goal: {id: walk, action: walk, goal: {distance: 0.6}, timeout: 20}
  - wait: {duration: 0.3}
expect:
  - name: the walk succeeds
    outcome: {goal: walk, status: SUCCEEDED}
  - name: walked 0.6 m
    measure: {base_displacement: {from: walk.sent, to: walk.done}}
    near: 0.6
    tol: 0.05
  - name: at the default pace
    measure: {mean_speed: {from: walk.sent, to: walk.done}}
    gt: 0.0
  - name: walking_speed at its default
    measure: {parameter: {node: locomotion, name: walking_speed}}
    near: 0.3
    tol: 0.000001
"""

# What a previous run leaves behind: a faster pace, another /odom grid, the robot moved, a goal still running.
LEAVE_A_MESS = """\
name: leave_a_mess
robot: g1
steps:
  - set_param: {node: locomotion, name: walking_speed, value: 0.5}
  - set_param: {node: sim, name: odom_rate, value: 47.0}
  - send_goal: {id: walk, action: walk, goal: {distance: 3.0}, wait: false, timeout: 20}
  - wait: {duration: 1.3}
expect:
  - name: the walk is under way
    measure: {feedback: {goal: walk, field: distance_walked}}
    gt: 0.05
"""


def _report_without_wall_times(report: dict[str, Any]) -> dict[str, Any]:
    """A report without what may differ between identical runs: wall times and stamps, artifact paths, the
    sim time at which the runner saw a goal end (quantized by its stepping; the goal's own end is in its result),
    and how much feedback arrived (delivery; the feedback itself is compared by its instants)."""
    kept = {key: value for key, value in report.items()
            if key not in ("started", "startup_wall_s", "wall_time_s", "wall_per_sim", "artifacts", "warnings")}
    kept["marks"] = {name: t for name, t in report["marks"].items() if not name.endswith(".done")}
    skipped = ("done_at", "feedback_count", "last_feedback")
    kept["goals"] = {goal_id: {k: v for k, v in goal.items() if k not in skipped} for goal_id, goal in report["goals"].items()}
    return kept


@pytest.mark.slow
def test_runs_on_one_bringup_give_the_report_of_a_run_on_fresh_nodes(tmp_path: pathlib.Path) -> None:
    def scenario(text: str, name: str) -> schema.Scenario:
        path = tmp_path / f"{name}.yaml"
        path.write_text(textwrap.dedent(text))
        return schema.load(path)

    walk, mess = scenario(WALK_AT_DEFAULT_PACE, "walk_at_default_pace"), scenario(LEAVE_A_MESS, "leave_a_mess")
    options = RunOptions(out=tmp_path / "runs", quiet=True)
    fresh: Any = run(walk, options, stream=io.StringIO())
    with Bringups(io.StringIO(), quiet=True) as bringups:
        shared: list[Any] = [run(s, options, io.StringIO(), bringups) for s in (mess, walk, walk)]
        assert bringups.started == 1, "consecutive runs of one robot and scene share one bring-up"
    assert all(result.passed for result in (fresh, *shared)), [r.report for r in (fresh, *shared) if not r.passed]
    assert shared[0].report["parameters"][0]["accepted"] and shared[0].report["parameters"][1]["accepted"]
    reports = [fresh.report, shared[1].report, shared[2].report]
    assert reports[0]["started_at_sim_s"] == reports[1]["started_at_sim_s"] == reports[2]["started_at_sim_s"]
    numbers = [_outcome_numbers(report) for report in reports]
    assert len(numbers[0]) >= 5, numbers[0]
    for other, label in ((numbers[1], "the first run on a reused bring-up"), (numbers[2], "the second one")):
        assert other.keys() == numbers[0].keys()
        differ = {key: (numbers[0][key], other[key]) for key in other if abs(numbers[0][key] - other[key]) > TOLERANCE}
        assert not differ, f"{label} differs from the run on fresh nodes: {differ}"
    for result in shared[1:]:
        problems = _feedback_differences(fresh.feedback, result.feedback)
        assert not problems, f"a run on a reused bring-up has other feedback than on fresh nodes: {problems}"
    whole = [_report_without_wall_times(report) for report in reports]
    assert whole[1] == whole[0] and whole[2] == whole[0]


@pytest.mark.slow
def test_a_run_after_the_world_was_replaced_gives_the_report_of_a_run_on_fresh_nodes(
        tmp_path: pathlib.Path, fresh_runs: FreshRun) -> None:
    """A run in the course on a bring-up that ran in the open scene (and left a mess there: a faster pace,
    another /odom grid, the robot moved, a goal still running) loads the course into the running nodes
    (/sim/load_world) and gives the report and feedback of a course run on fresh nodes."""
    mess_path = tmp_path / "leave_a_mess.yaml"
    mess_path.write_text(textwrap.dedent(LEAVE_A_MESS))
    mess, course = schema.load(mess_path), schema.load(schema.find("navigate_around_obstacle"))
    assert (mess.robot, mess.scene) == ("g1", "open") and (course.robot, course.scene) == ("g1", "course")
    options = RunOptions(out=tmp_path / "runs", quiet=True)
    assert course.rtf == 0.0  # the pace of the fresh run it is compared with
    fresh = fresh_runs(course.name, 0.0, 0)
    said = io.StringIO()  # what the bring-ups say: why a new one was started, if one was
    with Bringups(said) as bringups:
        shared: list[Any] = [run(s, options, io.StringIO(), bringups) for s in (mess, course)]
        assert bringups.started == 1, ("a run in another scene of the same robot loads that scene into the running "
                                       f"nodes; the bring-ups said:\n{said.getvalue()}")
    assert all(result.passed for result in (fresh, *shared)), [r.report for r in (fresh, *shared) if not r.passed]
    after = shared[1]
    assert after.report["started_at_sim_s"] == fresh.report["started_at_sim_s"]
    numbers, other = _outcome_numbers(fresh.report), _outcome_numbers(after.report)
    assert len(numbers) >= 5 and other.keys() == numbers.keys(), (numbers, other)
    differ = {key: (numbers[key], other[key]) for key in other if abs(numbers[key] - other[key]) > TOLERANCE}
    assert not differ, f"the course run after the open one differs from the run on fresh nodes: {differ}"
    problems = _feedback_differences(fresh.feedback, after.feedback)
    assert not problems, f"the course run after the open one has other feedback than on fresh nodes: {problems}"
    assert _report_without_wall_times(after.report) == _report_without_wall_times(fresh.report)
