"""Run a scenario: bring up its nodes, drive sim time, run the steps, judge the expectations.

The run is lock-stepped: the sim starts paused and the runner advances it in small chunks with
``/sim/step``, checking triggers and conditions between chunks; ``rtf`` 0 (the default) goes as fast
as the machine allows, ``rtf`` > 0 paces the chunks to that real-time factor. Either way the same
scenario gives the same numbers. Attached to nodes already running (``--attach``) with ``rtf`` > 0,
the sim runs free at its own pace and the runner follows ``/clock``.
"""

from __future__ import annotations

import contextlib
import datetime
import math
import pathlib
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, TextIO

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, JointState

import robot_models
from nodes.processes import running
from sim_client.actions import ACTION_CLIENTS, GoalHandle, ParameterError, Parameters, _ActionClientBase, push_request
from sim_client.scenario import artifacts
from sim_client.scenario.registry import (
    ACTIONS,
    CancelStep,
    CmdVelStep,
    Comparison,
    Condition,
    Measure,
    PushStep,
    ResetStep,
    SendGoalStep,
    SetParamStep,
    Step,
    WaitStep,
    describe_step,
    step_kind,
)
from sim_client.scenario.schema import Expectation, Scenario
from sim_client.session import RESPONSE_QOS, RosSession, TopicRecorder, WaitTimeout
from sim_interfaces.msg import LocomotionState, ObjectStates
from sim_interfaces.srv import Push, Reset, Step as StepSrv

CHUNK_S = 0.02  # sim time advanced between checks [s]
STARTUP_WALL_S = 90.0
SERVICE_WALL_S = 30.0
CAMERA_FRAMES_KEPT = 3000  # camera images kept for camera.png (~0.7 GB at 320x240 at most)
GOAL_END_WALL_S = 5.0  # wall seconds to wait for the results of goals /sim reports ended


class StepFailure(RuntimeError):
    """A step could not be carried out (timeout, server missing); the run fails."""


@dataclass(frozen=True)
class RunOptions:
    """How to run: ``rtf`` None = the scenario's own; 0 = as fast as possible, > 0 paced to that factor."""

    rtf: float | None = None
    record: bool = False
    video: bool = False
    plots: bool = False
    camera: bool = False  # record the robot's camera (images in the MCAP, camera.png); costs a rendering per frame
    out: pathlib.Path = pathlib.Path("scenario_runs")
    quiet: bool = False
    launch: bool = True  # False: use nodes already running (``sim up``)


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


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


class _Progress:
    """One status line, rewritten in place on a terminal; plain lines otherwise."""

    def __init__(self, stream: TextIO, quiet: bool) -> None:
        self.stream = stream
        self.quiet = quiet
        self.tty = stream.isatty()
        self._last = 0.0
        self._width = 0

    def update(self, text: str) -> None:
        if self.quiet:
            return
        now = time.monotonic()
        if self.tty:
            if now - self._last < 0.1:
                return
            self._last = now
            padded = text[:160].ljust(self._width)
            self._width = len(text[:160])
            self.stream.write("\r" + padded)
            self.stream.flush()
        elif now - self._last >= 2.0:
            self._last = now
            self.stream.write(text + "\n")
            self.stream.flush()

    def say(self, text: str) -> None:
        if self.quiet:
            return
        if self.tty and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self._width = 0
        self.stream.write(text + "\n")
        self.stream.flush()


