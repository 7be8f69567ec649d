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

Times are sim seconds; lengths metres; angles radians.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass, field
from typing import Any

import yaml

ROBOTS: dict[str, dict[str, Any]] = {
    # keyframes and object names are those of robot_models (kept here so validating a file
    # does not compile a model); tests check they agree.
    "g1": {"keyframes": ("stand",), "scenes": ("open", "course"), "actions": ("walk", "navigate", "move_arm"), "objects": (),
           "arms": ("left_arm", "right_arm")},
    "panda": {"keyframes": ("home",), "scenes": ("table",), "actions": ("move_arm", "pick_place"), "objects": ("box_0", "box_1", "box_2"),
              "arms": ("arm",)},
}
ACTION_SERVERS = {"walk": "/walk", "navigate": "/navigate_to_pose", "move_arm": "/move_arm", "pick_place": "/pick_place"}
STATUS_NAMES = ("SUCCEEDED", "ABORTED", "CANCELED", "REJECTED")
ERROR_NAMES = {
    "walk": ("SUCCESS", "INVALID_GOAL", "FELL", "TIMEOUT", "PREEMPTED", "CANCELED", "SIM_FAULT"),
    "navigate": ("SUCCESS", "INVALID_GOAL", "FELL", "TIMEOUT", "PREEMPTED", "CANCELED", "SIM_FAULT", "NO_VALID_PATH",
                 "GOAL_IN_OBSTACLE"),
    "move_arm": ("SUCCESS", "INVALID_GOAL", "UNREACHABLE", "TIMEOUT", "PREEMPTED", "CANCELED", "SIM_FAULT"),
    "pick_place": ("SUCCESS", "INVALID_GOAL", "UNREACHABLE", "TIMEOUT", "PREEMPTED", "CANCELED", "SIM_FAULT",
                   "GRASP_FAILED", "OBJECT_DROPPED", "PLACEMENT_FAILED"),
}
ERROR_NAMES_ANY = tuple(sorted({name for names in ERROR_NAMES.values() for name in names} | {"REJECTED"}))


class ScenarioError(ValueError):
    """A scenario file is not valid; the message starts with ``file:line:``."""


# ----- YAML with line numbers ---------------------------------------------------------------
class _Map(dict):
    line: int = 0
    key_lines: dict[Any, int]


class _List(list):
    line: int = 0
    item_lines: list[int]


class _Loader(yaml.SafeLoader):
    pass


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> _Map:
    loader.flatten_mapping(node)
    result = _Map()
    result.line = node.start_mark.line + 1
    result.key_lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in result:
            raise yaml.MarkedYAMLError(problem=f"duplicate key {key!r}", problem_mark=key_node.start_mark)
        result[key] = loader.construct_object(value_node, deep=True)
        result.key_lines[key] = key_node.start_mark.line + 1
    return result


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> _List:
    result = _List(loader.construct_object(child, deep=True) for child in node.value)
    result.line = node.start_mark.line + 1
    result.item_lines = [child.start_mark.line + 1 for child in node.value]
    return result


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


class _Ctx:
    """Where we are in the file, to prefix errors with ``file:line:``."""

    def __init__(self, file: str) -> None:
        self.file = file

    def error(self, line: int, message: str) -> ScenarioError:
        return ScenarioError(f"{self.file}:{line}: {message}")


def _line(obj: Any, default: int) -> int:
    return int(getattr(obj, "line", default) or default)


def _key_line(mapping: Any, key: str) -> int:
    lines = getattr(mapping, "key_lines", {})
    return int(lines.get(key, _line(mapping, 0)))


