"""Every kind of measure, action and step a scenario may use, each defined once.

A :class:`MeasureKind` holds the keys it takes (parsed and cross-checked from their role: a mark,
a goal id, an object...), its unit, what it is, and the function that evaluates it on what a run
recorded (:class:`Recorded`). An :class:`ActionKind` holds its generated action type (its error
codes are read from the ``Result`` constants), what a robot needs to have it, how its goal fields
are parsed and how the goal message is built. A :class:`StepKind` holds its dataclass, its parser,
its one-line description, and the name of the :class:`~sim_client.scenario.runner.ScenarioRun`
method that carries it out.

To add one, write its functions next to the others and add it to :data:`MEASURES`,
:data:`ACTIONS` or :data:`STEPS`; the schema, the runner and ``scenario kinds`` take it from there.
Times are sim seconds; lengths metres; angles radians.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Generic, Literal, Protocol, TypeVar

from sim_client.scenario.fields import Ctx, Fields, LineMap, Vector3, key_line, kind_of, line_of
from sim_client.scenario.robots import RobotFacts
from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, Walk

if TYPE_CHECKING:
    from sim_client.actions import GoalHandle
    from sim_client.scenario.artifacts import Series

Args = Mapping[str, Any]


# ----- measures: the data model -------------------------------------------------------------
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
        return MEASURES[self.kind].unit_of(self.args)

    def evaluate(self, recorded: Recorded) -> Any:
        """The value on what the run recorded; None when it cannot be measured; KeyError for a mark not reached."""
        return MEASURES[self.kind].evaluate(recorded, self.args)


COMPARISONS = ("near", "gte", "lte", "gt", "lt", "eq")


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
            return bool(measured == self.value)
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
        if self.when is not None:
            return f"when {self.when.describe()}"
        return f"after {self.after:g} s"


# ----- measures: the kinds ------------------------------------------------------------------
class Recorded(Protocol):
    """What a run recorded, as measures read it (``ScenarioRun`` provides it)."""

    def mark_time(self, name: str | None, default: str) -> float:
        """Sim time [s] of mark ``name`` (``default`` when None); KeyError if it was not reached."""
        ...

    def odom_series(self) -> Series:
        """Base pose over time: columns x, y, z [m], yaw [rad]."""
        ...

    def object_series(self, name: str) -> Series:
        """An object's position over time: columns x, y, z [m] (then its orientation)."""
        ...

    def joint_series(self) -> tuple[list[str], Series]:
        """Joint names and their positions over time [rad or m]."""
        ...

    def goal_handle(self, goal_id: str) -> GoalHandle[Any, Any] | None:
        """The handle of a goal the run sent, None if it was not sent."""
        ...

    def parameter(self, node: str, name: str) -> Any:
        """A parameter's value now, None when it cannot be read."""
        ...


KeyRole = Literal["mark", "goal", "object", "text", "choice", "point"]


@dataclass(frozen=True)
class Key:
    """One key of a measure. ``role`` says how it is parsed and what it must name.

    ``mark``, ``goal`` and ``object`` keys are checked against the scenario's marks, goal ids and
    the robot's objects; ``choice`` is one of ``choices`` (default ``default``); ``point`` is
    [x, y, z] in metres; ``text`` is any string.
    """

    name: str
    role: KeyRole
    required: bool = False
    choices: tuple[str, ...] = ()
    default: str | None = None


def _mark(name: str) -> Key:
    return Key(name, "mark")


FROM_TO = (_mark("from"), _mark("to"))
AT = _mark("at")
GOAL = Key("goal", "goal", required=True)
OBJECT = Key("object", "object", required=True)
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2, "yaw": 3}