class ScenarioRun:
    """One run of one scenario against nodes reachable through ``session``."""

    def __init__(self, scenario: Scenario, session: RosSession, options: RunOptions, folder: pathlib.Path,
                 stream: TextIO = sys.stdout) -> None:
        self.scenario = scenario
        self.session = session
        self.options = options
        self.folder = folder
        self.rtf = scenario.rtf if options.rtf is None else options.rtf
        self.lock_step = options.launch or self.rtf == 0.0
        self._pace_anchor: tuple[float, float] | None = None  # (wall [s], sim [s]) that pacing counts from
        self.progress = _Progress(stream, options.quiet)
        node = session.node
        self.clock = session.record(Clock, "/clock", keep=10)
        self.odom = session.record(Odometry, "/odom", keep=1_000_000)
        self.joints = session.record(JointState, "/joint_states", keep=1_000_000)
        self.objects = session.record(ObjectStates, "/objects", keep=1_000_000)
        # commanded vs measured speed, for the speed plot only: a run without plots carries no extra traffic
        self.locomotion = session.record(LocomotionState, "/sim/locomotion_state", keep=1_000_000) if options.plots else None
        # /sim renders a camera only while it is watched: a run watches (and records) it only when asked.
        cameras = [camera.name for camera in robot_models.cameras_of(scenario.robot)]
        self.camera_name = cameras[0] if options.camera and cameras else ""
        self.camera_images = (session.record(Image, f"/{self.camera_name}/image_raw", keep=CAMERA_FRAMES_KEPT)
                              if self.camera_name else None)
        self._unwatched = tuple(f"/{name}/{topic}" for name in cameras if name != self.camera_name
                                for topic in ("image_raw", "camera_info"))
        self._reset = node.create_client(Reset, "/sim/reset", qos_profile=RESPONSE_QOS)
        self._push = node.create_client(Push, "/sim/push", qos_profile=RESPONSE_QOS)
        self._step = node.create_client(StepSrv, "/sim/step", qos_profile=RESPONSE_QOS)
        self._cmd_vel = node.create_publisher(Twist, "/cmd_vel", 10)
        self.clients: dict[str, _ActionClientBase] = {}
        self.goals: dict[str, GoalHandle] = {}
        self.goal_actions: dict[str, str] = {}
        self.cancel_triggers: dict[str, Any] = {}
        self.marks: dict[str, float] = {}
        self.param_events: list[dict[str, Any]] = []
        self.param_verdicts: list[Verdict] = []
        self.failures: list[str] = []
        self._sim_now = 0.0
        self._control_dt = 0.0
        self._step_index = 0
        self._step_label = ""
        self.mcap: artifacts.McapRecorder | None = None
        self._last_discover = 0.0

    # ----- time ------------------------------------------------------------------------
    def now(self) -> float:
        latest = self.clock.latest
        if latest is not None:
            self._sim_now = max(self._sim_now, artifacts.stamp_s(latest.clock))
        return self._sim_now

    def _call(self, client: Any, request: Any, what: str) -> Any:
        self.session.wait_for(client.service_is_ready, SERVICE_WALL_S, f"service {what}")
        return self.session.wait_future(client.call_async(request), SERVICE_WALL_S, f"response of {what}")

    def _step_sim(self, steps: int) -> float:
        done_before = sum(1 for handle in self.goals.values() if handle.done)
        response = self._call(self._step, StepSrv.Request(steps=steps), "/sim/step")
        if not response.success:
            raise StepFailure(f"/sim/step refused: {response.message}")
        self._sim_now = max(self._sim_now, response.sim_time)
        if response.goals_ended:
            # Goals ended in these steps: take their results before stepping on, so a goal's end is
            # seen at the same sim time in every run. (Bounded: a goal of another client ends too.)
            def arrived() -> bool:
                return sum(1 for handle in self.goals.values() if handle.done) >= done_before + response.goals_ended

            with contextlib.suppress(WaitTimeout):
                self.session.wait_for(arrived, GOAL_END_WALL_S, "the results of goals that ended")
        return float(response.sim_time)

    def start(self) -> None:
        """Wait for the sim (and servers), calibrate stepping, reset to the keyframe."""
        self.session.wait_for(self._reset.service_is_ready, STARTUP_WALL_S, "the /sim node (service /sim/reset)")
        if self.options.record:
            self.mcap = artifacts.McapRecorder(self.session, self.folder / "recording.mcap", exclude=self._unwatched)
            self.mcap.discover()
        for action in self.scenario.actions:
            client = ACTION_CLIENTS[action](self.session)
            try:
                client.wait_for_server(SERVICE_WALL_S)
            except Exception as error:  # noqa: BLE001 - any failure to reach a server ends the run as a StepFailure
                raise StepFailure(f"{error}") from None
            self.clients[action] = client
        if self.lock_step:
            t0 = self._step_sim(1)
            self._control_dt = self._step_sim(1) - t0
            if self._control_dt <= 0:
                raise StepFailure("/sim/step did not advance sim time; is the sim paused by someone else?")
            self._wait_recordings_flow()
        else:
            self.session.wait_for(lambda: self.clock.count > 0, STARTUP_WALL_S, "/clock")
        self._do_reset(self.scenario.keyframe)
        self.marks["start"] = self.now()
        if self.mcap is not None:
            self.mcap.discover()

    def _wait_recordings_flow(self) -> None:
        """Have the paused sim publish again until the recordings receive its streams (subscriptions matched).

        Messages published before a subscription is matched are not delivered; on a loaded machine the
        matching can take a while, and a run stepped as fast as possible would start without them.
        The sim is not stepped meanwhile: a reset to the keyframe (sim time kept) publishes every stream
        at once. So the scenario starts at the same sim time however long the matching took (stepping
        here made the start, and with it the publication grid under the run, depend on the machine's load).
        """
        def flowing() -> bool:
            mcap = self.mcap
            return (self.clock.count > 0 and self.joints.count > 0 and self.odom.count > 0
                    and (mcap is None or all(mcap.counts.get(t, 0) > 0 for t in ("/clock", "/joint_states"))))

        deadline = time.monotonic() + STARTUP_WALL_S
        while not flowing():
            if time.monotonic() > deadline:
                raise StepFailure("no /clock, /joint_states or /odom reached the runner while the paused sim republished")
            self._do_reset(self.scenario.keyframe)
            with contextlib.suppress(WaitTimeout):
                self.session.wait_for(flowing, 0.2, "the recordings to receive the sim's streams")

    def advance(self, dt: float) -> None:
        """Let about ``dt`` [s] of sim time pass, then check triggers."""
        target = self.now() + dt
        if self.lock_step:
            steps = max(1, round(dt / self._control_dt))
            self._pace(self._step_sim(steps))
        else:
            self.session.wait_for(lambda: self.now() >= target - 1e-9, max(10.0, 20.0 * dt / self.rtf), "sim time to advance")
        self._tick()

    def _pace(self, sim_now: float) -> None:
        """At ``rtf`` > 0, wait until ``sim_now`` is due on the wall clock (the run's rhythm, not a wait for an event)."""
        if self.rtf <= 0.0:
            return
        wall = time.monotonic()
        if self._pace_anchor is None:
            self._pace_anchor = (wall, sim_now)
            return
        wall0, sim0 = self._pace_anchor
        delay = wall0 + (sim_now - sim0) / self.rtf - wall
        if delay > 0.0:
            time.sleep(delay)

    def _elapsed(self) -> float:
        return self.now() - self.marks.get("start", 0.0)

    def _tick(self) -> None:
        now = self.now()
        for goal_id, handle in self.goals.items():
            if handle.done and f"{goal_id}.done" not in self.marks:
                self.marks[f"{goal_id}.done"] = now
                outcome = handle.outcome()
                self.progress.say(f"        goal {goal_id}: {outcome}  (t={self._elapsed():.2f} s)")
            trigger = self.cancel_triggers.get(goal_id)
            if trigger is not None and not handle.done:
                fire = (now - self.marks[f"{goal_id}.sent"] >= trigger.after - 1e-9 if trigger.after is not None
                        else self._condition_holds(trigger.when))
                if fire:
                    del self.cancel_triggers[goal_id]
                    self.progress.say(f"        cancel {goal_id} ({trigger.describe()}) at t={self._elapsed():.2f} s")
                    handle.cancel()
        if self.mcap is not None and time.monotonic() - self._last_discover > 1.0:
            self._last_discover = time.monotonic()
            self.mcap.discover()
        self.progress.update(self._status_line())

    def _status_line(self) -> str:
        total = len(self.scenario.steps)
        bar_len = 20
        filled = int(bar_len * self._step_index / max(total, 1))
        bar = f"[{'#' * filled}{'.' * (bar_len - filled)}]"
        text = f"{bar} step {self._step_index}/{total} {self._step_label}  t={self._elapsed():6.2f} s"
        for goal_id, handle in self.goals.items():
            if not handle.done and handle.feedback is not None:
                text += f"  {goal_id}: {_feedback_summary(handle.feedback)}"
        return text

    # ----- steps -----------------------------------------------------------------------
    def run_steps(self) -> None:
        for index, step in enumerate(self.scenario.steps):
            self._step_index = index + 1
            self._step_label = describe_step(step)
            if step.mark:
                self.marks[step.mark] = self.now()
            self.progress.say(f"  [{index + 1}/{len(self.scenario.steps)}] t={self._elapsed():6.2f} s  {self._step_label}")
            self._run_step(step)
            if self._elapsed() > self.scenario.timeout:
                raise StepFailure(f"the scenario ran past its timeout of {self.scenario.timeout:g} s of sim time")

    def _run_step(self, step: Step) -> None:
        """Carry out one step with the method its kind names in the registry (``StepKind.run``)."""
        run: Callable[[Step], None] = getattr(self, step_kind(step).run)
        run(step)

    def _run_reset(self, step: ResetStep) -> None:
        self._do_reset(step.keyframe or self.scenario.keyframe)

    def _run_wait(self, step: WaitStep) -> None:
        if step.duration is not None:
            self._wait_sim(step.duration)
        elif step.until is not None:
            condition = step.until
            self._wait_until(lambda: self._condition_holds(condition), step.timeout, f"until {condition.describe()}",
                             step.line)
        elif step.goal is not None:
            goal_id = step.goal
            self._wait_until(lambda: self.goals[goal_id].done, step.timeout, f"for goal {goal_id} to end", step.line)

    def _run_cancel(self, step: CancelStep) -> None:
        handle = self.goals[step.goal]
        accepted = handle.cancel()
        self.progress.say(f"        cancel {step.goal}: {'accepted' if accepted else 'not accepted (goal already ended?)'}")

    def _push_body(self, step: PushStep) -> None:
        response = self._call(self._push, push_request(step.body, step.force, step.torque, step.duration), "/sim/push")
        wanted = "refused" if step.refused else "applied"
        got = "applied" if response.success else "refused"
        self.progress.say(f"        push: {got}: {response.message}")
        self.param_verdicts.append(Verdict(f"{describe_step(step)} is {wanted}", got == wanted, wanted, got,
                                           detail=response.message, line=step.line))

    def _do_reset(self, keyframe: str) -> None:
        response = self._call(self._reset, Reset.Request(keyframe=keyframe), "/sim/reset")
        if not response.success:
            raise StepFailure(f"/sim/reset failed: {response.message}")
        self._sim_now = max(self._sim_now, response.sim_time)

    def _wait_sim(self, duration: float) -> None:
        end = self.now() + duration
        while self.now() < end - 1e-6:
            self.advance(min(CHUNK_S, end - self.now()))
            self._check_wall()

    def _wait_until(self, predicate: Callable[[], bool], timeout: float, what: str, line: int) -> None:
        start = self.now()
        while not predicate():
            if self.now() - start > timeout:
                raise StepFailure(f"line {line}: waited {timeout:g} s of sim time {what}")
            self.advance(CHUNK_S)
            self._check_wall()

    def _check_wall(self) -> None:
        if time.monotonic() - self._wall0 > self.scenario.wall_timeout:
            raise StepFailure(f"the run took longer than its wall_timeout of {self.scenario.wall_timeout:g} s")

    def _send_goal(self, step: SendGoalStep) -> None:
        client = self.clients[step.action]
        goal = _make_goal(step.action, step.goal)
        self.marks[f"{step.id}.sent"] = self.now()
        handle = client.send(goal, timeout=SERVICE_WALL_S)
        self.goals[step.id] = handle
        self.goal_actions[step.id] = step.action
        if not handle.accepted:
            self.marks[f"{step.id}.done"] = self.now()
            self.progress.say(f"        goal {step.id}: rejected by {client.name}")
            return
        if step.cancel is not None:
            self.cancel_triggers[step.id] = step.cancel
        if self.lock_step:
            # Deterministic start: the paused sim applies the goal at the sim time it was sent, and is
            # not stepped on until the goal runs (its first feedback, measured in /sim) or has ended.
            self.session.wait_for(lambda: handle.feedback is not None or handle.done, SERVICE_WALL_S,
                                  f"goal {step.id} to start in /sim")
        if step.wait:
            self._wait_until(lambda: handle.done, step.timeout, f"for the result of goal {step.id}", step.line)
            self._tick()

    def _set_param(self, step: SetParamStep) -> None:
        try:
            ok, reason = Parameters(self.session, step.node).set(step.name, step.value)
        except ParameterError as error:
            raise StepFailure(str(error)) from None
        self.param_events.append({"t": self._elapsed(), "node": step.node, "name": step.name, "value": step.value,
                                  "accepted": ok, "reason": reason})
        wanted = "refused" if step.refused else "accepted"
        got = "accepted" if ok else "refused"
        self.progress.say(f"        {step.node} {step.name} = {step.value!r}: {got}{': ' + reason if reason else ''}")
        self.param_verdicts.append(Verdict(f"set {step.node} {step.name} = {step.value!r} is {wanted}", got == wanted,
                                           wanted, got, detail=reason, line=step.line))

    def _cmd_vel_for(self, step: CmdVelStep) -> None:
        message = Twist()
        message.linear.x, message.linear.y, message.angular.z = step.vx, step.vy, step.wz
        end = self.now() + step.duration
        while self.now() < end - 1e-6:
            self._cmd_vel.publish(message)
            self.advance(min(CHUNK_S, end - self.now()))
            self._check_wall()
        self._cmd_vel.publish(Twist())

    # ----- what measures read (registry.Recorded) -------------------------------------------
    def mark_time(self, name: str | None, default: str) -> float:
        """Sim time [s] of mark ``name`` (``default`` when None); ``end`` is now until the run ends."""
        key = name or default
        if key == "end" and "end" not in self.marks:
            return self.now()
        if key not in self.marks:
            raise KeyError(f"mark {key!r} was not reached")
        return self.marks[key]

    def odom_series(self) -> artifacts.Series:
        return artifacts.odom_series(self.odom.messages())

    def object_series(self, name: str) -> artifacts.Series:
        return artifacts.object_series(self.objects.messages(), name)

    def joint_series(self) -> tuple[list[str], artifacts.Series]:
        return artifacts.joint_series(self.joints.messages())

    def goal_handle(self, goal_id: str) -> GoalHandle[Any, Any] | None:
        return self.goals.get(goal_id)

    def parameter(self, node: str, name: str) -> Any:
        try:
            return Parameters(self.session, node).get(name)
        except (ParameterError, WaitTimeout):
            return None

    def measure(self, measure: Measure) -> Any:
        """The value of a measure now (or at its marks); None when it cannot be measured."""
        return measure.evaluate(self)

    def _condition_holds(self, condition: Condition | None) -> bool:
        if condition is None:
            return False
        try:
            return condition.comparison.holds(self.measure(condition.measure))
        except KeyError:
            return False

    def judge(self, expectation: Expectation) -> Verdict:
        if expectation.outcome_goal is not None:
            handle = self.goals.get(expectation.outcome_goal)
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
            value = self.measure(expectation.measure)
            detail = ""
        except KeyError as error:
            value, detail = None, str(error).strip("'\"")
        comparison: Comparison = expectation.comparison
        ok = comparison.holds(value)
        if value is None and not detail:
            detail = "nothing was measured"
        return Verdict(expectation.name, ok, f"{expectation.measure.kind} {comparison.describe()}", value,
                       expectation.measure.unit, detail, expectation.line)

    # ----- the whole run -------------------------------------------------------------------
    def execute(self) -> RunResult:
        self._wall0 = time.monotonic()
        scenario = self.scenario
        mode = ("lock-stepped, as fast as possible" if self.rtf == 0.0
                else f"lock-stepped at real-time factor {self.rtf:g}" if self.lock_step
                else f"free-running at real-time factor {self.rtf:g}")
        self.progress.say(f"scenario {scenario.name} ({scenario.robot}, seed {scenario.seed}, {mode})")
        sim_start = 0.0
        run_wall0 = self._wall0
        try:
            self.start()
            sim_start = self.now()
            run_wall0 = time.monotonic()
            self.run_steps()
        except (StepFailure, WaitTimeout) as error:
            self.failures.append(str(error))
            self.progress.say(f"  step failed: {error}")
        except Exception as error:  # noqa: BLE001 - any error ends the run as a failure with a report
            self.failures.append(f"{type(error).__name__}: {error}")
            self.progress.say(f"  error: {type(error).__name__}: {error}")
        self.marks.setdefault("end", self.now())
        run_wall = time.monotonic() - run_wall0
        self._settle_records()
        verdicts = [*self.param_verdicts, *(self.judge(e) for e in scenario.expectations)]
        self._finish_goals()
        sim = self.marks["end"] - sim_start
        passed = not self.failures and all(v.passed for v in verdicts)
        self.progress.say("")
        for verdict in verdicts:
            self.progress.say("  " + verdict.line_text())
        for failure in self.failures:
            self.progress.say(f"  FAIL  {failure}")
        result = RunResult(scenario.name, passed, verdicts, list(self.failures), run_wall, sim, self.folder,
                           startup_time=run_wall0 - self._wall0)
        result.report = self._report(result)
        return result

    def _settle_records(self) -> None:
        """Let the last published state reach the measures and the recording (deadline, not a sleep).

        Bursts of a lock-stepped run can still be in flight when the last step returns; a reliable
        reader gets each topic in order, so its newest stamp reaching the end means nothing is missing.
        /clock and /joint_states are published at every stepping stop, so in lock-step they reach the
        end exactly; /odom may lag one period.
        """
        end = self.marks["end"]
        exact = 1e-6 if self.lock_step else 0.05

        def latest_s(recorder: TopicRecorder[Any]) -> float:
            latest = recorder.latest
            return -math.inf if latest is None else artifacts.stamp_s(latest.header.stamp)

        def arrived() -> bool:
            if latest_s(self.odom) < end - 0.05 or latest_s(self.joints) < end - exact:
                return False
            mcap = self.mcap
            if mcap is None:
                return True
            return all(mcap.latest_stamp_s.get(topic, -math.inf) >= end - exact
                       for topic in ("/clock", "/joint_states") if topic in mcap.counts)

        with contextlib.suppress(WaitTimeout):
            self.session.wait_for(arrived, 10.0, "the final /odom, /joint_states and /clock")

    def _finish_goals(self) -> None:
        for goal_id, handle in self.goals.items():
            if not handle.done:
                self.progress.say(f"        goal {goal_id} still running at the end: canceling it")
                try:
                    handle.cancel()
                    if self.lock_step:
                        deadline = time.monotonic() + 10.0
                        while not handle.done and time.monotonic() < deadline:
                            self._step_sim(max(1, round(CHUNK_S / self._control_dt)))
                    else:
                        self.session.wait_for(lambda: handle.done, 10.0, f"goal {goal_id} to end after cancel")  # noqa: B023 - called at once
                except (StepFailure, WaitTimeout):
                    pass

    def _report(self, result: RunResult) -> dict[str, Any]:
        goals = {}
        for goal_id, handle in self.goals.items():
            outcome = handle.outcome()
            goals[goal_id] = {
                "action": self.goal_actions[goal_id],
                "accepted": handle.accepted,
                "status": outcome.status if outcome else "RUNNING",
                "error_code": outcome.error_code if outcome else None,
                "error_name": outcome.error_name if outcome else None,
                "error_msg": outcome.error_msg if outcome else "",
                "sent_at": self.marks.get(f"{goal_id}.sent", 0.0) - self.marks.get("start", 0.0),
                "done_at": self.marks.get(f"{goal_id}.done", math.nan) - self.marks.get("start", 0.0),
                "feedback_count": len(handle.feedback_history),
                "last_feedback": artifacts.msg_to_dict(handle.feedback) if handle.feedback is not None else None,
                "result": artifacts.msg_to_dict(outcome.result) if outcome and outcome.result is not None else None,
            }
        start = self.marks.get("start", 0.0)
        return {
            "scenario": self.scenario.name,
            "file": str(self.scenario.path),
            "description": self.scenario.description,
            "robot": self.scenario.robot,
            "scene": self.scenario.scene,
            "seed": self.scenario.seed,
            "mode": "lock-step" if self.lock_step else "free-run",
            "real_time_factor": self.rtf,
            "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "passed": result.passed,
            "startup_wall_s": round(result.startup_time, 3),
            "wall_time_s": round(result.wall_time, 3),
            "sim_time_s": round(result.sim_time, 3),
            "started_at_sim_s": start,  # the sim time the scenario started at (the same in every run)
            "wall_per_sim": round(result.wall_time / result.sim_time, 3) if result.sim_time > 0 else None,
            "expectations": [asdict(v) for v in result.verdicts],
            "failures": result.failures,
            "marks": {k: round(v - start, 4) for k, v in self.marks.items()},
            "goals": goals,
            "parameters": self.param_events,
            "artifacts": {},
        }