class _Fields:
    """Typed access to the keys of one mapping; reports unknown keys and wrong types."""

    def __init__(self, ctx: _Ctx, mapping: Any, what: str, line: int) -> None:
        self.ctx = ctx
        self.what = what
        self.line = _line(mapping, line)
        if not isinstance(mapping, dict):
            raise ctx.error(self.line, f"{what} must be a mapping (key: value), got {_kind(mapping)}")
        self.mapping = mapping
        self.used: set[str] = set()

    def at(self, key: str) -> int:
        return _key_line(self.mapping, key)

    def has(self, key: str) -> bool:
        return key in self.mapping

    def raw(self, key: str, default: Any = None) -> Any:
        self.used.add(key)
        return self.mapping.get(key, default)

    def _missing(self, key: str) -> ScenarioError:
        return self.ctx.error(self.line, f"{self.what}: missing required key {key!r}")

    def number(self, key: str, default: float | None = None, required: bool = False, low: float | None = None,
               high: float | None = None, unit: str = "") -> float | None:
        self.used.add(key)
        if key not in self.mapping:
            if required:
                raise self._missing(key)
            return default
        value = self.mapping[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
            raise self.ctx.error(self.at(key), f"{self.what}: {key} must be a number{unit}, got {value!r}")
        value = float(value)
        if low is not None and value < low:
            raise self.ctx.error(self.at(key), f"{self.what}: {key} must be >= {low}{unit}, got {value}")
        if high is not None and value > high:
            raise self.ctx.error(self.at(key), f"{self.what}: {key} must be <= {high}{unit}, got {value}")
        return value

    def integer(self, key: str, default: int) -> int:
        self.used.add(key)
        value = self.mapping.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.ctx.error(self.at(key), f"{self.what}: {key} must be an integer, got {value!r}")
        return value

    def string(self, key: str, default: str | None = None, required: bool = False,
               choices: tuple[str, ...] | None = None) -> str | None:
        self.used.add(key)
        if key not in self.mapping:
            if required:
                raise self._missing(key)
            return default
        value = self.mapping[key]
        if not isinstance(value, str):
            raise self.ctx.error(self.at(key), f"{self.what}: {key} must be a string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.ctx.error(self.at(key), f"{self.what}: {key} {value!r} is not one of: {', '.join(choices)}")
        return value

    def boolean(self, key: str, default: bool) -> bool:
        self.used.add(key)
        value = self.mapping.get(key, default)
        if not isinstance(value, bool):
            raise self.ctx.error(self.at(key), f"{self.what}: {key} must be true or false, got {value!r}")
        return value

    def vector(self, key: str, size: int, required: bool = False, unit: str = "") -> tuple[float, ...] | None:
        self.used.add(key)
        if key not in self.mapping:
            if required:
                raise self._missing(key)
            return None
        value = self.mapping[key]
        if (not isinstance(value, list) or len(value) != size
                or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value)):
            raise self.ctx.error(self.at(key), f"{self.what}: {key} must be a list of {size} numbers{unit}, got {value!r}")
        return tuple(float(v) for v in value)

    def done(self) -> None:
        unknown = [key for key in self.mapping if key not in self.used]
        if unknown:
            key = unknown[0]
            known = ", ".join(sorted(self.used))
            raise self.ctx.error(self.at(key), f"{self.what}: unknown key {key!r}; allowed: {known}")


def _kind(value: Any) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return repr(value)


# ----- the model ----------------------------------------------------------------------------
MEASURES: dict[str, tuple[str, str]] = {
    # kind: (unit, what it is)
    "base_displacement": ("m", "planar distance of the base between two marks"),
    "base_position": ("m|rad", "base x, y, z [m] or yaw [rad] at a mark"),
    "base_height_min": ("m", "lowest base height between two marks (never fell: >= 0.5 on the G1)"),
    "mean_speed": ("m/s", "planar base displacement / sim time between two marks"),
    "object_distance": ("m", "distance of an object's centre to a target point at a mark"),
    "object_position": ("m", "an object's x, y or z at a mark"),
    "joint_position": ("rad", "a joint's position at a mark"),
    "feedback": ("", "a feedback field of a goal: last, max, min or count"),
    "result": ("", "a result field of a goal (dotted path, e.g. final_pose.pose.position.x)"),
    "status": ("", "the final status of a goal (SUCCEEDED, ABORTED, CANCELED, REJECTED)"),
    "error_code": ("", "the name of a goal's result error code (SUCCESS, INVALID_GOAL, ...)"),
    "duration": ("s", "sim time between two marks"),
    "parameter": ("", "a parameter's value at the end of the run"),
}
_MEASURE_KEYS: dict[str, tuple[str, ...]] = {
    "base_displacement": ("from", "to"),
    "base_position": ("axis", "at"),
    "base_height_min": ("from", "to"),
    "mean_speed": ("from", "to"),
    "object_distance": ("object", "target", "at"),
    "object_position": ("object", "axis", "at"),
    "joint_position": ("joint", "at"),
    "feedback": ("goal", "field", "reduce"),
    "result": ("goal", "field"),
    "status": ("goal",),
    "error_code": ("goal",),
    "duration": ("from", "to"),
    "parameter": ("node", "name"),
}
COMPARISONS = ("near", "gte", "lte", "gt", "lt", "eq")


@dataclass(frozen=True)
class Measure:
    """A quantity the runner measures. ``args`` holds the validated keys of the kind."""

    kind: str
    args: dict[str, Any]
    line: int

    def describe(self) -> str:
        inner = ", ".join(f"{k}={v}" for k, v in self.args.items() if v is not None)
        return f"{self.kind}({inner})"

    @property
    def unit(self) -> str:
        unit = MEASURES[self.kind][0]
        if unit == "m|rad":
            return "rad" if self.args.get("axis") == "yaw" else "m"
        return unit


@dataclass(frozen=True)
class Comparison:
    """``op`` is one of near, gte, lte, gt, lt, eq. ``near`` uses ``tol`` or ``rel_tol``."""

    op: str
    value: Any
    tol: float | None = None
    rel_tol: float | None = None

    def allowed(self) -> float:
        if self.tol is not None:
            return self.tol
        return abs(float(self.value)) * float(self.rel_tol or 0.0)

    def holds(self, measured: Any) -> bool:
        if measured is None:
            return False
        if self.op == "eq":
            return measured == self.value
        try:
            measured = float(measured)
        except (TypeError, ValueError):
            return False
        if not math.isfinite(measured):
            return False
        if self.op == "near":
            return abs(measured - float(self.value)) <= self.allowed() + 1e-12
        return {"gte": measured >= self.value, "lte": measured <= self.value,
                "gt": measured > self.value, "lt": measured < self.value}[self.op]

    def describe(self) -> str:
        if self.op == "near":
            tol = f"±{self.tol:g}" if self.tol is not None else f"±{100 * float(self.rel_tol or 0):g}%"
            return f"{self.value:g} {tol}"
        symbol = {"gte": ">=", "lte": "<=", "gt": ">", "lt": "<", "eq": "=="}[self.op]
        return f"{symbol} {self.value}"


@dataclass(frozen=True)
class Condition:
    """A measure compared with a value, e.g. feedback distance_walked >= 1.0."""

    measure: Measure
    comparison: Comparison
    line: int

    def describe(self) -> str:
        return f"{self.measure.describe()} {self.comparison.describe()}"


@dataclass(frozen=True)
class Trigger:
    """When to act on a running goal: ``after`` sim seconds since it was sent, or ``when`` a condition holds."""

    after: float | None
    when: Condition | None
    line: int

    def describe(self) -> str:
        return f"after {self.after:g} s" if self.after is not None else f"when {self.when.describe()}"  # type: ignore[union-attr]


@dataclass(frozen=True)
class Step:
    """Base of all steps. ``mark`` names the sim time at which the step starts."""

    line: int
    mark: str | None


@dataclass(frozen=True)
class ResetStep(Step):
    keyframe: str | None = None


@dataclass(frozen=True)
class WaitStep(Step):
    """Wait ``duration`` sim seconds, or ``until`` a condition holds, or for ``goal`` to end."""

    duration: float | None = None
    until: Condition | None = None
    goal: str | None = None
    timeout: float = 60.0


@dataclass(frozen=True)
class SendGoalStep(Step):
    """Send an action goal. ``wait`` blocks until the result; ``cancel`` cancels it on a trigger."""

    id: str = ""
    action: str = ""
    goal: dict[str, Any] = field(default_factory=dict)
    wait: bool = True
    timeout: float = 120.0
    cancel: Trigger | None = None


@dataclass(frozen=True)
class CancelStep(Step):
    goal: str = ""


@dataclass(frozen=True)
class SetParamStep(Step):
    """Set a parameter; ``refused`` says the node must refuse it (a bad value)."""

    node: str = ""
    name: str = ""
    value: Any = None
    refused: bool = False


@dataclass(frozen=True)
class CmdVelStep(Step):
    """Publish /cmd_vel (base frame) for ``duration`` sim seconds, then zero."""

    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0
    duration: float = 1.0


@dataclass(frozen=True)
class PushStep(Step):
    """Push a body (/sim/push): a force and torque, world frame, for ``duration`` sim seconds.

    ``refused`` says the sim must refuse it (a bad value), as with ``set_param``.
    """

    body: str = ""
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque: tuple[float, float, float] = (0.0, 0.0, 0.0)
    duration: float = 0.1
    refused: bool = False


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

    @property
    def needs_servers(self) -> bool:
        return bool(self.actions) or any(isinstance(s, SetParamStep) and s.node.strip("/") != "sim" for s in self.steps)

    @property
    def goal_actions(self) -> dict[str, str]:
        return {s.id: s.action for s in self.steps if isinstance(s, SendGoalStep)}


# ----- goal fields per action ---------------------------------------------------------------
def _parse_goal(ctx: _Ctx, action: str, robot: str, raw: Any, line: int) -> dict[str, Any]:
    f = _Fields(ctx, raw if raw is not None else _Map(), f"goal of {action}", line)
    if action == "walk":
        goal = {"distance": f.number("distance", required=True, unit=" [m]"),
                "speed": f.number("speed", 0.0, unit=" [m/s]"), "timeout": f.number("timeout", 0.0, unit=" [s]")}
    elif action == "navigate":
        goal = {"x": f.number("x", required=True), "y": f.number("y", required=True), "yaw": f.number("yaw", 0.0),
                "frame": f.string("frame", "odom")}
    elif action == "move_arm":
        arms = ROBOTS[robot]["arms"]
        goal = {"position": f.vector("position", 3, required=True, unit=" [m]"), "rpy": f.vector("rpy", 3, unit=" [rad]"),
                "arm": f.string("arm", ""), "position_tolerance": f.number("position_tolerance", 0.005),
                "orientation_tolerance": f.number("orientation_tolerance", 0.0),
                "max_velocity_scaling": f.number("max_velocity_scaling", 0.0), "timeout": f.number("timeout", 0.0),
                "frame": f.string("frame", "world")}
        # An unknown arm is allowed on purpose (bad-goal stories), but a typo is worth a clear note.
        goal["arm_known"] = goal["arm"] in ("", *arms)
    elif action == "pick_place":
        goal = {"object": f.string("object", required=True), "place": f.vector("place", 3, required=True, unit=" [m]"),
                "arm": f.string("arm", ""), "timeout": f.number("timeout", 0.0)}
    else:  # checked by the caller
        raise ctx.error(line, f"unknown action {action!r}")
    f.done()
    return goal


# ----- measures, comparisons, conditions ----------------------------------------------------
def _parse_measure(ctx: _Ctx, raw: Any, line: int) -> Measure:
    if isinstance(raw, str):
        kind, args_raw = raw, _Map()
    elif isinstance(raw, dict) and len(raw) == 1:
        kind, args_raw = next(iter(raw.items()))
        line = _key_line(raw, kind)
        if args_raw is None:
            args_raw = _Map()
    else:
        raise ctx.error(_line(raw, line), f"measure must be a name or a mapping with one kind; kinds: {', '.join(MEASURES)}")
    if kind not in MEASURES:
        raise ctx.error(line, f"unknown measure {kind!r}; kinds: {', '.join(MEASURES)}")
    f = _Fields(ctx, args_raw, f"measure {kind}", line)
    args: dict[str, Any] = {}
    for key in _MEASURE_KEYS[kind]:
        if key in ("from", "to", "at", "goal", "field", "object", "joint", "node", "name"):
            args[key] = f.string(key)
        elif key == "axis":
            args[key] = f.string(key, "x", choices=("x", "y", "z", "yaw") if kind == "base_position" else ("x", "y", "z"))
        elif key == "reduce":
            args[key] = f.string(key, "last", choices=("last", "max", "min", "count"))
        elif key == "target":
            args[key] = f.vector(key, 3, required=True, unit=" [m]")
    f.done()
    for key in {"feedback": ("goal", "field"), "result": ("goal", "field"), "status": ("goal",), "error_code": ("goal",),
                "object_distance": ("object",), "object_position": ("object",), "joint_position": ("joint",),
                "parameter": ("node", "name")}.get(kind, ()):
        if not args.get(key):
            raise ctx.error(line, f"measure {kind}: missing required key {key!r}")
    return Measure(kind, args, line)


def _parse_comparison(ctx: _Ctx, f: _Fields, what: str) -> Comparison:
    ops = [op for op in COMPARISONS if f.has(op)]
    if len(ops) != 1:
        found = f"found {', '.join(ops)}" if ops else "found none"
        raise ctx.error(f.line, f"{what}: give exactly one comparison of {', '.join(COMPARISONS)} ({found})")
    op = ops[0]
    if op == "eq":
        value = f.raw("eq")
        return Comparison("eq", value)
    value = f.number(op, required=True)
    if op == "near":
        tol = f.number("tol", low=0.0)
        rel_tol = f.number("rel_tol", low=0.0)
        if (tol is None) == (rel_tol is None):
            raise ctx.error(f.at("near"), f"{what}: near needs exactly one of tol (absolute) or rel_tol (fraction, 0.05 = 5%)")
        return Comparison("near", value, tol, rel_tol)
    return Comparison(op, value)


def _parse_condition(ctx: _Ctx, raw: Any, line: int, what: str) -> Condition:
    f = _Fields(ctx, raw, what, line)
    if not f.has("measure"):
        raise ctx.error(f.line, f"{what}: missing required key 'measure'")
    measure = _parse_measure(ctx, f.raw("measure"), f.at("measure"))
    comparison = _parse_comparison(ctx, f, what)
    f.done()
    return Condition(measure, comparison, f.line)


def _parse_trigger(ctx: _Ctx, raw: Any, line: int, what: str) -> Trigger:
    f = _Fields(ctx, raw, what, line)
    after = f.number("after", low=0.0, unit=" [s of sim time]")
    when = _parse_condition(ctx, f.raw("when"), f.at("when"), f"{what}: when") if f.has("when") else None
    f.done()
    if (after is None) == (when is None):
        raise ctx.error(f.line, f"{what}: give exactly one of 'after' (sim seconds after the goal was sent) or 'when' (a condition)")
    return Trigger(after, when, f.line)


# ----- steps --------------------------------------------------------------------------------
STEP_KINDS = ("reset", "wait", "send_goal", "cancel", "set_param", "cmd_vel", "push")


def _parse_step(ctx: _Ctx, raw: Any, line: int, robot: str, index: int) -> Step:
    what = f"step {index + 1}"
    if not isinstance(raw, dict):
        raise ctx.error(line, f"{what} must be a mapping with one of: {', '.join(STEP_KINDS)}")
    kinds = [k for k in raw if k in STEP_KINDS]
    if len(kinds) != 1:
        other = [k for k in raw if k not in STEP_KINDS and k != "mark"]
        hint = f"unknown key {other[0]!r}; " if other else ""
        raise ctx.error(_line(raw, line), f"{what}: {hint}give exactly one of {', '.join(STEP_KINDS)} (and optionally mark)")
    kind = kinds[0]
    outer = _Fields(ctx, raw, what, line)
    mark = outer.string("mark")
    body = outer.raw(kind)
    outer.done()
    at = _key_line(raw, kind)
    what = f"{what} ({kind})"
    if kind == "reset":
        f = _Fields(ctx, body if body is not None else _Map(), what, at)
        keyframe = f.string("keyframe", choices=ROBOTS[robot]["keyframes"])
        f.done()
        return ResetStep(at, mark, keyframe)
    if kind == "wait":
        f = _Fields(ctx, body, what, at)
        duration = f.number("duration", low=0.0, unit=" [s of sim time]")
        until = _parse_condition(ctx, f.raw("until"), f.at("until"), f"{what}: until") if f.has("until") else None
        goal = f.string("goal")
        timeout = f.number("timeout", 60.0, low=0.0, unit=" [s of sim time]")
        f.done()
        if sum(x is not None for x in (duration, until, goal)) != 1:
            raise ctx.error(f.line, f"{what}: give exactly one of duration, until (a condition) or goal (a goal id)")
        return WaitStep(at, mark, duration, until, goal, float(timeout))  # type: ignore[arg-type]
    if kind == "send_goal":
        f = _Fields(ctx, body, what, at)
        action = f.string("action", required=True, choices=tuple(ACTION_SERVERS))
        assert action is not None
        if action not in ROBOTS[robot]["actions"]:
            raise ctx.error(f.at("action"), f"{what}: robot {robot} has no {action} action; it has: {', '.join(ROBOTS[robot]['actions'])}")
        goal_id = f.string("id", required=True)
        goal = _parse_goal(ctx, action, robot, f.raw("goal"), f.at("goal") if f.has("goal") else f.line)
        wait = f.boolean("wait", True)
        timeout = f.number("timeout", 120.0, low=0.0, unit=" [s of sim time]")
        cancel = _parse_trigger(ctx, f.raw("cancel"), f.at("cancel"), f"{what}: cancel") if f.has("cancel") else None
        f.done()
        return SendGoalStep(at, mark, goal_id, action, goal, wait, float(timeout), cancel)  # type: ignore[arg-type]
    if kind == "cancel":
        f = _Fields(ctx, body, what, at)
        goal_id = f.string("goal", required=True)
        f.done()
        return CancelStep(at, mark, goal_id)  # type: ignore[arg-type]
    if kind == "set_param":
        f = _Fields(ctx, body, what, at)
        node = f.string("node", required=True)
        name = f.string("name", required=True)
        if not f.has("value"):
            raise ctx.error(f.line, f"{what}: missing required key 'value'")
        value = f.raw("value")
        if isinstance(value, (dict, list)) or value is None:
            raise ctx.error(f.at("value"), f"{what}: value must be a number, string or bool, got {_kind(value)}")
        refused = f.boolean("refused", False)
        f.done()
        return SetParamStep(at, mark, node, name, value, refused)  # type: ignore[arg-type]
    if kind == "push":
        f = _Fields(ctx, body, what, at)
        step = PushStep(at, mark, f.string("body", ""), f.vector("force", 3, required=True, unit=" [N]"),  # type: ignore[arg-type]
                        f.vector("torque", 3, unit=" [N m]") or (0.0, 0.0, 0.0),
                        f.number("duration", required=True, unit=" [s of sim time]"), f.boolean("refused", False))  # type: ignore[arg-type]
        f.done()
        return step
    f = _Fields(ctx, body, what, at)  # cmd_vel
    if robot != "g1":
        raise ctx.error(at, f"{what}: /cmd_vel drives a walking robot; robot {robot} has none")
    step = CmdVelStep(at, mark, f.number("vx", 0.0, unit=" [m/s]"), f.number("vy", 0.0, unit=" [m/s]"),  # type: ignore[arg-type]
                      f.number("wz", 0.0, unit=" [rad/s]"), f.number("duration", required=True, low=0.0, unit=" [s]"))  # type: ignore[arg-type]
    f.done()
    return step


def _parse_expectation(ctx: _Ctx, raw: Any, line: int, index: int) -> Expectation:
    f = _Fields(ctx, raw, f"expectation {index + 1}", line)
    name = f.string("name", required=True)
    assert name is not None
    what = f"expectation {name!r}"
    f.what = what
    if f.has("outcome"):
        o = _Fields(ctx, f.raw("outcome"), f"{what}: outcome", f.at("outcome"))
        goal = o.string("goal", required=True)
        status = o.string("status", choices=STATUS_NAMES)
        error = o.string("error_code", choices=ERROR_NAMES_ANY)
        o.done()
        f.done()
        if status is None and error is None:
            raise ctx.error(o.line, f"{what}: outcome needs status and/or error_code")
        return Expectation(name, f.line, outcome_goal=goal, outcome_status=status, outcome_error=error)
    if not f.has("measure"):
        raise ctx.error(f.line, f"{what}: give either 'outcome' or 'measure' with a comparison")
    measure = _parse_measure(ctx, f.raw("measure"), f.at("measure"))
    comparison = _parse_comparison(ctx, f, what)
    f.done()
    return Expectation(name, f.line, measure=measure, comparison=comparison)


# ----- cross checks -------------------------------------------------------------------------
def _check_references(ctx: _Ctx, scenario: Scenario) -> None:
    marks = {"start", "end"}
    goals: dict[str, str] = {}
    conditions: list[tuple[Condition, int]] = []
    for step in scenario.steps:
        if step.mark:
            if step.mark in marks:
                raise ctx.error(step.line, f"mark {step.mark!r} is defined twice")
            marks.add(step.mark)
        if isinstance(step, SendGoalStep):
            if step.id in goals:
                raise ctx.error(step.line, f"goal id {step.id!r} is used twice")
            goals[step.id] = step.action
            marks.update({f"{step.id}.sent", f"{step.id}.done"})
            if step.cancel is not None and step.cancel.when is not None:
                conditions.append((step.cancel.when, step.cancel.line))
        elif isinstance(step, (CancelStep, WaitStep)) and getattr(step, "goal", None):
            if step.goal not in goals:
                raise ctx.error(step.line, f"goal {step.goal!r} is not sent by an earlier step; known: {', '.join(goals) or 'none'}")
        if isinstance(step, WaitStep) and step.until is not None:
            conditions.append((step.until, step.until.line))
    measures = [(c.measure, line) for c, line in conditions]
    measures += [(e.measure, e.line) for e in scenario.expectations if e.measure is not None]
    for expectation in scenario.expectations:
        if expectation.outcome_goal is not None:
            action = goals.get(expectation.outcome_goal)
            if action is None:
                raise ctx.error(expectation.line, f"expectation {expectation.name!r}: unknown goal {expectation.outcome_goal!r}; "
                                f"known: {', '.join(goals) or 'none'}")
            allowed = ERROR_NAMES[action] + ("REJECTED",)
            if expectation.outcome_error and expectation.outcome_error not in allowed:
                raise ctx.error(expectation.line, f"expectation {expectation.name!r}: {action} has no error code "
                                f"{expectation.outcome_error!r}; it has: {', '.join(allowed)}")
    objects = ROBOTS[scenario.robot]["objects"]
    for measure, line in measures:
        for key in ("from", "to", "at"):
            mark = measure.args.get(key)
            if mark is not None and mark not in marks:
                raise ctx.error(measure.line or line, f"measure {measure.kind}: unknown mark {mark!r}; marks: {', '.join(sorted(marks))}")
        goal = measure.args.get("goal")
        if goal is not None and goal not in goals:
            raise ctx.error(measure.line or line, f"measure {measure.kind}: unknown goal {goal!r}; known: {', '.join(goals) or 'none'}")
        obj = measure.args.get("object")
        if obj is not None and obj not in objects:
            raise ctx.error(measure.line or line, f"measure {measure.kind}: robot {scenario.robot} has no object {obj!r}; "
                            f"objects: {', '.join(objects) or 'none'}")
        if scenario.robot != "g1" and measure.kind in ("base_displacement", "mean_speed", "base_height_min"):
            raise ctx.error(measure.line or line, f"measure {measure.kind} needs a walking robot; {scenario.robot} has a fixed base")


# ----- entry points -------------------------------------------------------------------------
def parse(text: str, file: str = "<scenario>") -> Scenario:
    """Validate scenario ``text``; errors name ``file`` and the line."""
    ctx = _Ctx(file)
    try:
        raw = yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark is not None else 1
        raise ctx.error(line, f"not valid YAML: {error.problem or error}") from None
    except yaml.YAMLError as error:
        raise ctx.error(1, f"not valid YAML: {error}") from None
    f = _Fields(ctx, raw, "scenario", 1)
    stem = pathlib.Path(file).stem
    name = f.string("name", stem)
    description = f.string("description", "")
    robot = f.string("robot", required=True, choices=tuple(ROBOTS))
    assert robot is not None and name is not None
    scene = f.string("scene", ROBOTS[robot]["scenes"][0], choices=ROBOTS[robot]["scenes"])
    seed = f.integer("seed", 0)
    keyframe = f.string("keyframe", ROBOTS[robot]["keyframes"][0], choices=ROBOTS[robot]["keyframes"])
    rtf = f.number("rtf", 0.0, low=0.0, high=1000.0)
    timeout = f.number("timeout", 300.0, low=0.0, unit=" [s of sim time]")
    wall_timeout = f.number("wall_timeout", 600.0, low=1.0, unit=" [s]")
    tags_raw = f.raw("tags", [])
    if not isinstance(tags_raw, list) or not all(isinstance(t, str) for t in tags_raw):
        raise ctx.error(f.at("tags"), f"scenario: tags must be a list of strings, got {tags_raw!r}")
    steps_raw = f.raw("steps", _List())
    if not isinstance(steps_raw, list):
        raise ctx.error(f.at("steps"), f"scenario: steps must be a list, got {_kind(steps_raw)}")
    steps = tuple(_parse_step(ctx, s, _item_line(steps_raw, i), robot, i) for i, s in enumerate(steps_raw))
    expect_raw = f.raw("expect", _List())
    if not isinstance(expect_raw, list) or not expect_raw:
        raise ctx.error(f.at("expect") if f.has("expect") else f.line, "scenario: expect must be a non-empty list of expectations")
    expectations = tuple(_parse_expectation(ctx, e, _item_line(expect_raw, i), i) for i, e in enumerate(expect_raw))
    names = [e.name for e in expectations]
    for i, e in enumerate(expectations):
        if e.name in names[:i]:
            raise ctx.error(e.line, f"expectation name {e.name!r} is used twice")
    f.done()
    scenario = Scenario(name, pathlib.Path(file), description or "", robot, scene or "", seed, keyframe or "",
                        float(rtf or 0.0), float(timeout or 0.0), float(wall_timeout or 0.0), tuple(tags_raw), steps,
                        expectations)
    _check_references(ctx, scenario)
    return scenario


def _item_line(items: Any, index: int) -> int:
    lines = getattr(items, "item_lines", None)
    return lines[index] if lines else _line(items, 1)


def load(path: str | pathlib.Path) -> Scenario:
    """Read and validate a scenario file."""
    path = pathlib.Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise ScenarioError(f"{path}:0: cannot read: {error.strerror}") from None
    return parse(text, str(path))


SCENARIO_DIR = pathlib.Path(__file__).resolve().parents[2] / "scenarios"


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
    return sorted(directory.glob("*.yaml"))