@dataclass(frozen=True)
class MeasureKind:
    """One kind of measure: its keys, unit, description and evaluation.

    Attributes:
        name: the YAML name (``base_displacement``).
        keys: the keys it takes, in the order they are described.
        unit: its unit, or a function of its arguments for a unit that depends on them.
        about: what it is, for ``scenario kinds`` and the README.
        evaluate: ``(recorded, args) -> value``; None when it cannot be measured.
        walking: needs a robot with a floating base that walks.
    """

    name: str
    keys: tuple[Key, ...]
    unit: str | Callable[[Args], str]
    about: str
    evaluate: Callable[[Recorded, Args], Any]
    walking: bool = False

    def unit_of(self, args: Args) -> str:
        return self.unit if isinstance(self.unit, str) else self.unit(args)

    def parse(self, ctx: Ctx, raw: Any, line: int) -> Measure:
        f = Fields(ctx, raw, f"measure {self.name}", line)
        args: dict[str, Any] = {}
        for key in self.keys:
            if key.role == "point":
                point = f.required_vector3 if key.required else f.optional_vector3
                args[key.name] = point(key.name, " [m]")
            elif key.role == "choice":
                args[key.name] = f.string(key.name, key.default or key.choices[0], choices=key.choices)
            else:
                args[key.name] = f.optional_string(key.name)
        f.done()
        for key in self.keys:
            if key.required and not args.get(key.name):
                raise ctx.error(line, f"measure {self.name}: missing required key {key.name!r}")
        return Measure(self.name, args, line)


def _span(recorded: Recorded, a: Args) -> tuple[float, float]:
    return recorded.mark_time(a.get("from"), "start"), recorded.mark_time(a.get("to"), "end")


def _at(recorded: Recorded, a: Args) -> float:
    return recorded.mark_time(a.get("at"), "end")


def _planar_distance(recorded: Recorded, t0: float, t1: float) -> float | None:
    odom = recorded.odom_series()
    p0, p1 = odom.at(t0), odom.at(t1)
    if p0 is None or p1 is None:
        return None
    return float(math.hypot(p1[0] - p0[0], p1[1] - p0[1]))


def _base_displacement(recorded: Recorded, a: Args) -> float | None:
    return _planar_distance(recorded, *_span(recorded, a))


def _mean_speed(recorded: Recorded, a: Args) -> float | None:
    t0, t1 = _span(recorded, a)
    distance = _planar_distance(recorded, t0, t1)
    return distance / (t1 - t0) if distance is not None and t1 > t0 else None


def _base_height_min(recorded: Recorded, a: Args) -> float | None:
    t0, t1 = _span(recorded, a)
    window = recorded.odom_series().window(t0, t1)
    return float(window.values[:, 2].min()) if len(window.t) else None


def _duration(recorded: Recorded, a: Args) -> float:
    t0, t1 = _span(recorded, a)
    return t1 - t0


def _base_position(recorded: Recorded, a: Args) -> float | None:
    pose = recorded.odom_series().at(_at(recorded, a))
    return None if pose is None else float(pose[_AXIS_INDEX[a["axis"]]])


def _object_distance(recorded: Recorded, a: Args) -> float | None:
    pose = recorded.object_series(a["object"]).at(_at(recorded, a))
    return None if pose is None else float(math.dist(pose[0:3], a["target"]))


def _object_position(recorded: Recorded, a: Args) -> float | None:
    pose = recorded.object_series(a["object"]).at(_at(recorded, a))
    return None if pose is None else float(pose[_AXIS_INDEX[a["axis"]]])


def _joint_position(recorded: Recorded, a: Args) -> float | None:
    names, series = recorded.joint_series()
    row = series.at(_at(recorded, a))
    if row is None or a["joint"] not in names:
        return None
    return float(row[names.index(a["joint"])])


def _parameter(recorded: Recorded, a: Args) -> Any:
    return recorded.parameter(a["node"], a["name"])


def field_of(obj: Any, path: str) -> Any:
    """``obj.a.b.c`` for ``path`` ``"a.b.c"``; None where a part is missing."""
    for part in path.split("."):
        if obj is None:
            return None
        obj = getattr(obj, part, None)
    return obj


def _feedback(recorded: Recorded, a: Args) -> Any:
    handle = recorded.goal_handle(a["goal"])
    if handle is None:
        return None
    values = [field_of(sample.feedback, a["field"]) for sample in handle.feedback_history]
    if a["reduce"] == "count":
        return len(values)
    numbers = [float(v) for v in values if isinstance(v, (int, float))]
    if not numbers:
        return None
    return {"last": numbers[-1], "max": max(numbers), "min": min(numbers)}[a["reduce"]]


def _outcome(recorded: Recorded, a: Args) -> Any:
    handle = recorded.goal_handle(a["goal"])
    return None if handle is None else handle.outcome()


