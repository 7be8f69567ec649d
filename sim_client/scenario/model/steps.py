"""Every kind of step a scenario may use, each defined once.

A :class:`StepKind` holds its dataclass, its parser, its one-line description, and the function that
carries it out on a run (:class:`StepRunner`, which :class:`~sim_client.scenario.running.scenario_run.ScenarioRun`
provides). To add one, write its dataclass and functions next to the others and add it to :data:`STEPS`;
the schema, the runner and ``scenario kinds`` take it from there. Times are sim seconds; lengths metres;
angles radians.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, Protocol, TypeVar

from sim_client.scenario.model.actions import ACTIONS, actions_of
from sim_client.scenario.model.conditions import Condition, Trigger, parse_condition, parse_trigger
from sim_client.scenario.model.fields import Ctx, Fields, LineMap, Vector3, key_line, kind_of, line_of
from sim_client.scenario.model.robots import RobotFacts


# ----- the steps ----------------------------------------------------------------------------
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


# ----- the run that carries them out --------------------------------------------------------
class StepRunner(Protocol):
    """What a step may ask of the run that carries it out (``ScenarioRun`` provides it). Times are sim seconds."""

    def reset(self, keyframe: str | None) -> None:
        """Reset /sim to ``keyframe`` (None: the scenario's)."""
        ...

    def wait_sim(self, duration: float) -> None:
        """Let ``duration`` of sim time pass."""
        ...

    def wait_until(self, predicate: Callable[[], bool], timeout: float, what: str, line: int,
                   checks_measures: bool = True) -> None:
        """Let sim time pass until ``predicate`` holds; a failure of the step after ``timeout``.

        ``checks_measures`` False: the predicate reads only whether goals ended (checked less often).
        """
        ...

    def condition_holds(self, condition: Condition) -> bool:
        """Whether ``condition`` holds now (False while a mark it needs is not reached)."""
        ...

    def goal_done(self, goal_id: str) -> bool:
        """Whether goal ``goal_id``, sent earlier, has ended."""
        ...

    def cancel_goal(self, goal_id: str) -> None:
        """Ask the server to cancel goal ``goal_id``, sent earlier."""
        ...

    def send_goal(self, step: SendGoalStep) -> None:
        """Send the step's goal; with ``step.wait``, let sim time pass until it ends."""
        ...

    def set_param(self, step: SetParamStep) -> None:
        """Set the step's parameter and judge whether it was accepted as the step expects."""
        ...

    def push(self, step: PushStep) -> None:
        """Push the step's body and judge whether /sim applied it as the step expects."""
        ...

    def drive(self, step: CmdVelStep) -> None:
        """Publish the step's /cmd_vel for its duration, then zero."""
        ...


# ----- the kinds ----------------------------------------------------------------------------
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
        run: ``(run, step) -> None``: carries the step out on a run.
        about: its keys and what it does, for ``scenario kinds``.
        body_optional: ``reset:`` with nothing after it is an empty mapping.
    """

    name: str
    type: type[S]
    parse: Callable[[Fields, StepHead, RobotFacts], S]
    describe: Callable[[S], str]
    run: Callable[[StepRunner, S], None]
    about: str
    body_optional: bool = False


def _parse_reset(f: Fields, head: StepHead, robot: RobotFacts) -> ResetStep:
    keyframe = f.optional_string("keyframe", choices=robot.keyframes)
    f.done()
    return ResetStep(head.line, head.mark, keyframe)


def _describe_reset(step: ResetStep) -> str:
    return f"reset{' to ' + step.keyframe if step.keyframe else ''}"


def _run_reset(run: StepRunner, step: ResetStep) -> None:
    run.reset(step.keyframe)


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


def _run_wait(run: StepRunner, step: WaitStep) -> None:
    if step.duration is not None:
        run.wait_sim(step.duration)
    elif step.until is not None:
        condition = step.until
        run.wait_until(lambda: run.condition_holds(condition), step.timeout, f"until {condition.describe()}", step.line)
    elif step.goal is not None:
        goal_id = step.goal
        run.wait_until(lambda: run.goal_done(goal_id), step.timeout, f"for goal {goal_id} to end", step.line,
                       checks_measures=False)


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


def _run_send_goal(run: StepRunner, step: SendGoalStep) -> None:
    run.send_goal(step)


def _parse_cancel(f: Fields, head: StepHead, robot: RobotFacts) -> CancelStep:
    goal_id = f.required_string("goal")
    f.done()
    return CancelStep(head.line, head.mark, goal_id)


def _run_cancel(run: StepRunner, step: CancelStep) -> None:
    run.cancel_goal(step.goal)


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


def _run_set_param(run: StepRunner, step: SetParamStep) -> None:
    run.set_param(step)


def _parse_cmd_vel(f: Fields, head: StepHead, robot: RobotFacts) -> CmdVelStep:
    if not robot.walks:
        raise f.error(head.line, f"/cmd_vel drives a walking robot; robot {robot.name} has none")
    step = CmdVelStep(head.line, head.mark, f.number("vx", 0.0, unit=" [m/s]"), f.number("vy", 0.0, unit=" [m/s]"),
                      f.number("wz", 0.0, unit=" [rad/s]"), f.required_number("duration", low=0.0, unit=" [s]"))
    f.done()
    return step


def _describe_cmd_vel(step: CmdVelStep) -> str:
    return f"/cmd_vel vx={step.vx:g} vy={step.vy:g} wz={step.wz:g} for {step.duration:g} s"


def _run_cmd_vel(run: StepRunner, step: CmdVelStep) -> None:
    run.drive(step)


def _parse_push(f: Fields, head: StepHead, robot: RobotFacts) -> PushStep:
    step = PushStep(head.line, head.mark, f.string("body", ""), f.required_vector3("force", unit=" [N]"),
                    f.optional_vector3("torque", unit=" [N m]") or (0.0, 0.0, 0.0),
                    f.required_number("duration", unit=" [s of sim time]"), f.boolean("refused", False))
    f.done()
    return step


def _describe_push(step: PushStep) -> str:
    torque = f" torque {list(step.torque)} N m" if any(step.torque) else ""
    return f"push {step.body or 'the base'} with {list(step.force)} N{torque} for {step.duration:g} s"


def _run_push(run: StepRunner, step: PushStep) -> None:
    run.push(step)


_STEP_LIST: tuple[StepKind[Any], ...] = (
    StepKind("reset", ResetStep, _parse_reset, _describe_reset, _run_reset,
             "{keyframe}: /sim/reset to a keyframe (default: the scenario's)", body_optional=True),
    StepKind("wait", WaitStep, _parse_wait, _describe_wait, _run_wait,
             "{duration} sim seconds, or {until: CONDITION, timeout}, or {goal: ID, timeout} until it ends"),
    StepKind("send_goal", SendGoalStep, _parse_send_goal, _describe_send_goal, _run_send_goal,
             "{id, action, goal, wait, timeout, cancel: {after} or {when: CONDITION}}: an action goal"),
    StepKind("cancel", CancelStep, _parse_cancel, lambda step: f"cancel goal {step.goal}", _run_cancel,
             "{goal: ID}: cancel a goal sent earlier"),
    StepKind("set_param", SetParamStep, _parse_set_param, _describe_set_param, _run_set_param,
             "{node, name, value, refused}: set a parameter; refused: true = the node must refuse it"),
    StepKind("cmd_vel", CmdVelStep, _parse_cmd_vel, _describe_cmd_vel, _run_cmd_vel,
             "{vx, vy, wz, duration}: publish /cmd_vel [m/s, rad/s] for sim seconds, then zero (walking robots)"),
    StepKind("push", PushStep, _parse_push, _describe_push, _run_push,
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
