"""Scenario files: a typed, validated model loaded from YAML, with errors as ``file:line: what``.

A scenario is data (no code): the robot, the scene, a seed, an initial keyframe, a list of
steps and a list of expectations. See ``scenarios/README.md`` for the format; in short::

    name: walk_2m
    robot: g1
    steps:
      - send_goal: {id: walk, action: walk, goal: {distance: 2.0, speed: 0.3}}
    expect:
      - name: the walk succeeds
        outcome: {goal: walk, status: SUCCEEDED, error_code: SUCCESS}
      - name: walked 2 m
        measure: {base_displacement: {from: walk.sent}}
        near: 2.0
        rel_tol: 0.05

The kinds of steps, measures and actions are defined in :mod:`.steps`, :mod:`.measures` and :mod:`.actions`;
this module reads the file, builds the scenario and checks what refers to what (marks, goal ids,
objects). Robot facts come from ``robot_models``. Times are sim seconds; lengths metres; angles
radians.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass
from typing import Any

import robot_models
from sim_client.scenario.model.actions import ACTIONS, ERROR_NAMES_ANY, STATUS_NAMES
from sim_client.scenario.model.conditions import Comparison, Condition, parse_comparison
from sim_client.scenario.model.fields import Ctx, Fields, LineList, ScenarioError, item_line, kind_of
from sim_client.scenario.model.measures import MEASURES, Measure, parse_measure
from sim_client.scenario.model.robots import robot_facts, scene_problem
from sim_client.scenario.model.steps import SendGoalStep, Step, parse_step

__all__ = ["Expectation", "Scenario", "ScenarioError", "all_files", "find", "load", "parse"]


@dataclass(frozen=True)
class Expectation:
    """A named check: a measure compared with a value, or a goal's outcome."""

    name: str
    line: int
    measure: Measure | None = None
    comparison: Comparison | None = None
    outcome_goal: str | None = None
    outcome_status: str | None = None
    outcome_error: str | None = None

    def describe(self) -> str:
        if self.measure is not None and self.comparison is not None:
            return f"{self.measure.describe()} {self.comparison.describe()}"
        parts = [p for p in (self.outcome_status, self.outcome_error) if p]
        return f"outcome of {self.outcome_goal} is {' / '.join(parts)}"


@dataclass(frozen=True)
class Scenario:
    """A validated scenario file."""

    name: str
    path: pathlib.Path
    description: str
    robot: str
    scene: str
    seed: int
    keyframe: str
    rtf: float
    timeout: float
    wall_timeout: float
    tags: tuple[str, ...]
    steps: tuple[Step, ...]
    expectations: tuple[Expectation, ...]

    @property
    def actions(self) -> tuple[str, ...]:
        """Actions the scenario sends goals to (its servers must be up)."""
        return tuple(sorted({s.action for s in self.steps if isinstance(s, SendGoalStep)}))


def _parse_expectation(ctx: Ctx, raw: Any, line: int, index: int) -> Expectation:
    f = Fields(ctx, raw, f"expectation {index + 1}", line)
    name = f.required_string("name")
    what = f"expectation {name!r}"
    f.what = what
    if f.has("outcome"):
        o = Fields(ctx, f.raw("outcome"), f"{what}: outcome", f.at("outcome"))
        goal = o.required_string("goal")
        status = o.optional_string("status", choices=STATUS_NAMES)
        error = o.optional_string("error_code", choices=ERROR_NAMES_ANY)
        o.done()
        f.done()
        if status is None and error is None:
            raise ctx.error(o.line, f"{what}: outcome needs status and/or error_code")
        return Expectation(name, f.line, outcome_goal=goal, outcome_status=status, outcome_error=error)
    if not f.has("measure"):
        raise ctx.error(f.line, f"{what}: give either 'outcome' or 'measure' with a comparison")
    measure = parse_measure(ctx, f.raw("measure"), f.at("measure"))
    comparison = parse_comparison(f)
    f.done()
    return Expectation(name, f.line, measure=measure, comparison=comparison)