def _result(recorded: Recorded, a: Args) -> Any:
    outcome = _outcome(recorded, a)
    if outcome is None:
        return None
    value = field_of(outcome.result, a["field"])
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else value


def _status(recorded: Recorded, a: Args) -> str | None:
    outcome = _outcome(recorded, a)
    return None if outcome is None else str(outcome.status)


def _error_code(recorded: Recorded, a: Args) -> str | None:
    outcome = _outcome(recorded, a)
    return None if outcome is None else str(outcome.error_name)


_MEASURE_LIST = (
    MeasureKind("base_displacement", FROM_TO, "m", "planar distance of the base between two marks", _base_displacement,
                walking=True),
    MeasureKind("base_position", (Key("axis", "choice", choices=("x", "y", "z", "yaw")), AT),
                lambda a: "rad" if a.get("axis") == "yaw" else "m", "base x, y, z [m] or yaw [rad] at a mark", _base_position),
    MeasureKind("base_height_min", FROM_TO, "m", "lowest base height between two marks (never fell: >= 0.5 on the G1)",
                _base_height_min, walking=True),
    MeasureKind("mean_speed", FROM_TO, "m/s", "planar base displacement / sim time between two marks", _mean_speed,
                walking=True),
    MeasureKind("object_distance", (OBJECT, Key("target", "point", required=True), AT), "m",
                "distance of an object's centre to a target point at a mark", _object_distance),
    MeasureKind("object_position", (OBJECT, Key("axis", "choice", choices=("x", "y", "z")), AT), "m",
                "an object's x, y or z at a mark", _object_position),
    MeasureKind("joint_position", (Key("joint", "text", required=True), AT), "rad", "a joint's position at a mark",
                _joint_position),
    MeasureKind("feedback", (GOAL, Key("field", "text", required=True),
                             Key("reduce", "choice", choices=("last", "max", "min", "count"))), "",
                "a feedback field of a goal: last, max, min or count", _feedback),
    MeasureKind("result", (GOAL, Key("field", "text", required=True)), "",
                "a result field of a goal (dotted path, e.g. final_pose.pose.position.x)", _result),
    MeasureKind("status", (GOAL,), "", "the final status of a goal (SUCCEEDED, ABORTED, CANCELED, REJECTED)", _status),
    MeasureKind("error_code", (GOAL,), "", "the name of a goal's result error code (SUCCESS, INVALID_GOAL, ...)", _error_code),
    MeasureKind("duration", FROM_TO, "s", "sim time between two marks", _duration),
    MeasureKind("parameter", (Key("node", "text", required=True), Key("name", "text", required=True)), "",
                "a parameter's value at the end of the run", _parameter),
)
MEASURES: dict[str, MeasureKind] = {kind.name: kind for kind in _MEASURE_LIST}


def parse_measure(ctx: Ctx, raw: Any, line: int) -> Measure:
    """``name`` or ``{name: {key: value...}}``, validated by its kind."""
    if isinstance(raw, str):
        kind, args_raw = raw, LineMap()
    elif isinstance(raw, dict) and len(raw) == 1:
        kind, args_raw = next(iter(raw.items()))
        line = key_line(raw, kind)
        if args_raw is None:
            args_raw = LineMap()
    else:
        raise ctx.error(line_of(raw, line), f"measure must be a name or a mapping with one kind; kinds: {', '.join(MEASURES)}")
    if kind not in MEASURES:
        raise ctx.error(line, f"unknown measure {kind!r}; kinds: {', '.join(MEASURES)}")
    return MEASURES[kind].parse(ctx, args_raw, line)


def parse_comparison(f: Fields) -> Comparison:
    """Exactly one of near (with tol or rel_tol), gte, lte, gt, lt, eq among the keys of ``f``."""
    ops = [op for op in COMPARISONS if f.has(op)]
    if len(ops) != 1:
        found = f"found {', '.join(ops)}" if ops else "found none"
        raise f.error(f.line, f"give exactly one comparison of {', '.join(COMPARISONS)} ({found})")
    op = ops[0]
    if op == "eq":
        return Comparison("eq", f.raw("eq"))
    value = f.required_number(op)
    if op == "near":
        tol = f.optional_number("tol", low=0.0)
        rel_tol = f.optional_number("rel_tol", low=0.0)
        if (tol is None) == (rel_tol is None):
            raise f.error(f.at("near"), "near needs exactly one of tol (absolute) or rel_tol (fraction, 0.05 = 5%)")
        return Comparison("near", value, tol, rel_tol)
    return Comparison(op, value)


