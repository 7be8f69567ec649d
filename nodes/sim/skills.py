"""``/sim`` side of the goal protocol: SkillCommand in, skills in the control step, SkillState out.

Commands are applied under the simulation lock between two stretches of stepping, at the sim time
at which they arrive (while paused, at the paused instant). A goal's state is published at once when
it starts, ends or is asked to cancel, and at ``state_rate`` while anyone listens. Besides, every
running goal's state goes out at least every :data:`HEARTBEAT_PERIOD_S` of wall time, paused or not:
a server that hears nothing for much longer knows /sim has stopped or died.
"""

from __future__ import annotations

import collections
import time

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message

from nodes.servers.protocol import BINDINGS, SkillContext, fill_message, result_message
from nodes.sim.handoff import HandOffLock
from sim_bridge import Simulation
from sim_bridge.errors import InvalidGoalError
from sim_bridge.skills import SkillHost, SkillRun, SkillStatus
from sim_bridge.skills.host import refused_run
from sim_interfaces.msg import SkillCommand, SkillState
from sim_ros.names import SKILL_COMMAND_TOPIC, SKILL_QOS, SKILL_STATE_TOPIC
from sim_ros.stamps import set_time

HEARTBEAT_PERIOD_S = 0.2  # [s of wall time] the longest a running goal's state goes unpublished
# [s of wall time] While the physics thread is inside one long control step (a fetch planning its reach and building
# the arms' IK model on a loaded machine, a garbage collection), the heartbeat reports the running goals as the step
# before it left them, for at most this long: a thread stuck longer lets the servers end the goals (SIM_FAULT).
BUSY_STEP_S = 30.0
SEEN_COMMANDS = 256  # recent (resource, goal_seq) starts remembered, so a re-sent START is applied once