# ----- goals from scenario data -------------------------------------------------------------
def _make_goal(action: str, g: dict[str, Any]) -> Any:
    """The goal message of ``action`` from the goal fields of a send_goal step (``ActionKind.make_goal``)."""
    return ACTIONS[action].make_goal(ACTION_CLIENTS[action], g)


def _feedback_summary(feedback: Any) -> str:
    parts = []
    for name in ("stage_name", "distance_walked", "current_speed", "distance_remaining", "position_error", "percent_complete"):
        value = getattr(feedback, name, None)
        if isinstance(value, str) and value:
            parts.append(value)
        elif isinstance(value, (int, float)):
            parts.append(f"{name}={value:.3g}")
    return " ".join(parts)


# ----- entry point --------------------------------------------------------------------------
def run_folder(base: pathlib.Path, name: str) -> pathlib.Path:
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    folder = base / f"{name}-{stamp}"
    n = 1
    while folder.exists():
        n += 1
        folder = base / f"{name}-{stamp}-{n}"
    folder.mkdir(parents=True)
    return folder


def run(scenario: Scenario, options: RunOptions = RunOptions(), stream: TextIO = sys.stdout) -> RunResult:
    """Bring up ``bringup --robot R`` (paused for lock-stepping), run the scenario, write artifacts."""
    folder = run_folder(options.out, scenario.name)
    rtf = scenario.rtf if options.rtf is None else options.rtf
    args = ["bringup", "--robot", scenario.robot, "--scene", scenario.scene, "--rtf", f"{rtf:g}", "--paused"]
    with RosSession("scenario_runner", use_sim_time=True) as session:
        if options.launch:
            with running(args, log_dir=folder) as process:
                run_ = ScenarioRun(scenario, session, options, folder, stream)
                result = run_.execute()
                if not process.alive():
                    result.failures.append(f"bringup exited early with code {process.process.returncode}; see {process.log_path}")
                    result.passed = False
                    result.report["passed"] = False
                    result.report["failures"] = result.failures
                _write_artifacts(run_, result, stream)
        else:
            run_ = ScenarioRun(scenario, session, options, folder, stream)
            result = run_.execute()
            _write_artifacts(run_, result, stream)
    return result