def parse_condition(ctx: Ctx, raw: Any, line: int, what: str) -> Condition:
    f = Fields(ctx, raw, what, line)
    if not f.has("measure"):
        raise f.error(f.line, "missing required key 'measure'")
    measure = parse_measure(ctx, f.raw("measure"), f.at("measure"))
    comparison = parse_comparison(f)
    f.done()
    return Condition(measure, comparison, f.line)


def parse_trigger(ctx: Ctx, raw: Any, line: int, what: str) -> Trigger:
    f = Fields(ctx, raw, what, line)
    after = f.optional_number("after", low=0.0, unit=" [s of sim time]")
    when_raw = f.raw("when")
    when = parse_condition(ctx, when_raw, f.at("when"), f"{what}: when") if f.has("when") else None
    f.done()
    if (after is None) == (when is None):
        raise f.error(f.line, "give exactly one of 'after' (sim seconds after the goal was sent) or 'when' (a condition)")
    return Trigger(after, when, f.line)


# ----- actions ------------------------------------------------------------------------------
def error_code_names(action_type: Any) -> tuple[str, ...]:
    """The names of an action's result error codes, by value: the upper-case int constants of its ``Result``."""
    constants = {name: getattr(action_type.Result, name) for name in dir(action_type.Result) if name.isupper()}
    codes = {name: value for name, value in constants.items() if isinstance(value, int) and not isinstance(value, bool)}
    return tuple(sorted(codes, key=lambda name: (codes[name], name)))


@dataclass(frozen=True)
class ActionKind:
    """One action a scenario may send goals to.

    Attributes:
        name: the YAML name (``walk``).
        action_type: the generated ``sim_interfaces.action`` type; its result constants are the error codes.
        available: whether a robot has it (which servers bringup starts for it).
        parse_goal: ``(fields, robot) -> goal fields`` from the ``goal:`` mapping.
        make_goal: ``(client class, goal fields) -> goal message``, with the client's ``goal`` helper.
        fields: the goal's keys, for the README.
    """

    name: str
    action_type: Any
    available: Callable[[RobotFacts], bool]
    parse_goal: Callable[[Fields, RobotFacts], dict[str, Any]]
    make_goal: Callable[[Any, dict[str, Any]], Any]
    fields: str = ""
    error_names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "error_names", error_code_names(self.action_type))


def _walk_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    return {"distance": f.required_number("distance", unit=" [m]"), "speed": f.number("speed", 0.0, unit=" [m/s]"),
            "timeout": f.number("timeout", 0.0, unit=" [s]")}


def _navigate_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    return {"x": f.required_number("x"), "y": f.required_number("y"), "yaw": f.number("yaw", 0.0),
            "frame": f.string("frame", "odom")}


def _move_arm_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    goal = {"position": f.required_vector3("position", unit=" [m]"), "rpy": f.optional_vector3("rpy", unit=" [rad]"),
            "arm": f.string("arm", ""), "position_tolerance": f.number("position_tolerance", 0.005),
            "orientation_tolerance": f.number("orientation_tolerance", 0.0),
            "max_velocity_scaling": f.number("max_velocity_scaling", 0.0), "timeout": f.number("timeout", 0.0),
            "frame": f.string("frame", "world")}
    # An unknown arm is allowed on purpose (bad-goal stories), but a typo is worth a clear note.
    goal["arm_known"] = goal["arm"] in ("", *robot.arms)
    return goal


def _pick_place_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    return {"object": f.required_string("object"), "place": f.required_vector3("place", unit=" [m]"), "arm": f.string("arm", ""),
            "timeout": f.number("timeout", 0.0)}


def _make_move_arm(client: Any, g: dict[str, Any]) -> Any:
    return client.goal(*g["position"], rpy=g["rpy"], arm=g["arm"], position_tolerance=g["position_tolerance"],
                       orientation_tolerance=g["orientation_tolerance"], max_velocity_scaling=g["max_velocity_scaling"],
                       timeout=g["timeout"], frame=g["frame"])


