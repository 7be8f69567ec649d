"""Same scenario, same numbers: lock-stepped runs with the action servers in the loop are repeatable.

Each scenario runs twice, each time with its own freshly started nodes, as fast as possible (and one
paced at real-time factor 2: the same numbers at any pace). Every number of the two
reports (the goals' results and last feedback, the sim times at which they were sent, the measured
values of the expectations) must agree to 1e-6. Not compared: the sim time at which the runner *saw*
a goal end, which is quantized by its stepping (the goal's own end, in its result, is compared).
"""

from __future__ import annotations

import io
import math
import pathlib
from typing import Any

import pytest

from sim_client.scenario.model import schema
from sim_client.scenario.running.options import RunOptions
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
    goals = {goal_id: {k: v for k, v in goal.items() if k in ("result", "last_feedback", "sent_at",
                                                               "feedback_count", "error_code")}
             for goal_id, goal in report["goals"].items()}
    measured = {e["name"]: e["measured"] for e in report["expectations"]}
    return _numbers({"goals": goals, "measured": measured})


@pytest.mark.slow
@pytest.mark.parametrize(("name", "rtf"), [("walk_2m", 0.0), ("navigate_around_obstacle", 0.0), ("pick_place_box", 0.0),
                                          ("walk_2m", 2.0)])
def test_a_scenario_run_twice_gives_the_same_numbers(tmp_path: pathlib.Path, name: str, rtf: float) -> None:
    reports = []
    for attempt in range(2):
        options = RunOptions(out=tmp_path / str(attempt), quiet=True, rtf=rtf)
        result: Any = run(schema.load(schema.find(name)), options, stream=io.StringIO())
        assert result.passed, result.report
        reports.append(result.report)
    # The scenario starts at the same sim time, however long the recordings took to be matched (on a
    # loaded machine that once shifted the start, and the publication grid under the run, by 30 ms).
    assert reports[0]["started_at_sim_s"] == reports[1]["started_at_sim_s"]
    first, second = (_outcome_numbers(report) for report in reports)
    assert first.keys() == second.keys()
    assert len(first) >= 5, first  # the comparison has something to compare
    differ = {key: (first[key], second[key]) for key in first
              if not (math.isnan(first[key]) and math.isnan(second[key])) and abs(first[key] - second[key]) > TOLERANCE}
    assert not differ, f"{name} differs between two runs: {differ}"
