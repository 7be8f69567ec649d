"""The judgement of a run: a verdict per expectation, the run's result, and ``report.json``."""

from __future__ import annotations

import datetime
import json
import math
import pathlib
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import numpy as np

from sim_client.actions import FeedbackSample, GoalHandle
from sim_client.scenario.model.conditions import Comparison
from sim_client.scenario.model.measures import Recorded
from sim_client.scenario.model.schema import Expectation, Scenario


class ReportedRun(Protocol):
    """What a report reads of a finished run (:class:`~sim_client.scenario.running.scenario_run.ScenarioRun`)."""

    scenario: Scenario
    rtf: float
    lock_step: bool
    goals: dict[str, GoalHandle]
    goal_actions: dict[str, str]
    marks: dict[str, float]  # sim time [s] of each mark
    param_events: list[dict[str, Any]]
    warnings: list[str]


@dataclass(frozen=True)
class Verdict:
    """The judgement of one expectation."""

    name: str
    passed: bool
    expected: str
    measured: Any
    unit: str = ""
    detail: str = ""
    line: int = 0

    def line_text(self) -> str:
        value = _fmt(self.measured)
        unit = f" {self.unit}" if self.unit and isinstance(self.measured, (int, float)) else ""
        tail = f" ({self.detail})" if self.detail else ""
        return f"{'PASS' if self.passed else 'FAIL'}  {self.name}: measured {value}{unit}, expected {self.expected}{tail}"


@dataclass
class RunResult:
    scenario: str
    passed: bool
    verdicts: list[Verdict]
    failures: list[str]
    wall_time: float  # [s] from the start mark (nodes up, keyframe restored) to the end; excludes startup
    sim_time: float  # [s] of sim time over the same span
    folder: pathlib.Path
    report: dict[str, Any] = field(default_factory=dict)
    startup_time: float = 0.0  # [s] wall time to find the nodes ready and reset (process start-up, discovery)
    # Every goal's feedback as this client received it, in order (the report keeps its count and the last one).
    feedback: dict[str, list[FeedbackSample]] = field(default_factory=dict)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def judge(recorded: Recorded, expectation: Expectation) -> Verdict:
    """The verdict on one expectation, from what the run recorded (its goals' outcomes, its measures)."""
    if expectation.outcome_goal is not None:
        handle = recorded.goal_handle(expectation.outcome_goal)
        outcome = handle.outcome() if handle is not None else None
        parts = [p for p in (expectation.outcome_status, expectation.outcome_error) if p]
        expected = " / ".join(parts)
        if outcome is None:
            measured = "not sent" if handle is None else "still running"
            return Verdict(expectation.name, False, expected, measured, line=expectation.line)
        ok = ((expectation.outcome_status is None or outcome.status == expectation.outcome_status)
              and (expectation.outcome_error is None or outcome.error_name == expectation.outcome_error))
        measured = f"{outcome.status} / {outcome.error_name}"
        return Verdict(expectation.name, ok, expected, measured, detail=outcome.error_msg, line=expectation.line)
    if expectation.measure is None or expectation.comparison is None:
        raise ValueError(f"expectation {expectation.name!r} has neither an outcome nor a measure")  # the schema forbids it
    try:
        value = expectation.measure.evaluate(recorded)
        detail = ""
    except KeyError as error:
        value, detail = None, str(error).strip("'\"")
    comparison: Comparison = expectation.comparison
    ok = comparison.holds(value)
    if value is None and not detail:
        detail = "nothing was measured"
    return Verdict(expectation.name, ok, f"{expectation.measure.kind} {comparison.describe()}", value,
                   expectation.measure.unit, detail, expectation.line)


def build_report(run: ReportedRun, result: RunResult) -> dict[str, Any]:
    """The content of ``report.json`` (its ``artifacts`` filled in when they are written)."""
    goals = {}
    for goal_id, handle in run.goals.items():
        outcome = handle.outcome()
        goals[goal_id] = {
            "action": run.goal_actions[goal_id],
            "accepted": handle.accepted,
            "status": outcome.status if outcome else "RUNNING",
            "error_code": outcome.error_code if outcome else None,
            "error_name": outcome.error_name if outcome else None,
            "error_msg": outcome.error_msg if outcome else "",
            "sent_at": run.marks.get(f"{goal_id}.sent", 0.0) - run.marks.get("start", 0.0),
            "done_at": run.marks.get(f"{goal_id}.done", math.nan) - run.marks.get("start", 0.0),
            "feedback_count": len(handle.feedback_history),
            "last_feedback": msg_to_dict(handle.feedback) if handle.feedback is not None else None,
            "result": msg_to_dict(outcome.result) if outcome and outcome.result is not None else None,
        }
    start = run.marks.get("start", 0.0)
    return {
        "scenario": run.scenario.name,
        "file": str(run.scenario.path),
        "description": run.scenario.description,
        "robot": run.scenario.robot,
        "scene": run.scenario.scene,
        "seed": run.scenario.seed,
        "mode": "lock-step" if run.lock_step else "free-run",
        "real_time_factor": run.rtf,
        "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "passed": result.passed,
        "startup_wall_s": round(result.startup_time, 3),
        "wall_time_s": round(result.wall_time, 3),
        "sim_time_s": round(result.sim_time, 3),
        "started_at_sim_s": start,  # the sim time the scenario started at (the same in every run)
        "wall_per_sim": round(result.wall_time / result.sim_time, 3) if result.sim_time > 0 else None,
        "expectations": [asdict(v) for v in result.verdicts],
        "failures": result.failures,
        "warnings": run.warnings,
        "marks": {k: round(v - start, 4) for k, v in run.marks.items()},
        "goals": goals,
        "parameters": run.param_events,
        "artifacts": {},
    }


def msg_to_dict(msg: Any) -> Any:
    """A ROS message as plain JSON-able values."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {name: msg_to_dict(getattr(msg, name)) for name in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == "array" or isinstance(msg, np.ndarray):
        return [msg_to_dict(v) for v in msg]
    if isinstance(msg, float) and not math.isfinite(msg):
        return None
    if isinstance(msg, (bytes, bytearray)):
        return list(msg)
    if isinstance(msg, np.generic):
        return msg.item()
    return msg


def write_json(path: pathlib.Path, data: Any) -> None:
    path.write_text(json.dumps(data, indent=2, default=_json_default) + "\n")


def _json_default(value: Any) -> Any:
    if isinstance(value, (np.generic,)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, pathlib.Path):
        return str(value)
    if isinstance(value, tuple):
        return list(value)
    return str(value)