_ACTION_LIST = (
    ActionKind("walk", Walk, lambda robot: robot.walks, _walk_goal,
               lambda client, g: client.goal(g["distance"], g["speed"], g["timeout"]), "distance, speed, timeout"),
    ActionKind("navigate", NavigateToPose, lambda robot: robot.walks, _navigate_goal,
               lambda client, g: client.goal(g["x"], g["y"], g["yaw"], g["frame"]), "x, y, yaw, frame"),
    ActionKind("move_arm", MoveArm, lambda robot: bool(robot.arms), _move_arm_goal, _make_move_arm,
               "position [x,y,z], rpy [r,p,y] (omit = position only), arm, position_tolerance, orientation_tolerance, "
               "max_velocity_scaling, timeout, frame"),
    ActionKind("pick_place", PickPlace, lambda robot: bool(robot.objects), _pick_place_goal,
               lambda client, g: client.goal(g["object"], g["place"], arm=g["arm"], timeout=g["timeout"]),
               "object, place [x,y,z], arm, timeout"),
)
ACTIONS: dict[str, ActionKind] = {kind.name: kind for kind in _ACTION_LIST}
STATUS_NAMES = ("SUCCEEDED", "ABORTED", "CANCELED", "REJECTED")
# Any action's error code, and REJECTED (the name of a goal that was refused).
ERROR_NAMES_ANY = tuple(sorted({name for kind in _ACTION_LIST for name in kind.error_names} | {"REJECTED"}))


def actions_of(robot: RobotFacts) -> tuple[str, ...]:
    """The actions ``robot`` has, in registry order."""
    return tuple(name for name, kind in ACTIONS.items() if kind.available(robot))


# ----- steps: the data model ----------------------------------------------------------------
@dataclass(frozen=True)
class Step:
    """Base of all steps. ``mark`` names the sim time at which the step starts.

    The schema checks references through the three methods below, which a kind overrides.
    """

    line: int
    mark: str | None

    def goal_sent(self) -> tuple[str, str] | None:
        """(goal id, action) of a goal this step sends; its marks ``<id>.sent`` and ``<id>.done`` exist after it."""
        return None

    def goal_used(self) -> str | None:
        """The id of a goal an earlier step must have sent."""
        return None

    def conditions(self) -> tuple[Condition, ...]:
        """Conditions the step evaluates (their measures are checked like expectations')."""
        return ()


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

    def goal_used(self) -> str | None:
        return self.goal

    def conditions(self) -> tuple[Condition, ...]:
        return () if self.until is None else (self.until,)


@dataclass(frozen=True)
class SendGoalStep(Step):
    """Send an action goal. ``wait`` blocks until the result; ``cancel`` cancels it on a trigger."""

    id: str = ""
    action: str = ""
    goal: dict[str, Any] = field(default_factory=dict)
    wait: bool = True
    timeout: float = 120.0
    cancel: Trigger | None = None

    def goal_sent(self) -> tuple[str, str] | None:
        return self.id, self.action

    def conditions(self) -> tuple[Condition, ...]:
        return () if self.cancel is None or self.cancel.when is None else (self.cancel.when,)


@dataclass(frozen=True)
class CancelStep(Step):
    goal: str = ""

    def goal_used(self) -> str | None:
        return self.goal


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
    force: Vector3 = (0.0, 0.0, 0.0)
    torque: Vector3 = (0.0, 0.0, 0.0)
    duration: float = 0.1
    refused: bool = False


# ----- steps: the kinds ---------------------------------------------------------------------
@dataclass(frozen=True)
class StepHead:
    """What every step has: the line of its kind's key, and its optional mark."""

    line: int
    mark: str | None


S = TypeVar("S", bound=Step)


@dataclass(frozen=True)
class StepKind(Generic[S]):
    """One kind of step.

    Attributes:
        name: the YAML key (``send_goal``).
        type: the dataclass it parses into.
        parse: ``(fields of its mapping, head, robot) -> step``; it calls ``fields.done()`` itself.
        describe: one line for the progress output and verdicts.
        run: the name of the ``ScenarioRun`` method that carries it out (``run(step) -> None``).
        about: its keys and what it does, for ``scenario kinds``.
        body_optional: ``reset:`` with nothing after it is an empty mapping.
    """

    name: str
    type: type[S]
    parse: Callable[[Fields, StepHead, RobotFacts], S]
    describe: Callable[[S], str]
    run: str
    about: str
    body_optional: bool = False


