"""One run of one scenario against nodes reachable through a session: the steps carried out, the goals followed.

:class:`ScenarioRun` records what measures read (:class:`~sim_client.scenario.model.measures.Recorded`)
and carries out what steps ask (:class:`~sim_client.scenario.model.steps.StepRunner`); sim time passes
through :class:`~sim_client.scenario.running.sim_time.SimTime`, in chunks, with triggers and conditions
checked between chunks.
"""

from __future__ import annotations

import contextlib
import math
import pathlib
import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image, JointState

import robot_models
from sim_client.actions import ACTION_CLIENTS, GoalHandle, SimActionClient, feedback_elapsed_s, push_request
from sim_client.parameters import ParameterError, Parameters
from sim_client.scenario.model.actions import ACTIONS
from sim_client.scenario.model.conditions import Condition, Trigger
from sim_client.scenario.model.schema import Scenario
from sim_client.scenario.model.series import Series, joint_series, object_series, odom_series, stamp_s
from sim_client.scenario.model.steps import CmdVelStep, PushStep, SendGoalStep, SetParamStep, describe_step, step_kind
from sim_client.scenario.outputs.recorder_process import RecordingError, RecordingProcess
from sim_client.scenario.running import sim_time
from sim_client.scenario.running.bringups import ParameterKeeper
from sim_client.scenario.running.options import RunOptions
from sim_client.scenario.running.progress import Progress, feedback_summary
from sim_client.scenario.running.report import RunResult, Verdict, build_report, judge
from sim_client.scenario.running.run_clients import RunClients
from sim_client.scenario.running.sim_time import SERVICE_WALL_S, STARTUP_WALL_S, SimTime, StepFailure, call_service
from sim_interfaces.msg import LocomotionState, ObjectStates
from sim_interfaces.srv import Push, Reset
from sim_ros.names import ODOM_TOPIC, STREAMS, TF_TOPIC
from sim_ros.session import RESEND_S, RosSession, TopicRecorder, WaitTimeout

CAMERA_FRAMES_KEPT = 3000  # camera images kept for camera.png (~0.7 GB at 320x240 at most)