def _write_artifacts(run_: ScenarioRun, result: RunResult, stream: TextIO) -> None:
    folder = result.folder
    paths: dict[str, str | list[str]] = {}  # artifact kind -> path; "plots" -> a list of paths
    if run_.mcap is not None:
        run_.mcap.close()
        paths["mcap"] = str(run_.mcap.path)
        result.report["mcap_topics"] = dict(sorted(run_.mcap.counts.items()))
    start, end = run_.marks.get("start", 0.0), run_.marks.get("end", 0.0)
    if run_.options.plots:
        from sim_client.scenario import plots

        try:
            plot_paths = [str(plot) for plot in plots.make_plots(run_, folder)]
            if plot_paths:
                paths["plots"] = plot_paths
        except Exception as error:  # noqa: BLE001 - an artifact failing must not hide the verdicts
            result.report.setdefault("artifact_errors", []).append(f"plots: {type(error).__name__}: {error}")
    if run_.camera_images is not None and end > start:
        try:
            from sim_client.scenario import camera_sheet

            sheet = camera_sheet.make_sheet(run_.camera_images.messages(), start, end, folder / "camera.png",
                                            f"{run_.scenario.name}: /{run_.camera_name}/image_raw")
            if sheet is not None:
                paths["camera"] = str(sheet)
        except Exception as error:  # noqa: BLE001 - an artifact failing must not hide the verdicts
            result.report.setdefault("artifact_errors", []).append(f"camera: {type(error).__name__}: {error}")
    if run_.options.video and end > start:
        try:
            from sim_client.scenario import render

            render.render_video(render.recorded_run(run_), folder / "video.mp4")
            paths["video"] = str(folder / "video.mp4")
        except Exception as error:  # noqa: BLE001 - an artifact failing must not hide the verdicts
            result.report.setdefault("artifact_errors", []).append(f"video: {type(error).__name__}: {error}")
    paths["report"] = str(folder / "report.json")
    result.report["artifacts"] = paths
    artifacts.write_json(folder / "report.json", result.report)
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