def _parse_reset(f: Fields, head: StepHead, robot: RobotFacts) -> ResetStep:
    keyframe = f.optional_string("keyframe", choices=robot.keyframes)
    f.done()
    return ResetStep(head.line, head.mark, keyframe)


def _describe_reset(step: ResetStep) -> str:
    return f"reset{' to ' + step.keyframe if step.keyframe else ''}"


def _parse_wait(f: Fields, head: StepHead, robot: RobotFacts) -> WaitStep:
    duration = f.optional_number("duration", low=0.0, unit=" [s of sim time]")
    until_raw = f.raw("until")  # read even when absent, so that an unknown key lists it as allowed
    until = parse_condition(f.ctx, until_raw, f.at("until"), f"{f.what}: until") if f.has("until") else None
    goal = f.optional_string("goal")
    timeout = f.number("timeout", 60.0, low=0.0, unit=" [s of sim time]")
    f.done()
    if sum(x is not None for x in (duration, until, goal)) != 1:
        raise f.error(f.line, "give exactly one of duration, until (a condition) or goal (a goal id)")
    return WaitStep(head.line, head.mark, duration, until, goal, timeout)


def _describe_wait(step: WaitStep) -> str:
    if step.duration is not None:
        return f"wait {step.duration:g} s"
    if step.until is not None:
        return f"wait until {step.until.describe()}"
    return f"wait for goal {step.goal}"


def _parse_send_goal(f: Fields, head: StepHead, robot: RobotFacts) -> SendGoalStep:
    action = f.required_string("action", choices=tuple(ACTIONS))
    if not ACTIONS[action].available(robot):
        raise f.error(f.at("action"), f"robot {robot.name} has no {action} action; it has: {', '.join(actions_of(robot))}")
    goal_id = f.required_string("id")
    raw_goal = f.raw("goal")
    goal_fields = Fields(f.ctx, raw_goal if raw_goal is not None else LineMap(), f"goal of {action}",
                         f.at("goal") if f.has("goal") else f.line)
    goal = ACTIONS[action].parse_goal(goal_fields, robot)
    goal_fields.done()
    wait = f.boolean("wait", True)
    timeout = f.number("timeout", 120.0, low=0.0, unit=" [s of sim time]")
    cancel_raw = f.raw("cancel")
    cancel = parse_trigger(f.ctx, cancel_raw, f.at("cancel"), f"{f.what}: cancel") if f.has("cancel") else None
    f.done()
    return SendGoalStep(head.line, head.mark, goal_id, action, goal, wait, timeout, cancel)


def _describe_send_goal(step: SendGoalStep) -> str:
    goal = ", ".join(f"{k}={v}" for k, v in step.goal.items() if v not in (None, "", 0.0) and k != "arm_known")
    extra = f", cancel {step.cancel.describe()}" if step.cancel else ""
    return f"send {step.action} goal {step.id} ({goal}){'' if step.wait else ' without waiting'}{extra}"


def _parse_cancel(f: Fields, head: StepHead, robot: RobotFacts) -> CancelStep:
    goal_id = f.required_string("goal")
    f.done()
    return CancelStep(head.line, head.mark, goal_id)


def _parse_set_param(f: Fields, head: StepHead, robot: RobotFacts) -> SetParamStep:
    node = f.required_string("node")
    name = f.required_string("name")
    if not f.has("value"):
        raise f.error(f.line, "missing required key 'value'")
    value = f.raw("value")
    if isinstance(value, (dict, list)) or value is None:
        raise f.error(f.at("value"), f"value must be a number, string or bool, got {kind_of(value)}")
    refused = f.boolean("refused", False)
    f.done()
    return SetParamStep(head.line, head.mark, node, name, value, refused)


def _describe_set_param(step: SetParamStep) -> str:
    return f"set {step.node} {step.name} = {step.value!r}{' (must be refused)' if step.refused else ''}"


def _parse_cmd_vel(f: Fields, head: StepHead, robot: RobotFacts) -> CmdVelStep:
    if not robot.walks:
        raise f.error(head.line, f"/cmd_vel drives a walking robot; robot {robot.name} has none")
    step = CmdVelStep(head.line, head.mark, f.number("vx", 0.0, unit=" [m/s]"), f.number("vy", 0.0, unit=" [m/s]"),
                      f.number("wz", 0.0, unit=" [rad/s]"), f.required_number("duration", low=0.0, unit=" [s]"))
    f.done()
    return step