class SkillBridge:
    """Routes SkillCommands to the skill hosts of one simulation and publishes their SkillStates.

    Args:
        node: the sim node.
        sim: its simulation.
        lock: the lock that guards ``sim`` (commands take it; ``publish_*`` are called with it held).
        hosts: resource name -> the skill host that runs that resource's goals.
        context: what the bindings build skills from.
    """

    def __init__(self, node: Node, sim: Simulation, lock: HandOffLock, hosts: dict[str, SkillHost],
                 context: SkillContext) -> None:
        self._node = node
        self._sim = sim
        self._lock = lock
        self._hosts = hosts
        self._context = context
        self._seen: collections.deque[tuple[str, int]] = collections.deque(maxlen=SEEN_COMMANDS)
        # The last start, end or cancel state of those goals, published again when their START comes again: a server
        # re-sends a START it has heard nothing of, e.g. because /sim published the goal's only states before its
        # writer had matched the server's reader (a goal refused or preempted at once ended so for ever, SIM_FAULT).
        self._changes: collections.OrderedDict[tuple[str, int], SkillState] = collections.OrderedDict()
        # The running goals' liveness states as the physics thread last published them, and when [monotonic s].
        self._alive: list[SkillState] = []
        self._alive_at = time.monotonic()
        self._refused: list[SkillRun] = []
        self._pub = node.create_publisher(SkillState, SKILL_STATE_TOPIC, SKILL_QOS)
        node.create_subscription(SkillCommand, SKILL_COMMAND_TOPIC, self._on_command, SKILL_QOS,
                                 callback_group=ReentrantCallbackGroup())
        node.create_timer(HEARTBEAT_PERIOD_S, self._heartbeat, callback_group=ReentrantCallbackGroup(),
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    def busy(self, resource: str) -> bool:
        host = self._hosts.get(resource)
        return host is not None and host.running(resource) is not None

    # ----- commands ----------------------------------------------------------------------------
    def _on_command(self, msg: SkillCommand) -> None:
        with self._lock:
            self._apply(msg)
            self.publish_changed()

    def _apply(self, msg: SkillCommand) -> None:
        host = self._hosts.get(msg.resource)
        settings = dict(zip(msg.setting_names, msg.setting_values, strict=False))
        if msg.request == SkillCommand.CANCEL:
            if host is not None:
                host.cancel(msg.resource, msg.goal_seq)
            return
        if msg.request == SkillCommand.UPDATE:
            if host is not None:
                host.update_settings(msg.resource, msg.goal_seq, settings)
            return
        key = (msg.resource, msg.goal_seq)
        if key in self._seen:  # a START sent again before its state was seen: applied once, its last state sent again
            last = self._changes.get(key)
            if last is not None:
                self._pub.publish(last)
            return
        self._seen.append(key)
        now = self._sim.time
        binding = BINDINGS.get(msg.skill)
        if msg.request != SkillCommand.START:
            reason = f"unknown request {msg.request}; requests: START=0, CANCEL=1, UPDATE=2"
        elif binding is None:
            reason = f"unknown skill {msg.skill!r}; skills: {', '.join(BINDINGS)}"
        elif host is None:
            reason = (f"unknown resource {msg.resource!r} on robot {self._sim.robot.name!r}; "
                      f"resources: {', '.join(self._hosts) or 'none'}")
        elif (holder := self._holder_of(msg.resource)) is not None:
            reason = (f"{msg.resource!r} is moved by the running {holder.skill_name} goal {holder.seq} (on "
                      f"{holder.resource!r}); cancel it, or send this goal once it has ended")
        else:
            try:
                goal = deserialize_message(bytes(msg.goal), binding.action_type.Goal)
                skill = binding.build(goal, settings, self._context)
            except InvalidGoalError as error:
                reason = str(error)
            except Exception as error:  # noqa: BLE001 - a malformed goal is refused with its reason, never kills /sim
                reason = f"malformed {msg.skill} goal: {type(error).__name__}: {error}"
            else:
                for resource in getattr(skill, "also_holds", ()):  # the goals on what it will move end first
                    held = self._hosts.get(resource)
                    if held is not None:
                        held.preempt(resource, self._sim.model, self._sim.data,
                                     f"preempted by {msg.skill} goal {msg.goal_seq}, which moves {resource!r}")
                host.start(msg.goal_seq, skill, self._sim.model, self._sim.data)
                return
        self._node.get_logger().warning(f"{msg.skill} goal {msg.goal_seq} on {msg.resource!r} refused: {reason}")
        self._refused.append(refused_run(msg.goal_seq, msg.skill, msg.resource, self.epoch, reason, now))

    def _holder_of(self, resource: str) -> SkillRun | None:
        """The running goal (of another resource) that also moves ``resource``, if any."""
        for own, host in self._hosts.items():
            run = host.running(own)
            if own != resource and run is not None and resource in getattr(run.skill, "also_holds", ()):
                return run
        return None

    @property
    def epoch(self) -> int:
        """Resets of the simulation so far (every host counts them alike)."""
        return max((host.epoch for host in self._hosts.values()), default=0)

    def runs(self) -> list[SkillRun]:
        """Under the lock: the goals every host holds now (running ones and those just ended)."""
        return [run for host in set(self._hosts.values()) for run in host.runs()]

    # ----- states ------------------------------------------------------------------------------
    def publish_changed(self) -> int:
        """Under the lock: publish the goals that started, ended or were asked to cancel since last time.

        Returns how many of them have ended.
        """
        runs: list[SkillRun] = self._refused
        self._refused = []
        for host in set(self._hosts.values()):
            runs.extend(host.take_changed())
        for run in runs:
            state = self._state(run)
            self._changes[(run.resource, state.goal_seq)] = state
            if len(self._changes) > SEEN_COMMANDS:
                self._changes.popitem(last=False)
            if self._pub.get_subscription_count() > 0:
                self._pub.publish(state)
        return sum(1 for run in runs if run.status.terminal)

    def publish_all(self) -> None:
        """Under the lock, at state_rate: every running goal, while anyone listens (ended ones were published as they ended)."""
        if self._pub.get_subscription_count() == 0:
            return
        self.publish_changed()
        alive = []
        for host in set(self._hosts.values()):
            for run in host.runs():
                if run.status is SkillStatus.RUNNING:
                    self._pub.publish(self._state(run))
                    alive.append(self._liveness(run))
        self._alive, self._alive_at = alive, time.monotonic()

    def _heartbeat(self) -> None:
        """Wall-clock: the state of every running goal (the same sim stamp while paused: no feedback is due)."""
        if not any(host.runs() for host in set(self._hosts.values())):
            return
        # Never queue for the lock: if the physics thread holds it, it is stepping and publishes states; inside one long
        # step it publishes none, and the last ones it left say /sim is alive (up to BUSY_STEP_S).
        if not self._lock.acquire(blocking=False):
            if HEARTBEAT_PERIOD_S <= time.monotonic() - self._alive_at <= BUSY_STEP_S:
                for state in self._alive:
                    self._pub.publish(state)
            return
        try:
            if self._pub.get_subscription_count() == 0:
                return
            for host in set(self._hosts.values()):
                for run in host.runs():
                    if run.status is SkillStatus.RUNNING:
                        self._pub.publish(self._liveness(run))
        finally:
            self._lock.release()

    def _liveness(self, run: SkillRun) -> SkillState:
        """A running goal's state without feedback: it says /sim is alive, and is never relayed as feedback
        (feedback follows sim time only, so a lock-stepped run relays the same feedback every time)."""
        msg = self._header(run)
        set_time(msg.header.stamp, self._sim.time)
        return msg

    def _header(self, run: SkillRun) -> SkillState:
        """The fields every state of ``run`` carries: who it is, the epochs, the status."""
        return SkillState(skill=run.skill_name, resource=run.resource, goal_seq=run.seq & 0xFFFFFFFF,
                          reset_epoch=self.epoch, start_epoch=run.epoch, status=int(run.status),
                          cancel_requested=run.cancel_requested)

    def _state(self, run: SkillRun) -> SkillState:
        now = self._sim.time
        binding = BINDINGS[run.skill_name] if run.skill_name in BINDINGS else None
        msg = self._header(run)
        set_time(msg.header.stamp, now if run.status is SkillStatus.RUNNING else run.ended_at)
        if run.outcome is not None:
            msg.message = run.outcome.message
        if binding is None:
            return msg
        action = binding.action_type
        frame = run.skill.pose_frame if run.skill is not None else "world"
        if run.status is SkillStatus.RUNNING:
            assert run.skill is not None
            msg.milestone = int(getattr(run.skill, "milestone", 0))
            values = run.skill.feedback(self._sim.data)
            msg.feedback = serialize_message(fill_message(action.Feedback(), values, now, frame))
        else:
            stamp = run.ended_at
            if run.final_feedback:
                msg.feedback = serialize_message(fill_message(action.Feedback(), run.final_feedback, stamp, frame))
            result = result_message(action, run.outcome, run.final_result, stamp, frame)
            msg.error_code = int(result.error_code)
            msg.result = serialize_message(result)
        return msg