class ScenarioRun:
    """One run of one scenario against nodes reachable through ``session``."""

    def __init__(self, scenario: Scenario, session: RosSession, options: RunOptions, folder: pathlib.Path,
                 stream: TextIO = sys.stdout, parameters: ParameterKeeper | None = None,
                 clients: RunClients | None = None) -> None:
        self.scenario = scenario
        self.session = session
        self.run_clients = clients if clients is not None else RunClients(session)  # shared by a bring-up's runs
        self.options = options
        self.folder = folder
        self.rtf = scenario.rtf if options.rtf is None else options.rtf
        self.lock_step = options.launch or self.rtf == 0.0
        self.progress = Progress(stream, options.quiet)
        self.goals: dict[str, GoalHandle] = {}
        self.time = SimTime(session, self.lock_step, self.rtf, lambda: sum(1 for h in self.goals.values() if h.done))
        # Measures read every sample: a reader's history as deep as the writer's, so that a burst of a
        # lock-stepped stride waiting behind a busy spin thread is not overwritten (with a depth of 10, a
        # loaded machine lost a stand's lowest /odom sample: its base_height_min differed run to run).
        self.odom = session.record(Odometry, "odom", qos=STREAMS, keep=1_000_000, serialized=True)
        self.joints = session.record(JointState, "joint_states", qos=STREAMS, keep=1_000_000, serialized=True)
        self.objects = session.record(ObjectStates, "objects", qos=STREAMS, keep=1_000_000, serialized=True)
        # commanded vs measured speed, for the speed plot only: a run without plots carries no extra traffic
        self.locomotion = session.record(LocomotionState, "sim/locomotion_state", qos=STREAMS,
                                         keep=1_000_000) if options.plots else None
        # /sim renders a camera only while it is watched: a run watches (and records) it only when asked.
        cameras = [camera.name for camera in robot_models.cameras_of(scenario.robot)]
        self.camera_name = cameras[0] if options.camera and cameras else ""
        self.camera_images = (session.record(Image, f"{self.camera_name}/image_raw", keep=CAMERA_FRAMES_KEPT)
                              if self.camera_name else None)
        self.streams = (f"{session.namespace}/clock", f"{session.namespace}/joint_states")  # full names, as recorded
        self._unwatched = tuple(f"{session.namespace}/{name}/{topic}" for name in cameras if name != self.camera_name
                                for topic in ("image_raw", "camera_info"))
        self._reset = session.service_client(Reset, "sim/reset")
        self._push = session.service_client(Push, "sim/push")
        self._cmd_vel = self.run_clients.publisher(Twist, "cmd_vel")
        self.clients: dict[str, SimActionClient] = {}
        self.goal_actions: dict[str, str] = {}
        self.cancel_triggers: dict[str, Trigger] = {}
        self.marks: dict[str, float] = {}
        self.param_events: list[dict[str, Any]] = []
        self.param_verdicts: list[Verdict] = []
        self.warnings: list[str] = []  # waits that ran out without failing the run
        self.failures: list[str] = []
        self._step_index = 0
        self._step_label = ""
        self._wall0 = 0.0  # wall time [s] the run started at, set by execute()
        self.mcap: RecordingProcess | None = None  # recording.mcap, written by a process of its own
        self._kept_parameters = parameters  # the bring-up's start-up values, read before a node's first change

    def now(self) -> float:
        """The run's sim time [s]."""
        return self.time.now()

    # ----- start -----------------------------------------------------------------------
    def start(self) -> None:
        """Wait for the sim (and servers), calibrate stepping, reset to the keyframe."""
        if self.options.record:  # started first: its start-up overlaps the waits for the nodes below
            self.mcap = RecordingProcess(self.folder / "recording.mcap", exclude=self._unwatched,
                                         namespace=self.session.namespace, lock_step=self.lock_step)
        self.session.wait_for(self._reset.service_is_ready, STARTUP_WALL_S, "the /sim node (service /sim/reset)")
        if self.mcap is not None:
            self.mcap.discover()
        for action in self.scenario.actions:
            client = self.run_clients.action(action)
            try:
                client.wait_for_server(SERVICE_WALL_S)
            except Exception as error:  # noqa: BLE001 - any failure to reach a server ends the run as a StepFailure
                raise StepFailure(f"{error}") from None
            self.clients[action] = client
        if self.lock_step or self.mcap is not None:
            self._wait_recordings_flow()
        # After the recordings flow: a watched camera renders its first frame in these steps, when the recorder has
        # matched both its topics (a frame rendered before, in a parallel test run, was recorded without its
        # camera_info).
        self.time.calibrate()
        self.reset(None)
        self.marks["start"] = self.now()
        if self.mcap is not None:
            self.mcap.discover()

    def _wait_recordings_flow(self) -> None:
        """Have the paused sim publish again until the recordings receive its streams (subscriptions matched).

        Messages published before a subscription is matched are not delivered; on a loaded machine the
        matching can take a while, and a run stepped as fast as possible would start without them.
        The sim is not stepped meanwhile: a reset to the keyframe (sim time kept) publishes every stream
        at once. So the scenario starts at the same sim time however long the matching took. A recorded run
        also waits here for its recorder process to have matched the streams, stepped or free-running.
        """
        # The recorder must have /sim's other streams too (each republished by the reset): a short run stepped as
        # fast as possible on a loaded machine once ended before the recorder had matched /tf (an MCAP without it).
        # /odom and /tf, when the runner sees them published (/objects is not required: its writer exists in a
        # scene without objects, which never publishes).
        namespace = self.session.namespace
        recorded = (*self.streams, *(topic for topic in (f"{namespace}/{ODOM_TOPIC}", f"{namespace}/{TF_TOPIC}")
                                     if self.mcap is not None and self.session.node.count_publishers(topic) > 0))
        # The watched camera publishes only when stepped: its two topics matched by the recorder's subscriptions.
        camera = tuple(f"{namespace}/{self.camera_name}/{topic}" for topic in ("image_raw", "camera_info")
                       if self.mcap is not None and self.camera_name)

        def flowing() -> bool:
            if not (self.time.clock.count > 0 and self.joints.count > 0 and self.odom.count > 0):
                return False
            if self.mcap is None:
                return True
            status = self.mcap.status()
            return all(status.counts.get(t, 0) > 0 for t in recorded) and all(status.matched.get(t, 0) > 0 for t in camera)

        deadline = time.monotonic() + STARTUP_WALL_S
        while not flowing():
            if time.monotonic() > deadline:
                raise StepFailure("no /clock, /joint_states or /odom reached the runner while the paused sim republished"
                                  if self.mcap is None else "the runner or the recorder did not receive /sim's streams "
                                  f"({', '.join((*recorded, *camera))}) while the paused sim republished")
            self.reset(None)
            with contextlib.suppress(WaitTimeout):
                self.session.wait_for(flowing, 0.2, "the recordings to receive the sim's streams")

    # ----- time passing ----------------------------------------------------------------
    def advance(self, dt: float) -> None:
        """Let about ``dt`` [s] of sim time pass, then check triggers."""
        self.time.advance(dt)
        self._recorder_keeps_up()
        self._tick()

    def _recorder_keeps_up(self) -> None:
        """Lock-stepped and recording the camera, wait until the recorder has the newest frame this run has, and its info.

        The camera's writer keeps its last 4 frames (0.4 s of sim time at 10 Hz) for a reader that lags; a
        recorder process that fell further behind /sim, stepped as fast as possible on a loaded machine, lost
        frames (29 of 33 in a parallel test run). Waiting for it here holds /sim back as a reader in the
        runner's own process did. The other streams' writers keep 10 s of sim time.
        """
        images, mcap = self.camera_images, self.mcap
        if not self.lock_step or images is None or mcap is None or (latest := images.latest) is None:
            return
        frame_s = stamp_s(latest.header.stamp)
        topics = [f"{self.session.namespace}/{self.camera_name}/{name}" for name in ("image_raw", "camera_info")]
        self.session.wait_for(lambda: all(mcap.status().latest_stamp_s.get(t, -math.inf) >= frame_s - 1e-9 for t in topics),
                              SERVICE_WALL_S, f"the recorder to take the frame at {frame_s:.2f} s and its camera_info")

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
                        else self.condition_holds(trigger.when))
                if fire:
                    del self.cancel_triggers[goal_id]
                    self.progress.say(f"        cancel {goal_id} ({trigger.describe()}) at t={self._elapsed():.2f} s")
                    handle.cancel()
        self.progress.update(self._status_line())

    def _status_line(self) -> str:
        total = len(self.scenario.steps)
        bar_len = 20
        filled = int(bar_len * self._step_index / max(total, 1))
        bar = f"[{'#' * filled}{'.' * (bar_len - filled)}]"
        text = f"{bar} step {self._step_index}/{total} {self._step_label}  t={self._elapsed():6.2f} s"
        for goal_id, handle in self.goals.items():
            if not handle.done and handle.feedback is not None:
                text += f"  {goal_id}: {feedback_summary(handle.feedback)}"
        return text

    def _stride(self, checks_measures: bool) -> float:
        """Sim time [s] to advance before the next check: ``CHUNK_S`` while a condition on measures is watched, else a
        stride (``sim_time``: goal ends need no short chunks, a lock-stepped /sim stops its step where a goal ended),
        ending where the next cancel trigger with a delay falls due."""
        if not self.lock_step or checks_measures or any(t.when is not None for t in self.cancel_triggers.values()):
            return sim_time.CHUNK_S
        short = self.rtf > 0.0 or (self.camera_images is not None and self.mcap is not None)
        stride = sim_time.SHORT_STRIDE_S if short else sim_time.STRIDE_S
        for goal_id, trigger in self.cancel_triggers.items():
            if trigger.after is not None:
                stride = min(stride, self.marks[f"{goal_id}.sent"] + trigger.after - self.now())
        return max(stride, 0.0)

    def wait_sim(self, duration: float) -> None:
        end = self.now() + duration
        while self.now() < end - 1e-6:
            self.advance(min(self._stride(False), end - self.now()))
            self._check_wall()

    def wait_until(self, predicate: Callable[[], bool], timeout: float, what: str, line: int,
                   checks_measures: bool = True) -> None:
        start = self.now()
        while not predicate():
            if self.now() - start > timeout:
                raise StepFailure(f"line {line}: waited {timeout:g} s of sim time {what}")
            self.advance(min(self._stride(checks_measures), start + timeout - self.now() + sim_time.CHUNK_S))
            self._check_wall()

    def _check_wall(self) -> None:
        if time.monotonic() - self._wall0 > self.scenario.wall_timeout:
            raise StepFailure(f"the run took longer than its wall_timeout of {self.scenario.wall_timeout:g} s")

    # ----- steps (model.steps.StepRunner) ----------------------------------------------
    def run_steps(self) -> None:
        for index, step in enumerate(self.scenario.steps):
            self._step_index = index + 1
            self._step_label = describe_step(step)
            if step.mark:
                self.marks[step.mark] = self.now()
            self.progress.say(f"  [{index + 1}/{len(self.scenario.steps)}] t={self._elapsed():6.2f} s  {self._step_label}")
            step_kind(step).run(self, step)
            if self._elapsed() > self.scenario.timeout:
                raise StepFailure(f"the scenario ran past its timeout of {self.scenario.timeout:g} s of sim time")

    def reset(self, keyframe: str | None) -> None:
        # Lock-stepped (/sim paused), sent again until answered (rmw drops an answer to a client not matched yet): the same state.
        running = sum(1 for handle in self.goals.values() if not handle.done)  # each ends (SIM_FAULT)
        response = call_service(self.session, self._reset, Reset.Request(keyframe=keyframe or self.scenario.keyframe),
                                "/sim/reset", resend_every_s=RESEND_S if self.lock_step else None)
        if not response.success:
            raise StepFailure(f"/sim/reset failed: {response.message}")
        self.time.reached(response.sim_time)
        self.time.take_results(len(self.goals) - running, running)

    def goal_done(self, goal_id: str) -> bool:
        return self.goals[goal_id].done

    def cancel_goal(self, goal_id: str) -> None:
        accepted = self.goals[goal_id].cancel()
        self.progress.say(f"        cancel {goal_id}: {'accepted' if accepted else 'not accepted (goal already ended?)'}")

    def send_goal(self, step: SendGoalStep) -> None:
        client = self.clients[step.action]
        goal = ACTIONS[step.action].make_goal(ACTION_CLIENTS[step.action], step.goal)
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
            self.wait_until(lambda: handle.done, step.timeout, f"for the result of goal {step.id}", step.line,
                            checks_measures=False)
            self._tick()

    def set_param(self, step: SetParamStep) -> None:
        try:
            if self._kept_parameters is not None:
                self._kept_parameters.remember(self.session, step.node)
            ok, reason = Parameters(self.session, step.node).set(step.name, step.value)
        except ParameterError as error:
            raise StepFailure(str(error)) from None
        except WaitTimeout as error:
            raise StepFailure(f"{error}; is {step.node} running?") from None
        self.param_events.append({"t": self._elapsed(), "node": step.node, "name": step.name, "value": step.value,
                                  "accepted": ok, "reason": reason})
        wanted = "refused" if step.refused else "accepted"
        got = "accepted" if ok else "refused"
        self.progress.say(f"        {step.node} {step.name} = {step.value!r}: {got}{': ' + reason if reason else ''}")
        self.param_verdicts.append(Verdict(f"set {step.node} {step.name} = {step.value!r} is {wanted}", got == wanted,
                                           wanted, got, detail=reason, line=step.line))

    def push(self, step: PushStep) -> None:
        response = call_service(self.session, self._push, push_request(step.body, step.force, step.torque, step.duration),
                                "/sim/push")
        wanted = "refused" if step.refused else "applied"
        got = "applied" if response.success else "refused"
        self.progress.say(f"        push: {got}: {response.message}")
        self.param_verdicts.append(Verdict(f"{describe_step(step)} is {wanted}", got == wanted, wanted, got,
                                           detail=response.message, line=step.line))

    def drive(self, step: CmdVelStep) -> None:
        message = Twist()
        message.linear.x, message.linear.y, message.angular.z = step.vx, step.vy, step.wz
        end = self.now() + step.duration
        while self.now() < end - 1e-6:
            self._cmd_vel.publish(message)
            self.advance(min(sim_time.CHUNK_S, end - self.now()))
            self._check_wall()
        self._cmd_vel.publish(Twist())

    # ----- what measures read (model.measures.Recorded) --------------------------------
    def mark_time(self, name: str | None, default: str) -> float:
        """Sim time [s] of mark ``name`` (``default`` when None); ``end`` is now until the run ends."""
        key = name or default
        if key == "end" and "end" not in self.marks:
            return self.now()
        if key not in self.marks:
            raise KeyError(f"mark {key!r} was not reached")
        return self.marks[key]

    def odom_series(self) -> Series:
        return odom_series(self.odom.messages())

    def object_series(self, name: str) -> Series:
        return object_series(self.objects.messages(), name)

    def joint_series(self) -> tuple[list[str], Series]:
        return joint_series(self.joints.messages())

    def goal_handle(self, goal_id: str) -> GoalHandle[Any, Any] | None:
        return self.goals.get(goal_id)

    def parameter(self, node: str, name: str) -> Any:
        try:
            return Parameters(self.session, node).get(name)
        except (ParameterError, WaitTimeout):
            return None

    def condition_holds(self, condition: Condition | None) -> bool:
        if condition is None:
            return False
        try:
            return condition.comparison.holds(condition.measure.evaluate(self))
        except KeyError:
            return False

    def close(self) -> None:
        """Stop this run's recordings (the session, shared by the next runs on the bring-up, goes on)."""
        mine = [r for r in (self.odom, self.joints, self.objects, self.locomotion, self.camera_images, self.time.clock)
                if r is not None]
        for recorder in mine:
            recorder.stop()
        self.session.recorders[:] = [r for r in self.session.recorders if all(r is not m for m in mine)]

    # ----- the whole run ---------------------------------------------------------------
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
        verdicts = [*self.param_verdicts, *(judge(self, e) for e in scenario.expectations)]
        self._finish_goals()
        sim = self.marks["end"] - sim_start
        passed = not self.failures and all(v.passed for v in verdicts)
        self.progress.say("")
        for verdict in verdicts:
            self.progress.say("  " + verdict.line_text())
        for failure in self.failures:
            self.progress.say(f"  FAIL  {failure}")
        result = RunResult(scenario.name, passed, verdicts, list(self.failures), run_wall, sim, self.folder,
                           startup_time=run_wall0 - self._wall0,
                           feedback={goal_id: handle.feedback_history for goal_id, handle in self.goals.items()})
        result.report = build_report(self, result)
        return result

    def _settle_records(self) -> None:
        """Let the last published state reach the measures and the recording (deadline, not a sleep).

        Bursts of a lock-stepped run can still be in flight when the last step returns; a reliable
        reader gets each topic in order, so its newest stamp reaching the last publication at or before
        the end means nothing is missing. /sim publishes /clock and /joint_states on their own grids
        (``clock_rate``, ``joint_state_rate``), so a step that ends between two publications leaves the
        last one up to a period before the end; /odom may lag one period. A wait that runs out is said
        in the run's output and report, never swallowed.
        """
        end = self.marks["end"]
        exact = 1e-6
        periods = {topic: 1.0 / rate for topic, name in zip(self.streams, ("clock_rate", "joint_state_rate"), strict=True)
                   if self.lock_step and isinstance(rate := self.parameter("sim", name), int | float) and rate > 0}
        slack = {topic: periods.get(topic, 0.05) + exact for topic in self.streams}
        rates = {name: self.parameter("sim", name) for name in sim_time.STREAM_RATES} if self.mcap and self.lock_step else {}
        rate_periods = {name: 1.0 / rate for name, rate in rates.items() if isinstance(rate, int | float) and rate > 0}

        feedback_due = self._feedback_due(end)

        def latest_s(recorder: TopicRecorder[Any]) -> float:
            latest = recorder.latest
            return -math.inf if latest is None else stamp_s(latest.header.stamp)

        def arrived() -> bool:
            if latest_s(self.odom) < end - 0.05 or latest_s(self.joints) < end - slack[self.streams[1]]:
                return False
            if not all(handle.done or (feedback_elapsed_s(handle.feedback) or 0.0) >= due for handle, due in feedback_due):
                return False
            if self.mcap is None:
                return True
            recorded = self.mcap.status()
            # /sim's other periodic streams too: after a long stride's burst, on a loaded machine, /imu once trailed by 2.4 s.
            waits = {**slack, **sim_time.stream_slack(recorded.counts, rate_periods, self.session.namespace)}
            return all(recorded.latest_stamp_s.get(topic, -math.inf) >= end - period for topic, period in waits.items()
                       if recorded.counts.get(topic, 0) > 0)

        try:
            self.session.wait_for(arrived, 10.0, "the final /odom, /joint_states, /clock and goal feedback")
        except (WaitTimeout, RecordingError) as error:
            self.warnings.append(f"{error}: measures and the recording may miss the run's last state")
            self.progress.say(f"  WARN  {self.warnings[-1]}")

    def _feedback_due(self, end: float) -> list[tuple[GoalHandle, float]]:
        """Lock-stepped, each goal still running at ``end`` and the ``elapsed`` its feedback reaches by then.

        A server relays /sim's measured feedback from its own process, from the goal states /sim publishes
        every 1/``state_rate``, one at most every ``feedback_rate`` of sim time: the last messages of a run
        can still be on their way when the last step returns (a feedback measure once read a walk's
        distance from long before the end, on a loaded machine). The last one relayed by ``end`` is at most
        a feedback period and a state period older.
        """
        due: list[tuple[GoalHandle, float]] = []
        running = {goal_id: handle for goal_id, handle in self.goals.items()
                   if handle.accepted and not handle.done and feedback_elapsed_s(handle.feedback) is not None}
        state_rate = self.parameter("sim", "state_rate") if self.lock_step and running else None
        if not isinstance(state_rate, int | float) or state_rate <= 0:
            return due
        for goal_id, handle in running.items():
            period = self.clients[self.goal_actions[goal_id]].feedback_period_s()
            if period is not None:
                due.append((handle, end - self.marks[f"{goal_id}.sent"] - period - 1.0 / state_rate - 1e-6))
        return due

    def _finish_goals(self) -> None:
        for goal_id, handle in self.goals.items():
            if not handle.done:
                self.progress.say(f"        goal {goal_id} still running at the end: canceling it")
                try:
                    handle.cancel()
                    if self.lock_step:
                        deadline = time.monotonic() + 10.0
                        while not handle.done and time.monotonic() < deadline:
                            self.time.step(self.time.steps_for(sim_time.CHUNK_S))
                    else:
                        self.session.wait_for(lambda: handle.done, 10.0, f"goal {goal_id} to end after cancel")  # noqa: B023 - called at once
                except (StepFailure, WaitTimeout):
                    pass
