"""One generic action server over the goal protocol: validate, send, relay, end.

:class:`SkillActionServer` serves one action whose goals run as a skill inside ``/sim``. It
validates a goal with the binding's own validation (the same function ``/sim`` runs), sends it as a
START, relays the skill's measured feedback (at ``feedback_rate`` of sim time, the first one at
once), forwards a cancel as a CANCEL, and ends the goal with the Result ``/sim`` filled in (the state
says SUCCEEDED, ABORTED or CANCELED). It knows of a reset because ``/sim`` ends the goal with the
reset epoch in its state. A goal waits without holding a thread (``async`` execute, parked).
"""

from __future__ import annotations

import itertools
import os
import threading
import time
import traceback
import weakref
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.task import Future

from nodes.runtime.executor import wait_parked
from nodes.servers.protocol import BINDINGS, SkillBinding, result_codes
from nodes.servers.world import follow_world
from robot_models import RobotSpec
from sim_bridge.errors import InvalidGoalError
from sim_interfaces.msg import SkillCommand, SkillState
from sim_ros.names import FEEDBACK_QOS, SKILL_COMMAND_TOPIC, SKILL_QOS, SKILL_STATE_TOPIC
from sim_ros.stamps import seconds_of

ACK_TIMEOUT_S = 10.0  # wall seconds for /sim to report a goal it was sent
CANCEL_ACK_S = 2.0  # wall seconds a cancel request waits for /sim to report it has taken the cancel
SIM_MATCH_S = 10.0  # wall seconds a server waits at start-up for /sim's goal topics to match
RESEND_PERIOD_S = 0.1  # a START not yet reported is sent again (a message sent before discovery is lost)
# /sim publishes each running goal's state at least every 0.2 s of wall time, paused or not
# (nodes.sim.skills.HEARTBEAT_PERIOD_S): this long without a word, it has stopped or died.
# 5 s, not 2: on a loaded 2-core machine a running /sim was seen silent for 1.9 s (a fresh-clone test run
# beside four other simulations), and a goal ended SIM_FAULT though /sim lived.
SIM_SILENCE_S = 5.0
# The watchdog runs every RESEND_PERIOD_S; a longer gap means this server itself was starved of CPU
# (states from /sim may be queued unread): the gap is not counted as /sim's silence.
STARVED_GAP_S = 0.5
# The goal, cancel and result services keep this many requests (and responses) for a slow reader, as
# rclpy's parameter services do (qos_profile_parameters). Every client's requests share the server's one
# request reader: with ROS's services default (keep-last 10), a burst the executor has not yet taken
# overwrites its oldest requests, which are then never answered.
SERVICE_QOS = QoSProfile(depth=1000)
# Feedback of a fast (unpaced) sim comes in bursts: a writer history of ROS's default 10 would drop the
# feedback of a short stage before a slow client acknowledged it. A client that keeps as many gets each one.
GOODBYE_WALL_S = 2.0  # [s] a stopping server spends at most this long getting its goals' results out
RESULT_GRACE_S = 0.2  # [s] after its goals' callbacks returned, for the result responses to go out
_TERMINAL = frozenset((SkillState.SUCCEEDED, SkillState.ABORTED, SkillState.CANCELED))
_seq = itertools.count(1 + (os.getpid() % 4096) * 1_000_000)  # unique per process; /sim echoes it
_seq_lock = threading.Lock()


def _next_seq() -> int:
    with _seq_lock:
        return next(_seq) & 0xFFFFFFFF


@dataclass
class _Goal:
    """A goal sent to /sim and not yet ended."""

    handle: ServerGoalHandle
    seq: int
    resource: str
    command: SkillCommand
    done: Future = field(default_factory=Future)
    sent_at: float = field(default_factory=time.monotonic)
    acked: bool = False
    last_heard: float = field(default_factory=time.monotonic)  # [s, monotonic] of the latest state from /sim
    last_feedback: float = float("-inf")
    milestone: int = -1
    cancel_seen: threading.Event = field(default_factory=threading.Event)
    cancel_asked: bool = False


def feedback_due(last_s: float, last_milestone: int, stamp_s: float, milestone: int, period_s: float) -> bool:
    """Whether a running goal's state stamped ``stamp_s`` [s of sim time] is relayed as feedback, the last relayed one
    stamped ``last_s``: at ``period_s``, the first at once, and at every milestone (e.g. a new stage); never one older
    than the last relayed. /sim answers a START sent again with the goal's first state: a server that re-sent its START
    (at rtf 0 its sim-time watchdog fires every few ms of wall time) got that state after later ones, and relayed a
    fetch's stage going back from LIFT to APPROACH."""
    if stamp_s < last_s:
        return False
    return stamp_s - last_s >= period_s or milestone != last_milestone