def _describe_cmd_vel(step: CmdVelStep) -> str:
    return f"/cmd_vel vx={step.vx:g} vy={step.vy:g} wz={step.wz:g} for {step.duration:g} s"


def _parse_push(f: Fields, head: StepHead, robot: RobotFacts) -> PushStep:
    step = PushStep(head.line, head.mark, f.string("body", ""), f.required_vector3("force", unit=" [N]"),
                    f.optional_vector3("torque", unit=" [N m]") or (0.0, 0.0, 0.0),
                    f.required_number("duration", unit=" [s of sim time]"), f.boolean("refused", False))
    f.done()
    return step


def _describe_push(step: PushStep) -> str:
    torque = f" torque {list(step.torque)} N m" if any(step.torque) else ""
    return f"push {step.body or 'the base'} with {list(step.force)} N{torque} for {step.duration:g} s"


_STEP_LIST: tuple[StepKind[Any], ...] = (
    StepKind("reset", ResetStep, _parse_reset, _describe_reset, "_run_reset",
             "{keyframe}: /sim/reset to a keyframe (default: the scenario's)", body_optional=True),
    StepKind("wait", WaitStep, _parse_wait, _describe_wait, "_run_wait",
             "{duration} sim seconds, or {until: CONDITION, timeout}, or {goal: ID, timeout} until it ends"),
    StepKind("send_goal", SendGoalStep, _parse_send_goal, _describe_send_goal, "_send_goal",
             "{id, action, goal, wait, timeout, cancel: {after} or {when: CONDITION}}: an action goal"),
    StepKind("cancel", CancelStep, _parse_cancel, lambda step: f"cancel goal {step.goal}", "_run_cancel",
             "{goal: ID}: cancel a goal sent earlier"),
    StepKind("set_param", SetParamStep, _parse_set_param, _describe_set_param, "_set_param",
             "{node, name, value, refused}: set a parameter; refused: true = the node must refuse it"),
    StepKind("cmd_vel", CmdVelStep, _parse_cmd_vel, _describe_cmd_vel, "_cmd_vel_for",
             "{vx, vy, wz, duration}: publish /cmd_vel [m/s, rad/s] for sim seconds, then zero (walking robots)"),
    StepKind("push", PushStep, _parse_push, _describe_push, "_push_body",
             "{body, force, torque, duration, refused}: /sim/push [N, N m, s], world frame; body default: the base"),
)
STEPS: dict[str, StepKind[Any]] = {kind.name: kind for kind in _STEP_LIST}
_STEP_OF_TYPE: dict[type, StepKind[Any]] = {kind.type: kind for kind in _STEP_LIST}


def step_kind(step: Step) -> StepKind[Any]:
    """The kind of a parsed step."""
    return _STEP_OF_TYPE[type(step)]


def describe_step(step: Step) -> str:
    """One line saying what the step does."""
    return step_kind(step).describe(step)


def parse_step(ctx: Ctx, raw: Any, line: int, robot: RobotFacts, index: int) -> Step:
    """Step ``index`` (0-based): a mapping with one kind's key and, optionally, ``mark``."""
    what = f"step {index + 1}"
    names = tuple(STEPS)
    if not isinstance(raw, dict):
        raise ctx.error(line, f"{what} must be a mapping with one of: {', '.join(names)}")
    found = [k for k in raw if k in STEPS]
    if len(found) != 1:
        other = [k for k in raw if k not in STEPS and k != "mark"]
        hint = f"unknown key {other[0]!r}; " if other else ""
        raise ctx.error(line_of(raw, line), f"{what}: {hint}give exactly one of {', '.join(names)} (and optionally mark)")
    kind = STEPS[found[0]]
    outer = Fields(ctx, raw, what, line)
    mark = outer.optional_string("mark")
    body = outer.raw(kind.name)
    outer.done()
    at = key_line(raw, kind.name)
    if body is None and kind.body_optional:
        body = LineMap()
    return kind.parse(Fields(ctx, body, f"{what} ({kind.name})", at), StepHead(at, mark), robot)