# ----- cross checks -------------------------------------------------------------------------
def _check_references(ctx: Ctx, scenario: Scenario) -> None:
    marks = {"start", "end"}
    goals: dict[str, str] = {}
    conditions: list[Condition] = []
    for step in scenario.steps:
        if step.mark:
            if step.mark in marks:
                raise ctx.error(step.line, f"mark {step.mark!r} is defined twice")
            marks.add(step.mark)
        sent, used = step.goal_sent(), step.goal_used()
        if sent is not None:
            goal_id, sent_action = sent
            if goal_id in goals:
                raise ctx.error(step.line, f"goal id {goal_id!r} is used twice")
            goals[goal_id] = sent_action
            marks.update({f"{goal_id}.sent", f"{goal_id}.done"})
        if used and used not in goals:
            raise ctx.error(step.line, f"goal {used!r} is not sent by an earlier step; known: {', '.join(goals) or 'none'}")
        conditions.extend(step.conditions())
    measures = [(c.measure, c.line) for c in conditions]
    measures += [(e.measure, e.line) for e in scenario.expectations if e.measure is not None]
    for expectation in scenario.expectations:
        if expectation.outcome_goal is not None:
            action = goals.get(expectation.outcome_goal)
            if action is None:
                raise ctx.error(expectation.line, f"expectation {expectation.name!r}: unknown goal {expectation.outcome_goal!r}; "
                                f"known: {', '.join(goals) or 'none'}")
            allowed = (*ACTIONS[action].error_names, "REJECTED")
            if expectation.outcome_error and expectation.outcome_error not in allowed:
                raise ctx.error(expectation.line, f"expectation {expectation.name!r}: {action} has no error code "
                                f"{expectation.outcome_error!r}; it has: {', '.join(allowed)}")
    robot = robot_facts(scenario.robot, scenario.scene)
    for measure, line in measures:
        kind = MEASURES[measure.kind]
        at = measure.line or line
        for role in ("mark", "goal", "object"):
            for key in kind.keys:
                value = measure.args.get(key.name)
                if key.role != role or value is None:
                    continue
                if role == "mark" and value not in marks:
                    raise ctx.error(at, f"measure {measure.kind}: unknown mark {value!r}; marks: {', '.join(sorted(marks))}")
                if role == "goal" and value not in goals:
                    raise ctx.error(at, f"measure {measure.kind}: unknown goal {value!r}; known: {', '.join(goals) or 'none'}")
                if role == "object" and value not in robot.objects:
                    raise ctx.error(at, f"measure {measure.kind}: robot {robot.name} has no object {value!r}; "
                                    f"objects: {', '.join(robot.objects) or 'none'}")
        if kind.walking and not robot.walks:
            raise ctx.error(at, f"measure {measure.kind} needs a walking robot; {robot.name} has a fixed base")


# ----- entry points -------------------------------------------------------------------------
def parse(text: str, file: str = "<scenario>") -> Scenario:
    """Validate scenario ``text``; errors name ``file`` and the line."""
    ctx = Ctx(file)
    f = Fields(ctx, ctx.load_yaml(text), "scenario", 1)
    name = f.string("name", pathlib.Path(file).stem)
    description = f.string("description", "")
    robot = robot_facts(f.required_string("robot", choices=robot_models.ROBOT_NAMES))
    scene = f.string("scene", robot.default_scene)
    problem = scene_problem(robot.name, scene)
    if problem is not None:
        raise ctx.error(f.at("scene"), f"scenario: {problem}")
    robot = robot_facts(robot.name, scene)  # the scene's objects
    seed = f.integer("seed", 0)
    keyframe = f.string("keyframe", robot.keyframes[0], choices=robot.keyframes)
    rtf = f.number("rtf", 0.0, low=0.0, high=1000.0)
    timeout = f.number("timeout", 300.0, low=0.0, unit=" [s of sim time]")
    wall_timeout = f.number("wall_timeout", 600.0, low=1.0, unit=" [s]")
    tags_raw = f.raw("tags", [])
    if not isinstance(tags_raw, list) or not all(isinstance(t, str) for t in tags_raw):
        raise ctx.error(f.at("tags"), f"scenario: tags must be a list of strings, got {tags_raw!r}")
    steps_raw = f.raw("steps", LineList())
    if not isinstance(steps_raw, list):
        raise ctx.error(f.at("steps"), f"scenario: steps must be a list, got {kind_of(steps_raw)}")
    steps = tuple(parse_step(ctx, s, item_line(steps_raw, i), robot, i) for i, s in enumerate(steps_raw))
    expect_raw = f.raw("expect", LineList())
    if not isinstance(expect_raw, list) or not expect_raw:
        line = f.at("expect") if f.has("expect") else f.line
        raise ctx.error(line, "scenario: expect must be a non-empty list of expectations")
    expectations = tuple(_parse_expectation(ctx, e, item_line(expect_raw, i), i) for i, e in enumerate(expect_raw))
    names = [e.name for e in expectations]
    for i, e in enumerate(expectations):
        if e.name in names[:i]:
            raise ctx.error(e.line, f"expectation name {e.name!r} is used twice")
    f.done()
    scenario = Scenario(name, pathlib.Path(file), description, robot.name, scene, seed, keyframe, rtf, timeout, wall_timeout,
                        tuple(tags_raw), steps, expectations)
    _check_references(ctx, scenario)
    return scenario


def load(path: str | pathlib.Path) -> Scenario:
    """Read and validate a scenario file."""
    path = pathlib.Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise ScenarioError(f"{path}:0: cannot read: {error.strerror}") from None
    return parse(text, str(path))


SCENARIO_DIR = pathlib.Path(__file__).resolve().parents[3] / "scenarios"


def find(name_or_path: str, directory: pathlib.Path = SCENARIO_DIR) -> pathlib.Path:
    """A scenario file by path, or by name in ``scenarios/``."""
    path = pathlib.Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.exists():
            raise ScenarioError(f"{path}:0: no such file")
        return path
    candidate = directory / f"{name_or_path}.yaml"
    if candidate.exists():
        return candidate
    known = ", ".join(p.stem for p in sorted(directory.glob("*.yaml")))
    raise ScenarioError(f"{name_or_path}:0: no scenario of that name in {directory}; known: {known}")


def all_files(directory: pathlib.Path = SCENARIO_DIR) -> list[pathlib.Path]:
    """The scenario files in ``directory``, sorted."""
    return sorted(directory.glob("*.yaml"))