class SkillActionServer:
    """Serves ``action_name`` for one binding of the goal protocol.

    Args:
        node: the server node.
        binding: which action and skill.
        action_name: e.g. ``"/walk"``.
        robot: the robot of ``/sim``.
        settings: the node's parameters the skill reads, read when a goal starts or they change.
        feedback_period: [s of sim time] between relayed feedback messages.
    """

    def __init__(self, node: Node, binding: SkillBinding, action_name: str, robot: RobotSpec,
                 settings: Callable[[], dict[str, float]], feedback_period: Callable[[], float], commands: Any) -> None:
        self._node = node
        self.binding = binding
        self.robot = robot  # the light model goals are validated on (the scene /sim runs)
        self._settings = settings
        self._feedback_period = feedback_period
        self._commands = commands
        self._goals: dict[tuple[str, int], _Goal] = {}
        self._lock = threading.Lock()
        self._codes = result_codes(binding.action_type)
        group = ReentrantCallbackGroup()
        self.server = ActionServer(
            node, binding.action_type, action_name, execute_callback=self._execute, goal_callback=self._accept,
            handle_accepted_callback=lambda handle: handle.execute(), cancel_callback=self._cancel, callback_group=group,
            goal_service_qos_profile=SERVICE_QOS, result_service_qos_profile=SERVICE_QOS,
            cancel_service_qos_profile=SERVICE_QOS, feedback_pub_qos_profile=FEEDBACK_QOS)
        # Runs only while goals run (an idle server has no timer firing).
        self._watchdog_timer = node.create_timer(RESEND_PERIOD_S, self._watchdog, callback_group=group,
                                                 clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._watchdog_timer.cancel()
        self._last_watchdog = time.monotonic()

    # ----- goal life ---------------------------------------------------------------------------
    def _accept(self, goal: Any) -> GoalResponse:
        try:
            self.binding.validate(goal, self.robot)
            self.binding.resource(goal, self.robot)
        except InvalidGoalError as reason:
            self._node.get_logger().warning(f"{self.binding.action_type.__name__} goal rejected: {reason}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    async def _execute(self, handle: ServerGoalHandle) -> Any:
        try:
            return await self._run(handle)
        except Exception as error:  # noqa: BLE001 - reported to the client as SIM_FAULT, logged with its traceback
            self._node.get_logger().error(f"{self.binding.name} goal failed: {''.join(traceback.format_exception(error))}")
            result = self.binding.action_type.Result()
            result.error_code = self.binding.action_type.Result.SIM_FAULT
            result.error_msg = f"internal error in /{self._node.get_name()}: {type(error).__name__}: {error}"
            if handle.is_active:
                handle.abort()
            return result

    async def _run(self, handle: ServerGoalHandle) -> Any:
        resource = self.binding.resource(handle.request, self.robot)
        settings = self._settings()
        command = SkillCommand(request=SkillCommand.START, skill=self.binding.name, resource=resource, goal_seq=_next_seq(),
                               goal=serialize_message(handle.request), setting_names=list(settings),
                               setting_values=[float(v) for v in settings.values()])
        goal = _Goal(handle, command.goal_seq, resource, command)
        with self._lock:
            self._goals[(resource, goal.seq)] = goal
            if self._watchdog_timer.is_canceled():
                self._last_watchdog = time.monotonic()
            self._watchdog_timer.reset()  # with the registration: the watchdog cannot miss this goal
        self._send(command)
        try:
            return await wait_parked(goal.done)
        finally:
            with self._lock:
                self._goals.pop((resource, goal.seq), None)

    def _cancel(self, handle: ServerGoalHandle) -> CancelResponse:
        goal = self._find(handle)
        if goal is not None:
            goal.cancel_asked = True
            self._send(SkillCommand(request=SkillCommand.CANCEL, skill=self.binding.name, resource=goal.resource,
                                    goal_seq=goal.seq))
            # Answered once /sim has the cancel (the robot is stopping), so a client that steps a paused
            # sim after the answer gets the same run every time. Bounded: a silent /sim is the watchdog's.
            goal.cancel_seen.wait(CANCEL_ACK_S)
        return CancelResponse.ACCEPT

    def update_settings(self) -> None:
        """Send the current settings to every running goal (a parameter changed)."""
        settings = self._settings()
        for goal in self._running():
            self._send(SkillCommand(request=SkillCommand.UPDATE, skill=self.binding.name, resource=goal.resource,
                                    goal_seq=goal.seq, setting_names=list(settings),
                                    setting_values=[float(v) for v in settings.values()]))

    # ----- states from /sim --------------------------------------------------------------------
    def on_state(self, state: SkillState) -> None:
        """A SkillState of any resource: relay it to the goal it belongs to."""
        with self._lock:
            goal = self._goals.get((state.resource, state.goal_seq))
        if goal is None or goal.done.done():
            return
        goal.acked = True
        goal.last_heard = time.monotonic()
        if state.cancel_requested or state.status != SkillState.RUNNING:
            goal.cancel_seen.set()
        action = self.binding.action_type
        if state.status == SkillState.RUNNING:
            if not state.feedback:  # /sim's wall-clock liveness report: nothing to relay
                return
            now = seconds_of(state.header.stamp)
            if feedback_due(goal.last_feedback, goal.milestone, now, state.milestone, self._feedback_period()):
                goal.last_feedback, goal.milestone = now, state.milestone
                if state.feedback:
                    goal.handle.publish_feedback(deserialize_message(bytes(state.feedback), action.Feedback))
            return
        if state.status not in _TERMINAL:
            return
        result = deserialize_message(bytes(state.result), action.Result) if state.result else action.Result()
        if not state.result:
            result.error_code, result.error_msg = action.Result.SIM_FAULT, state.message or "ended without a result"
        self._end(goal, state.status, result)

    def _end(self, goal: _Goal, status: int, result: Any) -> None:
        handle = goal.handle
        if status == SkillState.CANCELED and goal.cancel_asked:
            # /sim can end a goal CANCELED before rclpy has marked it canceling (that happens when the
            # cancel callback, still waiting for this very state, returns): give it that moment.
            deadline = time.monotonic() + CANCEL_ACK_S
            while handle.is_active and not handle.is_cancel_requested and time.monotonic() < deadline:
                time.sleep(0.001)
        if handle.is_active:
            if status == SkillState.CANCELED and handle.is_cancel_requested:
                handle.canceled()
            elif status == SkillState.SUCCEEDED:
                handle.succeed()
            else:
                handle.abort()
        name = self._codes.get(int(result.error_code), str(result.error_code))
        text = f"{self.binding.name} goal {goal.seq} ended {name}: {result.error_msg}"
        if status == SkillState.SUCCEEDED or status == SkillState.CANCELED:
            self._node.get_logger().info(text)
        else:
            self._node.get_logger().warning(text)
        goal.cancel_seen.set()
        goal.done.set_result(result)

    def _watchdog(self) -> None:
        """While goals run: re-send unanswered STARTs; end goals /sim never answered or stopped answering."""
        now = time.monotonic()
        gap, self._last_watchdog = now - self._last_watchdog, now
        with self._lock:
            pending = [goal for goal in self._goals.values() if not goal.done.done()]
            if not pending:
                self._watchdog_timer.cancel()
        if gap > STARVED_GAP_S:  # this process was not running: what /sim sent meanwhile may be unread
            for goal in pending:
                goal.last_heard = max(goal.last_heard, now - RESEND_PERIOD_S)
            return
        action = self.binding.action_type
        for goal in pending:
            if goal.acked:
                if now - goal.last_heard > SIM_SILENCE_S:
                    result = action.Result()
                    result.error_code = action.Result.SIM_FAULT
                    result.error_msg = (f"/sim stopped answering: no state of this goal on {SKILL_STATE_TOPIC} for "
                                        f"{now - goal.last_heard:.1f} s of wall time (it reports running goals every "
                                        "0.2 s, paused or not); the sim node has stopped or died")
                    self._end(goal, SkillState.ABORTED, result)
            elif now - goal.sent_at > ACK_TIMEOUT_S:
                result = action.Result()
                result.error_code = action.Result.SIM_FAULT
                result.error_msg = (f"no answer from /sim on {SKILL_STATE_TOPIC} within {ACK_TIMEOUT_S:g} s: "
                                    f"is /sim running with the {self.robot.name}?")
                self._end(goal, SkillState.ABORTED, result)
            else:
                self._send(goal.command)

    def end_all(self, reason: str) -> int:
        """End every running goal ABORTED with SIM_FAULT and ``reason`` (the server is going away). Returns how many."""
        ended = 0
        for goal in list(self._running()):
            result = self.binding.action_type.Result()
            result.error_code = self.binding.action_type.Result.SIM_FAULT
            result.error_msg = reason
            self._send(SkillCommand(request=SkillCommand.CANCEL, skill=self.binding.name, resource=goal.resource,
                                    goal_seq=goal.seq))
            self._end(goal, SkillState.ABORTED, result)
            ended += 1
        return ended

    # ----- helpers -----------------------------------------------------------------------------
    def _send(self, command: SkillCommand) -> None:
        command.header.stamp = self._node.get_clock().now().to_msg()
        self._commands.publish(command)

    def pending(self) -> bool:
        """Whether a goal is registered whose execute callback has not returned (its result not sent)."""
        with self._lock:
            return bool(self._goals)

    def _running(self) -> Iterator[_Goal]:
        with self._lock:
            goals = list(self._goals.values())
        return (goal for goal in goals if not goal.done.done())

    def _find(self, handle: ServerGoalHandle) -> _Goal | None:
        for goal in self._running():
            if goal.handle is handle:
                return goal
        return None


_SERVERS: weakref.WeakKeyDictionary[Node, list[SkillActionServer]] = weakref.WeakKeyDictionary()


def end_goals_of(node: Node, reason: str) -> int:
    """End every running goal of ``node``'s skill servers ABORTED with ``reason`` (the node is going away)."""
    return sum(server.end_all(reason) for server in _SERVERS.get(node, []))


def goals_pending(node: Node) -> bool:
    """Whether any skill server of ``node`` still has a goal whose result has not gone out."""
    return any(server.pending() for server in _SERVERS.get(node, []))


def end_goals_before_exit(node: Node, executor: Executor) -> None:
    """End the running goals ABORTED "server shutting down" and spin until their results have gone out.

    The ``before_exit`` of a server node's ``spin_server``: called after Ctrl-C or SIGTERM, while ROS still runs.
    """
    ended = end_goals_of(node, f"server shutting down: /{node.get_name()} was stopped while the goal ran")
    if not ended:
        return
    node.get_logger().warning(f"stopping: ended {ended} running goal(s) ABORTED (server shutting down)")
    deadline = time.monotonic() + GOODBYE_WALL_S
    while goals_pending(node) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)  # the goals' execute callbacks return
    grace = time.monotonic() + RESULT_GRACE_S
    while time.monotonic() < grace:
        executor.spin_once(timeout_sec=0.02)  # and the result requests they release are answered


def skill_servers(node: Node, robot: RobotSpec, actions: dict[str, str], settings: Callable[[], dict[str, float]],
                  feedback_period: Callable[[], float],
                  on_scene: Callable[[RobotSpec], None] = lambda spec: None) -> dict[str, SkillActionServer]:
    """Action servers for several skills of one node, sharing one /sim/skill_state stream and one command publisher.

    Args:
        actions: skill name -> action name (e.g. ``{"walk": "/walk"}``).
        on_scene: told the light model of the scene when /sim loads another one (the servers validate on it).
    """
    servers: dict[str, SkillActionServer] = {}

    def on_state(state: SkillState) -> None:
        server = servers.get(state.skill)
        if server is not None:
            server.on_state(state)

    # Subscribed for the node's life (discovery is done before the first goal, which then gets its
    # first feedback at once); /sim publishes states only while a goal runs or changes, so an idle
    # server receives nothing.
    states = node.create_subscription(SkillState, SKILL_STATE_TOPIC, on_state, SKILL_QOS,
                                      callback_group=ReentrantCallbackGroup())
    commands = node.create_publisher(SkillCommand, SKILL_COMMAND_TOPIC, SKILL_QOS)
    # The actions are offered once /sim is matched both ways, so a client that waited for the server
    # finds its first goal taken at once (not after discovery, which takes a while after start-up).
    deadline = time.monotonic() + SIM_MATCH_S
    while (commands.get_subscription_count() == 0 or states.get_publisher_count() == 0) and time.monotonic() < deadline:
        time.sleep(0.05)  # discovery runs in the middleware's threads; nothing here to spin yet
    if commands.get_subscription_count() == 0:
        node.get_logger().warning(f"/sim has not subscribed to {SKILL_COMMAND_TOPIC} within {SIM_MATCH_S:g} s; "
                                  "serving anyway (goals are sent again until /sim answers)")
    for skill, action_name in actions.items():
        servers[skill] = SkillActionServer(node, BINDINGS[skill], action_name, robot, settings, feedback_period, commands)
    _SERVERS.setdefault(node, []).extend(servers.values())

    def scene_loaded(spec: RobotSpec) -> None:
        for server in servers.values():
            server.robot = spec
        on_scene(spec)

    follow_world(node, robot, scene_loaded)
    return servers
