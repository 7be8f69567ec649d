"""Every kind of measure a scenario may use, each defined once.

A :class:`MeasureKind` holds the keys it takes (parsed and cross-checked from their role: a mark,
a goal id, an object...), its unit, what it is, and the function that evaluates it on what a run
recorded (:class:`Recorded`). To add one, write its function next to the others and add it to
:data:`MEASURES`; the schema, the runner and ``scenario kinds`` take it from there. Times are sim
seconds; lengths metres; angles radians.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol

from sim_client.scenario.model.fields import Ctx, Fields, LineMap, key_line, line_of

if TYPE_CHECKING:
    from sim_client.actions import GoalHandle
    from sim_client.scenario.model.series import Series

Args = Mapping[str, Any]


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
    MeasureKind("base_height_min", FROM_TO, "m", "lowest base height between two marks (it drops when the robot falls)",
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
